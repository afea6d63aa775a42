"""The backend contract's plain helpers (:mod:`legbench.backends.base`), engine-free: where a run's force acted
(``contact_point``), a rigid contact's declaration, the one sub-step rule and a setting's range."""

from __future__ import annotations

import math
from typing import Any

import pytest

from legbench.backends.base import Range, contact_point, dt_problem, rigid_contact, sub_step_count
from legbench.exceptions import LegbenchError


@pytest.mark.parametrize(
    ("info", "law_poc", "want"),
    [
        ({"contact": {"poc": "true", "lift": 0.5}}, "true", ("true", 0.5)),  # MuJoCo: halfway through y
        ({"contact": {"poc": "centre", "lift": 0.0}}, "true", ("centre", 0.0)),  # a law at the sphere centre
        ({"contact": {"lift": 1e-8}}, "centre", ("centre", 1e-8)),  # no poc declared: the scenario's law's
        ({"contact": {"poc": "true"}}, "true", ("true", 0.0)),  # no lift declared: the lowest point
        ({"contact": {"poc": "elsewhere", "lift": "half"}}, "true", ("true", 0.0)),  # not a poc, not a number
        ({"contact": {"poc": "true", "lift": True}}, "true", ("true", 0.0)),  # a bool is not a fraction
        ({"contact": None}, "centre", ("centre", 0.0)),
        ({}, "true", ("true", 0.0)),  # an imported log declares nothing
        (None, "centre", ("centre", 0.0)),
    ],
)
def test_contact_point_is_the_declared_one_else_the_law_s_lowest_point(
    info: dict[str, Any] | None, law_poc: str, want: tuple[str, float]
) -> None:
    """Every check that maps the force to joint torques takes the point a backend's info declares (contact.poc,
    contact.lift as a fraction of the penetration above the lowest point); what is not declared, or not a poc or a
    number, falls back to the scenario's law's poc and lift 0, exactly."""
    assert contact_point(info, law_poc) == want


def test_a_rigid_contact_is_declared_by_a_null_stiffness() -> None:
    """contact.Kp given and null is a rigid contact (DART's LCP); a number, or no Kp at all, is not."""
    assert rigid_contact({"contact": {"Kp": None}})
    assert not rigid_contact({"contact": {"Kp": 1e4}})
    assert not rigid_contact({"contact": {}})
    assert not rigid_contact({})


@pytest.mark.parametrize(
    ("dt", "n"),
    [(1e-3, 1), (5e-4, 2), (5e-5, 20), (1e-5, 100), (1e-3 / 3, 3)],  # whole fractions of 1 ms
)
def test_a_sub_step_that_divides_the_control_period_counts_its_steps(dt: float, n: int) -> None:
    """1 ms / dt a whole number (to 1e-9, for steps like 1/3 ms that are not exact in binary): that many steps."""
    assert dt_problem(dt, 1e-3) is None
    assert sub_step_count("x", dt, 1e-3) == n


@pytest.mark.parametrize("dt", [3e-4, 2e-3, 0.0, -1e-4])
def test_a_sub_step_that_does_not_divide_the_control_period_is_refused_with_the_key(dt: float) -> None:
    """0.3 ms (3.33 steps), 2 ms (longer than the period), 0 and a negative step: refused, naming the backend's key
    and a step that would work."""
    why = dt_problem(dt, 1e-3)
    assert why is not None and "does not divide the control period 0.001 s" in why
    with pytest.raises(LegbenchError, match=r"^backends\.x\.dt: "):
        sub_step_count("x", dt, 1e-3)


def test_a_range_says_its_bounds_open_or_closed() -> None:
    """[0, 1] takes both ends; (0, inf) refuses 0 and takes any positive number; the phrase names the range."""
    closed, open_low = Range(0.0, 1.0), Range(0.0, math.inf, open_low=True)
    assert closed.problem(0.0) is None and closed.problem(1.0) is None
    assert closed.problem(1.5) == "must be in [0, 1], got 1.5"
    assert open_low.problem(1e-300) is None
    assert open_low.problem(0.0) == "must be > 0, got 0"
