"""Errors legbench raises on purpose. Only :mod:`legbench.cli` catches them.

Every error pickles and unpickles to an equal one (same type, message and attributes): an error raised in a
worker process (``legbench compare TREE --jobs 2``, ``legbench run --jobs 2``) reaches the parent whole, so
the command prints its one line instead of a broken process pool. The default pickling of an exception
calls ``type(exc)(*exc.args)`` with the *message* as the only argument, which fails for a subclass whose
``__init__`` takes other arguments; :class:`LegbenchError` therefore remembers the arguments it was built
with and rebuilds from them, for every subclass, including those defined outside this module.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any


def _rebuild(cls: type[LegbenchError], args: tuple[Any, ...], kwargs: dict[str, Any]) -> LegbenchError:
    """Unpickle a :class:`LegbenchError`: call its constructor again with the arguments it was built with."""
    return cls(*args, **kwargs)


class LegbenchError(Exception):
    """Base of every error legbench raises for the user to read (picklable, whatever its ``__init__`` takes)."""

    _init_args: tuple[Any, ...]
    _init_kwargs: dict[str, Any]

    def __new__(cls, *args: Any, **kwargs: Any) -> LegbenchError:
        self = super().__new__(cls, *args)
        self._init_args, self._init_kwargs = args, kwargs
        return self

    def __reduce__(self) -> tuple[Any, ...]:
        state = {k: v for k, v in self.__dict__.items() if k not in ("_init_args", "_init_kwargs")}
        return _rebuild, (type(self), self._init_args, self._init_kwargs), state or None


class ModelError(LegbenchError):
    """The leg's parameter file is malformed or inconsistent."""


class Unreachable(LegbenchError):
    """A Cartesian point lies outside the leg's workspace or joint limits."""


class ScenarioError(LegbenchError):
    """A scenario (or sweep, or tolerance) file is invalid.

    Attributes:
        file: the file the problem is in.
        key: dotted key path of the offending value (``events[2].target``).
        problem: what is wrong, one sentence.
    """

    def __init__(self, file: str, key: str, problem: str, line: int | None = None) -> None:
        self.file = str(file)
        self.key = key
        self.problem = problem
        self.line = line
        where = f"{self.file}:{line}" if line is not None else self.file
        super().__init__(f"{where}: {key}: {problem}" if key else f"{where}: {problem}")


class BackendNotFound(LegbenchError):
    """A backend name that is not installed or not known."""

    def __init__(self, name: str, available: Iterable[str], hint: str = "") -> None:
        self.name = name
        self.available = sorted(available)
        self.hint = hint
        self._init_args, self._init_kwargs = (name, self.available, hint), {}  # an iterator would not pickle
        msg = f"backend '{name}' is not available" + (f" ({hint})" if hint else "")
        super().__init__(f"{msg}; available here: {', '.join(self.available) or 'none'}")


class UnknownBackend(BackendNotFound):
    """A backend name given by the user (``option``: ``--backends``, or the API's ``backends``) that cannot run
    here, in one line naming the option: ``--backends bogus: unknown backend; available here: dart, drake, ...``,
    or for a backend legbench knows (``known``) whose engine is not installed, ``--backends ode: not installed
    here (what to install); ...``."""

    def __init__(self, name: str, available: Iterable[str], hint: str = "", known: bool = False,
                 option: str = "--backends") -> None:  # fmt: skip
        super().__init__(name, available, hint)
        self._init_args, self._init_kwargs = (name, self.available, hint, known, option), {}
        what = "not installed here" + (f" ({hint})" if hint else "") if known else "unknown backend"
        names = ", ".join(self.available) or "none"
        self.args = (f"{option} {name}: {what}; available here: {names}",)


class SimulationDiverged(LegbenchError):
    """A backend's state became non-finite or left its physical bounds."""

    def __init__(self, backend: str, t: float, reason: str) -> None:
        self.backend = backend
        self.t = t
        self.reason = reason
        super().__init__(f"{backend} diverged at t = {t:.4f} s: {reason}")


class ResultsError(LegbenchError):
    """A run directory, imported log, metrics file or baseline is missing or malformed.

    Attributes:
        file: the file or directory the problem is in.
        problem: what is wrong, one sentence.
        key: dotted key path of the offending value in a JSON file (``scenario.duration``), or "".
    """

    def __init__(self, file: str, problem: str, key: str = "") -> None:
        self.file = str(file)
        self.problem = problem
        self.key = key
        super().__init__(f"{self.file}: {key}: {problem}" if key else f"{self.file}: {problem}")
