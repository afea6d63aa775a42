"""Errors legbench raises on purpose. Only :mod:`legbench.cli` catches them."""

from __future__ import annotations

from collections.abc import Iterable


class LegbenchError(Exception):
    """Base of every error legbench raises for the user to read."""


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
        msg = f"backend '{name}' is not available. Available backends: {self.available}"
        if hint:
            msg += f" ({hint})"
        super().__init__(msg)


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
    """

    def __init__(self, file: str, problem: str) -> None:
        self.file = str(file)
        self.problem = problem
        super().__init__(f"{self.file}: {problem}")
