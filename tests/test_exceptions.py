"""legbench's errors survive a trip between processes (pickle), as the worker pools of run and compare need."""

from __future__ import annotations

import inspect
import pickle
from typing import Any

import pytest

from legbench import exceptions as E

#: Constructor arguments of every error class in legbench.exceptions (positional, keyword).
SAMPLES: dict[type[E.LegbenchError], list[tuple[tuple[Any, ...], dict[str, Any]]]] = {
    E.LegbenchError: [(("plain message",), {})],
    E.ModelError: [(("models/leg.yaml: link2.mass: must be > 0",), {})],
    E.Unreachable: [(("point (1, 2, 3) is outside the workspace",), {})],
    E.ScenarioError: [
        (("scenarios/a.yaml", "events[2].target", "must be a list of 3 numbers"), {}),
        (("scenarios/a.yaml", "", "top level must be a mapping"), {"line": 7}),
    ],
    # a dict's keys view does not pickle: the error must keep the sorted list it shows
    E.BackendNotFound: [(("drake", {"mujoco": 1, "ode": 2}.keys()), {"hint": "pip install drake"})],
    E.UnknownBackend: [
        (("bogus", {"mujoco": 1}.keys()), {}),
        (("ode", ["mujoco"], "pip install ode-python", True, "backends"), {}),
    ],
    E.SimulationDiverged: [(("ode", 0.1234, "q2 is NaN"), {})],
    E.ResultsError: [
        (("results/x/a.parquet", "not a readable parquet file"), {}),
        (("results/x/run.json", "must be a finite number > 0, not 'abc'"), {"key": "scenario.duration"}),
    ],
}


def _classes() -> list[type[E.LegbenchError]]:
    return [c for _, c in inspect.getmembers(E, inspect.isclass) if issubclass(c, E.LegbenchError)]


def test_every_error_class_has_a_pickling_sample() -> None:
    """A class added to legbench.exceptions without a sample here would go untested: fail loudly instead."""
    assert set(_classes()) == set(SAMPLES)


@pytest.mark.parametrize(
    ("cls", "args", "kwargs"),
    [(c, a, k) for c, samples in SAMPLES.items() for a, k in samples],
    ids=lambda v: v.__name__ if isinstance(v, type) else "",
)
def test_an_error_round_trips_through_pickle_with_its_message_and_attributes(
    cls: type[E.LegbenchError], args: tuple[Any, ...], kwargs: dict[str, Any]
) -> None:
    """A worker process's error reaches the parent by pickle: the parent prints str(exc), and the CLI and
    callers read its attributes (file, key, problem); a failure to unpickle broke the process pool instead."""
    exc = cls(*args, **kwargs)
    exc.add_note("a note added after construction")  # state set after __init__ travels too
    back = pickle.loads(pickle.dumps(exc))
    assert type(back) is cls
    assert str(back) == str(exc)
    assert back.args == exc.args
    assert vars(back) == vars(exc)
    assert getattr(back, "__notes__", None) == ["a note added after construction"]


def test_a_subclass_defined_elsewhere_with_its_own_arguments_pickles() -> None:
    """Errors defined outside legbench.exceptions (a study's ParityError) get the same round trip for free."""

    class Local(E.LegbenchError):
        def __init__(self, backend: str, row: str, *, more: int = 0) -> None:
            self.backend, self.row, self.more = backend, row, more
            super().__init__(f"{backend}: {row} ({more} more)")

    globals()["Local"] = Local  # pickle finds classes by module-level name
    Local.__qualname__ = "Local"
    try:
        back = pickle.loads(pickle.dumps(Local("ode", "link2.mass", more=2)))
    finally:
        del globals()["Local"]
    assert str(back) == "ode: link2.mass (2 more)"
    assert (back.backend, back.row, back.more) == ("ode", "link2.mass", 2)
