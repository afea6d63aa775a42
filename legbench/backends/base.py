"""The one backend interface: load, reset, step one control period, read.

A backend knows nothing of controllers, scenarios or logging. The run loop
hands it the same joint torques at the same instants as every other backend;
it advances its engine one control period under that held torque (zero-order
hold) with whatever sub-steps it uses, and reports state and ground force.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from legbench.contact import ContactParams


@dataclass(frozen=True)
class Physics:
    """Physics every backend must honour.

    Attributes:
        gravity: magnitude of gravity along -z_W [m/s^2].
        contact: ground contact parameters.
        contact_mode: ``"native"`` (the engine's own contact with the spec's
            parameters mapped onto it) or ``"reference"`` (engine contact off;
            the analytic law of :mod:`legbench.contact` applied as J_poc^T F at
            every sub-step).
        control_dt: control period, the length of one :meth:`Backend.step` [s].
        torque_limit: joint torque limits [N m], applied by the harness; a
            backend may also configure its actuators with them.
    """

    gravity: float = 9.81
    contact: ContactParams = field(default_factory=ContactParams)
    contact_mode: str = "native"
    control_dt: float = 1e-3
    torque_limit: tuple[float, float, float] = (7.051408, 10.07344, 10.07344)


class Backend(ABC):
    """A physics engine simulating the leg.

    Subclasses set :attr:`name` and :attr:`defaults` (their settings with
    documented default values) and implement the abstract methods. Settings a
    scenario gives for this backend are merged over :attr:`defaults`; an
    unknown key is an error (the scenario loader checks it against
    :attr:`defaults`).
    """

    name: ClassVar[str]
    #: Backend settings and their defaults, e.g. {"dt": 1e-4, "integrator": "euler"}.
    defaults: ClassVar[Mapping[str, Any]] = {}
    #: Allowed values of string settings, e.g. {"integrator": ("euler", "rk4")}.
    choices: ClassVar[Mapping[str, tuple[str, ...]]] = {}

    @abstractmethod
    def load(self, urdf: Path, physics: Physics, settings: Mapping[str, Any]) -> None:
        """Build the engine's model of the leg from the generated URDF."""

    @abstractmethod
    def reset(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Set joint positions q [rad] and velocities qd [rad/s]; contact state cleared."""

    @abstractmethod
    def step(self, tau: np.ndarray) -> None:
        """Advance one control period with joint torques tau [N m] held constant."""

    @abstractmethod
    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions q [rad] (hip unwrapped, continuous in time) and velocities qd [rad/s]."""

    @abstractmethod
    def ground_force(self) -> np.ndarray:
        """Force of the ground on the foot in W [N] (fx, fy, fz), at the end of the last step."""

    @abstractmethod
    def info(self) -> dict[str, Any]:
        """Engine name and version and every physics setting actually used (JSON-serialisable)."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release engine resources."""

    def mass_properties(self) -> dict[str, dict[str, Any]]:
        """Per moving body (link1, link2, link3 incl. foot): mass [kg], com [m] and inertia
        about the COM [kg m^2], in the link's DH frame, as read back from the engine."""
        raise NotImplementedError(f"mass_properties is not supported by {self.name}")

    def settings(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """Defaults overlaid with the scenario's settings for this backend."""
        return {**self.defaults, **given}
