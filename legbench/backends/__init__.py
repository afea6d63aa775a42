"""Backend registry: built-in backends by guarded import, third-party ones by entry point.

A backend whose engine package is missing is simply not available; asking for
it raises :class:`~legbench.exceptions.BackendNotFound` naming what to install.
Other packages add backends through the ``legbench.backends`` entry-point group
(``name = "package.module:Class"``).
"""

from __future__ import annotations

import importlib
import inspect
import logging
import re
from collections.abc import Mapping
from importlib import metadata
from typing import Any

from legbench import resources
from legbench.backends.base import (
    INTEGRATOR_FAMILIES,
    PROFILES,
    Backend,
    Limits,
    Physics,
    Range,
    dt_problem,
    sub_step_count,
)
from legbench.exceptions import BackendNotFound, LegbenchError, UnknownBackend
from legbench.yamlfile import one_line

__all__ = [
    "INTEGRATOR_FAMILIES",
    "PROFILES",
    "Backend",
    "Limits",
    "Physics",
    "Range",
    "UnknownBackend",
    "available",
    "check_profile",
    "dt_problem",
    "engine_packages",
    "get",
    "load",
    "resolve",
    "sub_step_count",
    "unavailable",
]

#: Built-in backends: name -> (module, class, pip requirement that provides the engine, with pyproject.toml's
#: pin (tests/test_entry_point.py keeps them equal), or the whole install command where a pip package is not enough,
#: e.g. a system library too).
BUILTIN: dict[str, tuple[str, str, str]] = {
    "pinocchio": ("legbench.backends.pinocchio_", "PinocchioBackend", "'pin>=4.1,<5'"),
    "mujoco": ("legbench.backends.mujoco_", "MujocoBackend", "'mujoco>=4.0,<5'"),
    "pybullet": ("legbench.backends.pybullet_", "PybulletBackend", "'pybullet>=3.2.6'"),
    "drake": ("legbench.backends.drake_", "DrakeBackend", "'drake>=1.51,<2'"),
    "dart": ("legbench.backends.dart_", "DartBackend", "'dartpy>=6.20,<7'"),
    "lagrange": ("legbench.backends.lagrange_", "LagrangeBackend", "'sympy>=1.12,<2'"),
    "ode": ("legbench.backends.ode_", "OdeBackend", "apt-get install -y libode8 && pip install ode-python"),
}

_MISSING: dict[str, str] = {}
#: The backends :func:`resolve` has said are not installed (each is said once per process).
_SAID_MISSING: set[str] = set()
logger = logging.getLogger(__name__)


def _interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is, or was raised while handling or because of, a KeyboardInterrupt: Ctrl-C (or SIGTERM,
    :mod:`legbench.cli`) during an engine's import comes back from a pybind11 extension as ``ImportError:
    initialization failed`` from it, which is an interrupt, not an engine that is not installed."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def _load_builtin(name: str) -> type[Backend] | None:
    module, cls, package = BUILTIN[name]
    try:
        return getattr(importlib.import_module(module), cls)  # type: ignore[no-any-return]
    except ImportError as exc:
        if _interrupted(exc):
            raise KeyboardInterrupt from exc
        command = package if package.startswith("apt-get ") else f"pip install {package}"
        _MISSING[name] = one_line(f"{command} ({exc})")  # numpy's ImportError spans lines
        return None
    except Exception as exc:  # an engine whose import breaks (a bad build, a missing shared library) fails alone
        if _interrupted(exc):
            raise KeyboardInterrupt from exc
        _MISSING[name] = one_line(f"its engine failed to import: {type(exc).__name__}: {exc}")
        return None


def _load_plugin(ep: metadata.EntryPoint) -> type[Backend] | None:
    """The class a plug-in's entry point names (its module imported), or None with why in ``_MISSING``."""
    try:
        obj = ep.load()
    except Exception as exc:  # a broken plug-in must not take the others down
        if _interrupted(exc):
            raise KeyboardInterrupt from exc
        _MISSING[ep.name] = one_line(f"entry point {ep.value} failed to load: {exc}")
        return None
    if not (isinstance(obj, type) and issubclass(obj, Backend)):  # it would fail on its first attribute
        _MISSING[ep.name] = f"entry point {ep.value} names {obj!r}, not a subclass of legbench's Backend"
        return None
    if inspect.isabstract(obj):  # listed as runnable, it failed at its first load
        missing = ", ".join(sorted(getattr(obj, "__abstractmethods__", ())))
        _MISSING[ep.name] = f"entry point {ep.value}: {obj.__name__} does not implement {missing}"
        return None
    if not isinstance(obj.profiles, Mapping):  # `p in None` crashed `legbench backends` with a TypeError
        _MISSING[ep.name] = (f"entry point {ep.value}: {obj.__name__}.profiles is {type(obj.profiles).__name__}, not "
                             "a mapping of profile name to settings")  # fmt: skip
        return None
    lacking = [p for p in PROFILES if p not in obj.profiles]
    if lacking:  # it ran alone, then stopped every `--backends all` run of that profile (make compare) with exit 2
        _MISSING[ep.name] = (f"entry point {ep.value}: {obj.__name__}.profiles has no {' or '.join(map(repr, lacking))}"
                             f" (every backend offers {' and '.join(PROFILES)}; it may add its own)")  # fmt: skip
        return None
    return obj


def _plugins() -> dict[str, metadata.EntryPoint]:
    """The plug-ins' entry points by name, not loaded (a name of a built-in is the built-in's)."""
    found: dict[str, metadata.EntryPoint] = {}
    for ep in metadata.entry_points(group="legbench.backends"):
        if ep.name not in BUILTIN:
            found.setdefault(ep.name, ep)
    return found


def _registry() -> dict[str, type[Backend]]:
    found: dict[str, type[Backend]] = {}
    for name in BUILTIN:
        cls = _load_builtin(name)
        if cls is not None:
            found[name] = cls
    for name, ep in _plugins().items():
        cls = _load_plugin(ep)
        if cls is not None:
            found[name] = cls
    return found


def engine_packages() -> list[str]:
    """Distribution names of the built-in backends' engines (whose versions a run records): each requirement's name
    (``'pin>=3.0'`` -> ``pin``; an install command's last ``pip install`` package). The requirements carried their
    pins from 27 Nov, and run.json's versions lost every engine until 28 Nov."""
    return list(dict.fromkeys(_distribution(package) for _, _, package in BUILTIN.values()))


def _distribution(requirement: str) -> str:
    """The distribution a pip requirement or an install command names: ``'drake>=1.51,<2'`` -> ``drake``,
    ``apt-get install -y libode8 && pip install ode-python`` -> ``ode-python``."""
    spec = requirement.rsplit("pip install ", 1)[-1].strip().strip("'\"")
    return re.split(r"[<>=!~\[;,\s]", spec, maxsplit=1)[0]


def module_of(name: str) -> str | None:
    """The module that holds backend ``name`` (a built-in's ``legbench.backends.<engine>_``, a plug-in's entry
    point module), not imported: what a worker pool preloads to have only the named engines imported; None for a
    name that is neither."""
    if name in BUILTIN:
        return BUILTIN[name][0]
    ep = _plugins().get(name)
    return ep.module if ep is not None else None


def check_profile(profile: str) -> None:
    """Refuse a profile a study is asked to load every backend in that not every backend offers.

    Raises:
        LegbenchError: ``profile`` is not one of :data:`PROFILES`.
    """
    if profile not in PROFILES:
        raise LegbenchError(f"unknown profile '{profile}'; choose from {', '.join(PROFILES)}")


def available() -> list[str]:
    """Names of the backends that can run here, built-ins first."""
    return list(_registry())


def unavailable() -> dict[str, str]:
    """The backends known here that cannot run, each with why: a built-in whose engine is not installed (with
    the command that installs it) or a plug-in whose entry point failed to load."""
    found = _registry()
    plugins = {ep.name for ep in metadata.entry_points(group="legbench.backends")}
    known = [n for n in dict.fromkeys([*BUILTIN, *_MISSING]) if n in BUILTIN or n in plugins]  # a record may be stale
    return {n: _MISSING.get(n) or "not installed" for n in known if n not in found}


def get(name: str) -> type[Backend]:
    """The backend class registered under ``name``, its engine imported alone (a built-in's module, or the plug-in's
    entry point), not with every engine: ``--backends a,b`` imports a and b (:func:`available` imports them all).
    Only a name that cannot be loaded imports the others, to list what is available.

    Raises:
        BackendNotFound: ``name`` is unknown, or its engine is not installed (or failed to import).
        KeyboardInterrupt: Ctrl-C (SIGTERM) while its engine was imported, even where the engine turned it into
            an ImportError (:func:`_interrupted`).
    """
    cls: type[Backend] | None = None
    if name in BUILTIN:
        cls = _load_builtin(name)
    else:
        ep = _plugins().get(name)
        cls = _load_plugin(ep) if ep is not None else None
    if cls is not None:
        return cls
    reg = _registry()
    if name not in reg:
        raise BackendNotFound(name, reg, _MISSING.get(name, ""))
    return reg[name]


def load(name: str, physics: Physics, settings: Mapping[str, Any], profile: str = "matched") -> Backend:
    """A backend instance with the generated leg loaded under ``physics``, its ``profile`` and ``settings``.

    The backend receives its defaults overlaid with the profile's settings and then
    with ``settings`` (:meth:`Backend.resolve_settings`). A ``profile`` key in
    ``settings`` (a scenario's ``backends.<name>.profile``) wins over ``profile``;
    the instance's :attr:`Backend.profile` says which one it was loaded with.

    Raises:
        BackendNotFound: ``name`` is not available.
        LegbenchError: ``profile`` is not one the backend offers.
        Exception: whatever the engine raises while loading (the instance is closed first).
    """
    cls = get(name)
    given = dict(settings)
    profile = str(given.pop("profile", profile))
    resolved = cls.resolve_settings(given, profile)
    backend = cls()
    backend.profile = profile
    try:
        backend.load(resources.urdf_file(), physics, resolved)
    except ImportError as exc:  # a plug-in that imports its engine only when loading
        backend.close()
        if _interrupted(exc):
            raise KeyboardInterrupt from exc
        hint = cls.install or "install the package that provides it"
        others = [n for n in available() if n != name]  # it imported, but its engine did not
        raise BackendNotFound(name, others, f"its engine did not import when loading: {exc}; {hint}") from exc
    except BaseException:
        backend.close()
        raise
    return backend


def resolve(names: str | list[str], option: str = "--backends") -> list[str]:
    """Expand ``"all"`` or a comma-separated list into backend names (checked); ``option`` is how the caller's
    user gave them (``--backends``, the API's ``backends``), for the errors.

    Raises:
        LegbenchError: the list names no backend (``""``: an empty list never means all).
        UnknownBackend: a name that is unknown or not installed here (a :class:`BackendNotFound`), in one line
            naming ``option`` and the backends available here.
    """
    given = names
    if isinstance(names, str):
        names = names.split(",")
    names = [n.strip() for n in names if n.strip()]
    if not names:
        raise LegbenchError(f"{option} {given!r}: names no backend (give names, or 'all')")
    if names == ["all"]:
        missing = {n: why for n, why in unavailable().items() if n not in _SAID_MISSING}
        if missing:  # "reported and skipped": once per process, not at every resolve of a command
            _SAID_MISSING.update(missing)
            logger.warning("legbench: note: %s all: the backends that can run here; not available, so not run: %s",
                           option, "; ".join(f"{n} ({why})" for n, why in missing.items()))  # fmt: skip
        return available()
    if "all" in names:
        raise LegbenchError(f"{option} {','.join(names)}: 'all' stands alone (every backend installed here); give "
                            "either it or names")  # fmt: skip
    for n in names:
        try:
            get(n)
        except BackendNotFound as exc:
            known = n in BUILTIN or n in _MISSING
            raise UnknownBackend(n, exc.available, exc.hint, known, option) from None
    return list(dict.fromkeys(names))
