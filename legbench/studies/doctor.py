"""Parity pre-flight: what each engine actually holds, read back from it, side by side.

Every backend is loaded for the scenario exactly as a run would load it, and
its model is read back: link masses, COMs and inertias (``Backend.mass_properties``),
joint position and torque limits and gravity (from the engine objects, see
:func:`readback`), and the settings it reports (``Backend.info``: time step,
integrator, contact parameters as mapped, friction cone). One table shows them
across backends beside the value the spec (the active leg parameter file,
``models/leg.yaml`` unless ``--model`` names another, and the scenario) asks for.

Rows of the leg itself and of the shared physics (mass properties, limits,
gravity) must agree with the spec to :data:`RTOL` relative (of the quantity's
scale: the mass, the largest COM component, the largest inertia entry of the
link); :func:`check` raises :class:`ParityError` naming the first row that
differs. Other rows (integrator, contact mapping, ...) are expected to differ
between engines and are only reported.

Data flow: scenario -> :func:`readback` per backend (a flat dict of plain
values) -> :func:`table` (a DataFrame: ``group, item, unit, spec, <backend>...,
status``) -> :func:`check`. :func:`doctor` and :func:`preflight` do both.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import numbers
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench import backends as registry
from legbench import model, resources, yamlfile
from legbench import scenario as scenario_mod
from legbench.backends.base import Backend
from legbench.exceptions import BackendNotFound, LegbenchError, ModelError
from legbench.exitcodes import EXIT_BACKEND_FAILED
from legbench.scenario import Scenario, physics_of

logger = logging.getLogger(__name__)
#: The pre-flight's warnings given in this process (each once).
_WARNED: set[str] = set()

__all__ = ["RTOL", "ParityError", "add_cli", "check", "doctor", "preflight", "readback", "table", "verdict"]

#: Relative tolerance of the parity rows.
RTOL = 1e-6
_AXES = ("x", "y", "z")
_INERTIA = (("xx", 0, 0), ("yy", 1, 1), ("zz", 2, 2), ("xy", 0, 1), ("xz", 0, 2), ("yz", 1, 2))


class ParityError(LegbenchError):
    """A backend holds a different leg (or gravity) than the spec.

    Attributes:
        backend: the backend that differs.
        row: the table row (``link2.mass``).
        value: what the engine holds.
        expected: what the spec asks for.
    """

    def __init__(self, backend: str, row: str, value: Any, expected: Any, unit: str = "", more: int = 0) -> None:
        self.backend, self.row, self.value, self.expected = backend, row, value, expected
        spec = f"{resources.shown(resources.model_file())} and the scenario"  # the active leg file, not the bundled
        msg = (f"parity: {backend} holds {row} = {_plain(value)} {unit}, the spec ({spec}) "
               f"says {_plain(expected)} {unit} (relative tolerance {RTOL:g})")  # fmt: skip
        if more:
            msg += f"; {more} more row(s) differ, see `legbench doctor`"
        super().__init__(msg)


def _plain(v: Any) -> str:
    """A value as a message shows it: numbers to 10 significant digits (numpy's too, without their
    ``np.float64(...)`` repr), text quoted."""
    if isinstance(v, bool | np.bool_):
        return str(bool(v))
    if isinstance(v, numbers.Real):
        return f"{float(v):.10g}"
    return repr(v)


# --------------------------------------------------------------------------- #
# Read back


def _flatten(prefix: str, d: Mapping[str, Any], out: dict[str, Any]) -> None:
    for k, v in d.items():
        key = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, Mapping):
            _flatten(key, v, out)
        else:
            out[key] = v


def readback(backend: Backend) -> dict[str, Any]:
    """What a loaded backend holds, as a flat dict ``row -> value``.

    Mass properties come from :meth:`Backend.mass_properties`; gravity, joint
    and torque limits, the engine's own step and how it enforces the limits
    from :meth:`Backend.limits` (read back from the engine's model by the
    backend); every other row from :meth:`Backend.info`.
    """
    out: dict[str, Any] = {}
    try:
        props = backend.mass_properties()
    except NotImplementedError:
        props = {}
    for link in model.LINK_NAMES:
        mp = props.get(link)
        if mp is None:
            continue
        out[f"{link}.mass"] = float(mp["mass"])
        for i, a in enumerate(_AXES):
            out[f"{link}.com.{a}"] = float(mp["com"][i])
        I = np.asarray(mp["inertia"], float)
        for name, r, c in _INERTIA:
            out[f"{link}.inertia.{name}"] = float(I[r, c])
    lim = backend.limits()
    out["gravity"] = float(lim.gravity)
    for key, values in (("lower", lim.lower), ("upper", lim.upper), ("torque_limit", lim.effort)):
        for jn, v in zip(model.JOINT_NAMES, values, strict=True):
            out[f"{jn}.{key}"] = float(v)
    if lim.timestep is not None:
        out["engine.timestep"] = lim.timestep
    if lim.enforcement:
        out["engine.limit_enforcement"] = lim.enforcement
    info = backend.info()
    settings: dict[str, Any] = {}
    _flatten("", info, settings)
    for k, v in settings.items():
        out[f"info.{k}"] = v if isinstance(v, str | int | float | bool) or v is None else json.dumps(v, default=str)
    return out


def _spec(scenario: Scenario) -> dict[str, tuple[Any, str, float]]:
    """Spec rows: row -> (value, unit, scale for the relative tolerance)."""
    p = model.load_params()
    rows: dict[str, tuple[Any, str, float]] = {}
    for link in model.LINK_NAMES:
        inr = p.body_inertial(link)
        rows[f"{link}.mass"] = (inr.mass, "kg", inr.mass)
        com_scale = float(np.abs(inr.com).max())
        for i, a in enumerate(_AXES):
            rows[f"{link}.com.{a}"] = (float(inr.com[i]), "m", com_scale)
        I = inr.I
        i_scale = float(np.abs(I).max())
        for name, r, c in _INERTIA:
            rows[f"{link}.inertia.{name}"] = (float(I[r, c]), "kg m^2", i_scale)
    rows["gravity"] = (scenario.gravity, "m/s^2", scenario.gravity)
    for j in p.joints:
        for key, v in (("lower", j.lower), ("upper", j.upper)):
            rows[f"{j.name}.{key}"] = (v, "rad", abs(v) if math.isfinite(v) else 1.0)
        rows[f"{j.name}.torque_limit"] = (j.effort, "N m", j.effort)
    return rows


def _group(row: str) -> str:
    if row.startswith("link"):
        return "mass properties"
    if row.startswith(model.JOINT_NAMES):
        return "joints"
    if row == "gravity":
        return "physics"
    if row.startswith("info.contact"):
        return "contact (as mapped)"
    return "settings"


def _same(a: Any, b: Any, tol: float) -> bool:
    """a equals b within the absolute tolerance tol (infinite values must match exactly)."""
    if isinstance(a, float) and isinstance(b, float) and (math.isinf(a) or math.isinf(b)):
        return a == b
    try:
        return abs(float(a) - float(b)) <= tol
    except (TypeError, ValueError):
        return bool(a == b)


_FIXED = ("group", "row", "unit", "spec", "tolerance", "status")


def _engine_error(name: str, what: str, exc: BaseException) -> str:
    return yamlfile.one_line(f"parity check: {name} failed to {what}: {type(exc).__name__}: {exc}")


def table(
    scenario: Scenario | str | Path,
    backends: Sequence[str] | None = None,
    contact_mode: str | None = None,
    failed: dict[str, str] | None = None,
) -> pd.DataFrame:
    """Load every backend for the scenario, read back what it holds, and tabulate it against the spec.

    Args:
        scenario: a :class:`~legbench.scenario.Scenario` or the path of a scenario file.
        backends: backend names (default: every available backend).
        contact_mode: the contact mode they are loaded in (default: the scenario's), the run's: a backend or
            setting that cannot run in it is refused here, as its run would be.
        failed: where an engine's own error while loading or reading back goes (name -> one line), that backend
            left out of the table: one engine failing does not stop the others. None: it is raised.

    Returns:
        Columns ``group, row, unit, spec, tolerance, <one per backend>, status``; status is
        ``ok``, ``MISMATCH`` (a parity row off by more than :data:`RTOL`), ``missing``
        (a backend does not report a parity row) or ``info`` (not a parity row).
    """
    sc = scenario if isinstance(scenario, Scenario) else scenario_mod.load(scenario)
    names = list(backends) if backends is not None else registry.available()
    physics = physics_of(sc, contact_mode)
    values: dict[str, dict[str, Any]] = {}
    for name in names:
        try:
            b = registry.load(name, physics, sc.backends.get(name, {}), sc.profile)
        except BackendNotFound as exc:  # a plug-in importing its engine only when loading, and it is missing:
            if failed is None:  # that engine's problem, as any other load error (the names were resolved before)
                raise
            failed[name] = str(exc)
            continue
        except ModelError:  # the leg or the cache every engine needs: named as it is
            raise
        except LegbenchError as exc:  # a setting the engine refuses for this scenario (a dt that does not
            raise LegbenchError(f"{sc.file}: {exc}") from exc  # divide its control period): name the file
        except Exception as exc:  # the engine's own error (a plug-in's bug): one line naming it, not a traceback
            if failed is None:
                raise LegbenchError(_engine_error(name, "load", exc)) from exc
            failed[name] = _engine_error(name, "load", exc)
            continue
        try:
            values[name] = readback(b)
        except LegbenchError:
            raise
        except Exception as exc:
            if failed is None:
                raise LegbenchError(_engine_error(name, "read back", exc)) from exc
            failed[name] = _engine_error(name, "read back", exc)
        finally:
            b.close()
    names = [n for n in names if n in values]
    spec = _spec(sc)
    rows: list[dict[str, Any]] = []
    for row, (expected, unit, scale) in spec.items():
        tol = RTOL * scale
        rec: dict[str, Any] = {"group": _group(row), "row": row, "unit": unit, "spec": expected, "tolerance": tol}
        status = "ok"
        for name in names:
            v = values[name].get(row)
            rec[name] = v
            if v is None:
                status = "missing" if status == "ok" else status
            elif not _same(v, expected, tol):
                status = "MISMATCH"
        rec["status"] = status
        rows.append(rec)
    extra = sorted({k for v in values.values() for k in v} - set(spec), key=lambda k: (_group(k), k))
    for row in extra:
        rec = {"group": _group(row), "row": row.removeprefix("info."), "unit": "", "spec": None, "tolerance": None}
        rec.update({name: values[name].get(row) for name in names})
        rec["status"] = "info"
        rows.append(rec)
    return pd.DataFrame(rows, columns=["group", "row", "unit", "spec", "tolerance", *names, "status"])


def check(t: pd.DataFrame) -> None:
    """Raise :class:`ParityError` naming the first parity row a backend gets wrong."""
    bad = t[t["status"] == "MISMATCH"]
    if not len(bad):
        return
    names = [c for c in t.columns if c not in _FIXED]
    first = bad.iloc[0]
    name = next(n for n in names if first[n] is not None and not _same(first[n], first["spec"], first["tolerance"]))
    raise ParityError(name, first["row"], first[name], first["spec"], first["unit"], len(bad) - 1)


def verdict(t: pd.DataFrame) -> str:
    """The one-line outcome of a table that :func:`check` passed: every backend holds the spec, or which
    backends did not read back some parity rows (those rows are not checked, so parity is not claimed for them)."""
    names = [c for c in t.columns if c not in _FIXED]
    parity = t[t["status"] != "info"]
    unread = {n: int(parity[n].isna().sum()) for n in names}
    unread = {n: k for n, k in unread.items() if k}
    if not unread:
        return "parity: every backend holds the spec's leg, limits and gravity"
    which = ", ".join(f"{n} ({k} of {len(parity)} rows)" for n, k in unread.items())
    return (f"parity: every row read back matches the spec's leg, limits and gravity; not read back, so not "
            f"checked: {which}")  # fmt: skip


def doctor(
    scenario: Scenario | str | Path, backends: Sequence[str] | None = None, contact_mode: str | None = None
) -> pd.DataFrame:
    """:func:`table` across backends (default: all available); raises :class:`ParityError` on a mismatch."""
    t = table(scenario, backends, contact_mode)
    check(t)
    return t


def preflight(
    scenario: Scenario | str | Path, backends: Sequence[str], contact_mode: str | None = None
) -> pd.DataFrame:
    """The run's pre-flight: the backends about to run, loaded in the run's ``contact_mode`` (default: the
    scenario's), hold the spec's leg, limits and gravity, or an error (:class:`ParityError`). A backend whose
    engine fails to load or read back is left to fail its own run: a warning line says so, the others are
    checked (a failing engine never takes the others down)."""
    failed: dict[str, str] = {}
    t = table(scenario, backends, contact_mode, failed)
    for line in failed.values():
        if line not in _WARNED:  # once per process: a run of several scenarios pre-flights each
            _WARNED.add(line)
            logger.warning("legbench: warning: %s; not checked, its run fails alone", line)
    check(t)
    return t


def _cell(v: Any) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, float):
        return f"{v:.9g}"
    return str(v)


def _cli(args: argparse.Namespace) -> int:
    names = registry.resolve(args.backends)  # the options' errors first, as every command's
    sc = scenario_mod.load(args.scenario, yamlfile.parse_overrides(args.set), engines=names)  # what `run --set` runs
    failed: dict[str, str] = {}
    t = table(sc, names, failed=failed)
    shown = t if args.all else t[t["status"] != "info"]
    width = {c: max(len(c), *(len(_cell(v)) for v in shown[c])) for c in shown.columns}
    print("  ".join(c.ljust(width[c]) for c in shown.columns))
    for r in shown.itertuples(index=False):
        print("  ".join(_cell(v).ljust(width[c]) for c, v in zip(shown.columns, r, strict=True)))
    if not args.all:
        print(f"({int((t['status'] == 'info').sum())} settings rows not shown; --all shows them)")
    sys.stdout.flush()  # the table first, then what failed, on stderr (a script reading the table gets the table)
    for line in failed.values():
        print(f"legbench: error: {line}", file=sys.stderr)
    try:
        check(t)
    except ParityError as exc:
        print(f"legbench: error: {exc}", file=sys.stderr)
        return 1
    if failed:
        return EXIT_BACKEND_FAILED
    print(verdict(t))
    return 0


def add_cli(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register ``legbench doctor SCENARIO [--backends all] [--all] [--set KEY=VALUE ...]``."""
    p = subparsers.add_parser("doctor", help="parity pre-flight: what each engine holds, read back, side by side")
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument("--backends", default="all", help="comma-separated backend names, or 'all' (default)")
    p.add_argument("--all", action="store_true", help="also show every setting each backend reports")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key as legbench run does, e.g. --set profile=engine-defaults or "
                        "--set backends.<name>.dt=1e-4")  # fmt: skip
    p.set_defaults(func=_cli)
