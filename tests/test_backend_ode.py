"""ODE backend: profiles (matched, engine-defaults, gazebo), Gazebo's kp/kd -> ERP/CFM, joint stops, install hint.

The engine tests every backend passes (free space, mass properties, gravity,
contact balance, reference mode) are in tests/test_backends_engines.py; these
are the ODE-specific ones. Skipped where libode or odepy is missing.
"""

from __future__ import annotations

import ctypes
import dataclasses
import importlib.abc
import importlib.util
import re
import shutil
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from legbench import backends as registry
from legbench import kinematics, model, scenario
from legbench.backends.base import Backend, Physics
from legbench.contact import ContactParams
from legbench.exceptions import BackendNotFound, LegbenchError, ScenarioError

ode_ = pytest.importorskip("legbench.backends.ode_")
OdeBackend = ode_.OdeBackend

PARAMS = model.load_params()
R_FOOT = PARAMS.geometry.R_foot
CONTROL_DT = 1e-3  # [s]
KP_JOINT, KD_JOINT = 10.0, 1.0  # spec joint PD gains [N m/rad], [N m s/rad]
START = np.array([0.1667, 0.0, R_FOOT + 0.003])  # foot centre 3 mm above touching [m, W]


@pytest.fixture
def loaded() -> Iterator[list[Backend]]:
    """Backends loaded in a test, closed after it."""
    made: list[Backend] = []
    yield made
    for b in made:
        b.close()


def load(made: list[Backend], physics: Physics, profile: str = "matched", **settings: Any) -> Any:
    backend = registry.load("ode", physics, settings, profile=profile)
    made.append(backend)
    return backend


def press(backend: Any, push: np.ndarray, duration: float = 1.5) -> dict[str, np.ndarray]:
    """Lower the foot from 3 mm onto the ground under joint PD + gravity compensation, pressing with ``push`` [N].

    The PD target is the start pose moved by J_poc^T push / Kp_joint, so the joint springs
    press the foot with about ``push`` once it rests (as in tests/test_backends_engines.py).
    """
    q0 = kinematics.ik_nearest(START, np.array(PARAMS.q_star))
    q_target = q0 + kinematics.jacobian_poc(q0).T @ push / KP_JOINT
    backend.reset(q0, np.zeros(3))
    n = round(duration / CONTROL_DT)
    log = {"q": np.zeros((n, 3)), "tau": np.zeros((n, 3)), "F": np.zeros((n, 3))}
    for k in range(n):
        q, qd = backend.state()
        tau = KP_JOINT * (q_target - q) - KD_JOINT * qd + model.gravity_torque(q)
        backend.step(tau)
        log["tau"][k] = tau
        log["q"][k] = backend.state()[0]
        log["F"][k] = backend.ground_force()
    return log


def test_info_lists_only_the_settings_that_acted(loaded: list[Backend]) -> None:
    """The report's settings table lists what acted (as MuJoCo's, PyBullet's and Drake's do): in reference contact
    there are no contact joints, so their settings (the friction coefficient, the ground's stiffness and damping,
    the contact caps and layers) are left out and the law's reference_friction is there; native contact the other
    way round; the quick step's own settings only under dWorldQuickStep."""
    contact_only = set(ode_.CONTACT_ONLY)
    for mode, stepper in (("reference", "world"), ("native", "world"), ("native", "quick")):
        info = load(loaded, dataclasses.replace(Physics(), contact_mode=mode), stepper=stepper).info()
        assert (contact_only <= info.keys()) is (mode == "native"), mode
        assert ("reference_friction" in info) is (mode == "reference"), mode
        assert (set(ode_.QUICK_ONLY) <= info.keys()) is (stepper == "quick") and "erp" in info, stepper


# --------------------------------------------------------------------------- #
# profiles


def test_profiles_are_overlays_of_the_defaults() -> None:
    """matched, engine-defaults and gazebo exist, and every key of an overlay is a setting."""
    assert {"matched", "engine-defaults", "gazebo"} <= set(OdeBackend.profiles)
    for overlay in OdeBackend.profiles.values():
        assert set(overlay) <= set(OdeBackend.defaults)


def test_every_default_and_profile_value_lies_in_its_declared_range() -> None:
    """Each range ODE declares is for a setting it has, and the defaults and every profile's values lie in it
    (the validator refused ODE's own default 0 for cfm, stop_cfm, damping, ground_kd, contact_surface_layer)."""
    assert set(OdeBackend.ranges) <= set(OdeBackend.defaults)
    for profile in OdeBackend.profiles:
        settings = OdeBackend.resolve_settings({}, profile)
        for key, rng in OdeBackend.ranges.items():
            value = settings[key]
            assert (value is None and rng.nullable) or rng.problem(float(value)) is None, (profile, key, value)


BASE_SCENARIO = {"name": "t", "duration": 1.0, "events": [{"t": 0.0, "position": {"joint": [0, 0, 0]}}]}


def test_settings_of_zero_where_ode_allows_it_are_valid() -> None:
    """0 is a valid cfm, stop_cfm, damping, ground_kd, contact_surface_layer and erp (ODE's own defaults or
    documented bounds), and null switches off the optional ones: a sweep over cfm: [0.0, 1e-10] is accepted."""
    zeros = {k: 0 for k in ("cfm", "stop_cfm", "damping", "ground_kd", "contact_surface_layer", "erp", "stop_erp")}
    nulls = dict.fromkeys(("contact_max_correcting_vel", "surface_max_vel", "surface_min_depth", "ground_kp"))
    sc = scenario.parse({**BASE_SCENARIO, "backends": {"ode": {**zeros, **nulls}}}, "s.yaml")
    assert sc.backends["ode"]["cfm"] == 0.0 and sc.backends["ode"]["ground_kp"] is None
    schema = scenario.json_schema()["properties"]["backends"]["properties"]["ode"]["properties"]
    assert schema["cfm"] == {"type": "number", "minimum": 0.0} and schema["erp"]["maximum"] == 1.0
    for cfm in (0.0, 1e-10):  # the grid points of such a sweep
        assert scenario.parse({**BASE_SCENARIO, "backends": {"ode": {"cfm": cfm}}}, "s.yaml").backends["ode"] == {
            "cfm": cfm
        }


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("erp", 5, "must be in [0, 1], got 5"),
        ("erp", -0.1, "must be in [0, 1], got -0.1"),
        ("stop_erp", 1.5, "must be in [0, 1], got 1.5"),
        ("cfm", -1e-10, "must be >= 0, got -1e-10"),
        ("stop_cfm", -1, "must be >= 0, got -1"),
        ("damping", 2, "must be in [0, 1], got 2"),
        ("contact_surface_layer", -0.001, "must be >= 0, got -0.001"),
        ("ground_kp", 0, "must be > 0, got 0 (or null: the backend's default for it)"),
        ("ground_kd", -1, "must be >= 0, got -1"),
        ("surface_max_vel", "fast", "expected a number, got 'fast'"),
        ("dt", 0, "must be > 0, got 0"),
    ],
)
def test_settings_outside_the_range_ode_documents_are_refused_naming_the_key(key: str, value: Any, words: str) -> None:
    """An ERP outside [0, 1] (``erp: 5`` was accepted and diverged at the first tick), a negative CFM, damping
    scale outside [0, 1], a non-positive ground stiffness: a ScenarioError naming backends.ode.<key>."""
    with pytest.raises(ScenarioError) as err:
        scenario.parse({**BASE_SCENARIO, "backends": {"ode": {key: value}}}, "s.yaml")
    assert err.value.key == f"backends.ode.{key}" and words in err.value.problem


@pytest.mark.parametrize("profile", ["matched", "engine-defaults", "gazebo"])
def test_foot_lowered_onto_the_ground_carries_the_pressed_load(loaded: list[Backend], profile: str) -> None:
    """Per profile, native contact: the foot pressed with ~10 N rests, and F = -(J_poc^T)^-1 (tau - G) to 2 %.

    Also the normal force is the profile's spring on the whole depth:
    Fn = kp y to 0.5 %, with y = R_foot - z_E and kp the (series-combined)
    stiffness: no profile leaves a layer uncorrected (ODE's default layer is 0;
    in Gazebo the foot's own min_depth, 0 by default, replaces the world's 1 mm
    contact_surface_layer, so gazebo's foot does not rest 1 mm deeper).
    Measured (Fn 8.46 N): balance to 5e-12 (matched), 6e-5 (engine-defaults),
    1e-5 (gazebo); Fn vs kp y to 1e-9, 6e-4, 8e-5 (gazebo with the world's 1 mm
    layer: 0.56). 2 % is the spec's tolerance for the analytic check;
    0.5 % still catches a 1 mm layer (10 % of 10 N) or a wrong kp.
    """
    backend = load(loaded, Physics(), profile)
    log = press(backend, np.array([0.0, 0.0, -10.0]))
    F, q, tau = log["F"][-1], log["q"][-1], log["tau"][-1]
    h = np.linalg.solve(kinematics.jacobian_poc(q).T, tau - model.gravity_torque(q))
    assert F[2] > 5.0  # [N], carrying the load
    assert abs(F[2] - log["F"][-500, 2]) < 0.02 * F[2]  # settled over the last 0.5 s
    assert np.linalg.norm(F + h) < 0.02 * np.linalg.norm(h), (F, -h)
    info = backend.info()
    y = R_FOOT - kinematics.fk(q)[2]
    assert F[2] == pytest.approx(info["contact"]["kp_effective"] * y, rel=5e-3)


def test_gazebo_profile_converts_kp_kd_to_erp_cfm_as_gazebo_does(loaded: list[Backend]) -> None:
    """Kp = 1e4 N/m, Kd = 100 N s/m at Gazebo's 1 ms step: erp = dt kp / (dt kp + kd), cfm = 1 / (dt kp + kd).

    Gazebo (ODEPhysics::Collide) first combines the two surfaces: kp in series with
    the ground's default 1e12 N/m, kd plus the ground's default 1 N s/m; so
    kp = 9999.9999 N/m and kd = 101 N s/m, erp = 0.0900900892, cfm = 0.00900900901.
    Compared exactly (1e-12 relative: the same three floating-point operations) with
    the values on the contact the backend creates, and with the hand-computed numbers
    to 1e-9.
    """
    physics = Physics(contact=ContactParams(Kp=1e4, Kd=100.0))
    backend = load(loaded, physics, "gazebo")
    dt = 1e-3
    kp = 1.0 / (1.0 / 1e4 + 1.0 / 1e12)
    kd = 100.0 + 1.0
    surface = backend.contacts[0].surface
    assert backend.h == dt
    assert surface.soft_erp == pytest.approx(dt * kp / (dt * kp + kd), rel=1e-12)
    assert surface.soft_cfm == pytest.approx(1.0 / (dt * kp + kd), rel=1e-12)
    assert surface.soft_erp == pytest.approx(0.0900900892, rel=1e-9)
    assert surface.soft_cfm == pytest.approx(0.00900900901, rel=1e-9)
    assert surface.mu == surface.mu2 == physics.contact.mu_s


def test_gazebo_profile_world_settings_read_back_from_ode(loaded: list[Backend]) -> None:
    """Quick step with 50 iterations, SOR 1.3, ERP 0.2, CFM 0, 100 m/s, 1 ms: as ODE holds them.

    The surface layer and the damping are the values Gazebo's bodies end up with, 0 and 0: the foot's own
    min_depth (SDFormat default 0) replaces the world's 1 mm layer in the fork's contact row, and ODELink::Init
    sets each link's damping to its velocity_decay (0 by default) over the world's 1e-4.
    """
    world = load(loaded, Physics(), "gazebo").info()["world"]
    assert world == {
        "erp": 0.2,
        "cfm": 0.0,
        "quick_step_iterations": 50,
        "quick_step_sor": 1.3,
        "contact_max_correcting_vel": 100.0,
        "contact_surface_layer": 0.0,
        "linear_damping": 0.0,
        "angular_damping": 0.0,
    }
    profile = OdeBackend.profiles["gazebo"]
    assert profile["contact_surface_layer"] == 0.001 and profile["surface_min_depth"] == 0.0  # world's, foot's


def test_gazebo_profile_links_are_undamped_as_gazebo_leaves_them(loaded: list[Backend]) -> None:
    """Verification's energy case (1 s free 3D swing, no torque, no contact) on the gazebo profile: |dE| < 1e-2 J.

    Gazebo's links carry no ODE damping by default (ODELink::Init: their velocity_decay, 0), so only the 1 ms
    quick step's own error takes energy out: measured -5.0e-3 J of E0 = 4.29 J. ODE's world damping 1e-4 per
    step, which Gazebo sets and then overrides per link, would take -9.9e-2 J.
    """
    sc = scenario.load(model.ROOT / "scenarios" / "verification" / "energy.yaml")
    physics = Physics(gravity=sc.gravity, contact_mode="reference", contact=ContactParams(Kp=0.0, Kd=0.0))
    backend = load(loaded, physics, "gazebo")
    dyn = model.Dynamics(sc.gravity)
    backend.reset(np.array(sc.q0), np.array(sc.qd0))
    E0 = sum(dyn.energy(*backend.state()))
    for _ in range(round(sc.duration / CONTROL_DT)):
        backend.step(np.zeros(3))
    dE = sum(dyn.energy(*backend.state())) - E0
    assert E0 > 4.0 and abs(dE) < 1e-2, dE


def test_gazebo_fork_surface_values_override_the_world_ones() -> None:
    """Gazebo's ODE fork: a body's max_vel caps the world's (min), its min_depth replaces the surface layer."""
    eff = ode_._effective_correction
    base = dict(OdeBackend.defaults) | dict(OdeBackend.profiles["gazebo"])
    assert eff(base) == (100.0, 0.0)  # the foot's min_depth 0, not the world's 1 mm
    assert eff(base | {"surface_min_depth": None}) == (100.0, 0.001)  # no body value: the world's layer
    assert eff(base | {"surface_max_vel": 0.01, "surface_min_depth": 0.002}) == (0.01, 0.002)
    assert eff(base | {"surface_max_vel": 500.0}) == (100.0, 0.0)
    assert eff(dict(OdeBackend.defaults)) == (None, 0.0)  # stock ODE: no cap


def test_force_is_read_on_the_foot_side_when_the_ground_comes_first_in_the_pair(loaded: list[Backend]) -> None:
    """ODE may hand the pair as (ground, foot) (dSpaceCollide's order): the force read is the same, on the foot.

    dJointAttach(joint, 0, foot) swaps the static ground to the joint's second
    place (ode/src/ode.cpp: dJointAttach), so the foot's force is in f1 and f2 is
    never written (ode/src/step.cpp: feedback f2 only for a second body). The
    press is run twice, the pair's geoms once in ODE's order and once
    swapped: the steady force must be the same to 1e-9 N (both are the same
    contact; only the bookkeeping differs) and balance the statics to 2 %
    (reading the stale f2 gives 0 N).
    """
    forces = []
    for swap in (False, True):
        backend = load(loaded, Physics())
        if swap:
            g1, g2 = backend._pair
            backend._use_pair(g2, g1)
        log = press(backend, np.array([0.0, 0.0, -10.0]))
        ground = ctypes.cast(ode_.ode.dGeomGetBody(backend.plane), ctypes.c_void_p).value
        assert ground is None and backend._n_contacts == 1
        forces.append(log)
    F_ode, F_swapped = forces[0]["F"][-1], forces[1]["F"][-1]
    np.testing.assert_allclose(F_swapped, F_ode, rtol=0, atol=1e-9)
    q, tau = forces[1]["q"][-1], forces[1]["tau"][-1]
    h = np.linalg.solve(kinematics.jacobian_poc(q).T, tau - model.gravity_torque(q))
    assert F_swapped[2] > 5.0 and np.linalg.norm(F_swapped + h) < 0.02 * np.linalg.norm(h), (F_swapped, -h)


def space_collide_step(backend: Any) -> None:
    """The native step as it was with ``dSpaceCollide`` and a near callback from C into Python."""
    ode, h = ode_.ode, backend.h
    t0, t1, t2 = backend._u
    j0, j1, j2 = backend.joints

    def near(_data: Any, g1: Any, g2: Any) -> None:
        n = ode_._collide(g1, g2, ode_.MAX_CONTACTS, backend._contact_geoms, ode_._CONTACT_STRIDE)
        backend._use_pair(g1, g2)
        backend._add_contacts(n)
        backend._n_contacts = n

    callback = ode.dNearCallback(near)
    for _ in range(backend.n_sub):
        ode.dJointGroupEmpty(backend.contact_group)
        backend._n_contacts = 0  # what is left where the bounding boxes do not meet (no callback)
        ode.dSpaceCollide(backend.space, None, callback)
        ode.dJointAddHingeTorque(j0, t0)
        ode.dJointAddHingeTorque(j1, t1)
        ode.dJointAddHingeTorque(j2, t2)
        backend._world_step(backend.world, h)
    backend._read()
    backend._native_force()


def test_the_native_step_collides_the_pair_as_dspacecollide_did_bit_for_bit(loaded: list[Backend]) -> None:
    """The native step calls dCollide on its one pair itself: the same run, bit for bit, as dSpaceCollide
    with a near callback (the pair in ODE's order, its bounding-box test first), through flight, touch-down
    and a press."""
    logs = []
    for via_space in (False, True):
        backend = load(loaded, Physics())
        if via_space:
            backend._step = lambda b=backend: space_collide_step(b)
        q0 = kinematics.ik_nearest(START + np.array([0.0, 0.0, 0.005]), np.array(PARAMS.q_star))
        backend.reset(q0, np.zeros(3))
        rows = []
        for k in range(400):
            q, qd = backend.state()
            target = q0 + kinematics.jacobian_poc(q0).T @ np.array([0.0, 0.0, -10.0 * min(k, 200) / 200]) / KP_JOINT
            backend.step(KP_JOINT * (target - q) - KD_JOINT * qd + model.gravity_torque(q))
            rows.append(np.concatenate([*backend.state(), backend.ground_force()]))
        logs.append(np.array(rows))
    fz = logs[0][:, 8]
    assert fz[0] == 0.0 and fz[-1] > 5.0  # flight, then the foot carries the press
    assert np.array_equal(logs[0], logs[1])


def test_load_refuses_a_collision_space_with_more_than_the_foot_and_the_ground(monkeypatch: pytest.MonkeyPatch) -> None:
    """The native step collides the foot-ground pair alone: a third geom in the space is an error at load."""
    create_plane = ode_.ode.dCreatePlane

    def plane_and_box(space: Any, *args: Any) -> Any:
        ode_.ode.dCreateBox(space, 1.0, 1.0, 1.0)
        return create_plane(space, *args)

    monkeypatch.setattr(ode_.ode, "dCreatePlane", plane_and_box)
    with pytest.raises(LegbenchError, match="exactly the foot sphere and the ground plane .* it holds 3 geoms"):
        registry.load("ode", Physics(), {})


def test_contact_without_stiffness_or_damping_exerts_no_force(loaded: list[Backend]) -> None:
    """Kp = Kd = 0 (verification's energy case): no contact joint, zero force, the leg swings through the ground."""
    backend = load(loaded, Physics(contact=ContactParams(Kp=0.0, Kd=0.0)))
    backend.reset(np.array([0.0, -np.pi / 2, 0.0]), np.zeros(3))  # foot below z = 0
    backend.step(np.zeros(3))
    assert backend.contact_bodies() == []
    assert np.array_equal(backend.ground_force(), np.zeros(3))


# --------------------------------------------------------------------------- #
# joints


def test_limits_are_the_urdf_stops_read_back_from_ode(loaded: list[Backend]) -> None:
    """dJointGetHingeParam: ab/ad +-pi/2, knee +-2.229, continuous hip none (+-inf); gravity and step.

    1e-11 rad (read back exactly now that the URDF writes pi/2 with repr; 5e-12 off at 12 digits).
    """
    lim = load(loaded, Physics(gravity=9.81)).limits()
    np.testing.assert_allclose(lim.lower, PARAMS.lower, rtol=0, atol=1e-11)
    np.testing.assert_allclose(lim.upper, PARAMS.upper, rtol=0, atol=1e-11)
    assert lim.lower[1] == -np.inf and lim.upper[1] == np.inf
    assert lim.gravity == 9.81
    assert lim.timestep == OdeBackend.defaults["dt"]


@pytest.mark.parametrize(("profile", "overshoot", "rest"), [("matched", 1e-3, 1e-6), ("gazebo", 0.02, 2e-3)])
def test_knee_driven_into_its_stop_rests_there(loaded: list[Backend], profile: str, overshoot: float,
                                               rest: float) -> None:  # fmt: skip
    """10 N m drives the knee into its 2.229 rad stop: it overshoots less than ``overshoot`` and rests within ``rest``.

    Gravity off, no contact. Measured: matched (exact solver, stop CFM 0, 0.05 ms)
    peaks 3.9e-6 rad past the stop and rests on it to 1e-15; gazebo (quick step,
    1 ms) peaks 0.015 rad past and rests 1.2e-6 past it.
    """
    backend = load(loaded, Physics(gravity=0.0, contact_mode="reference"), profile)
    backend.reset(np.array([0.0, 0.5, 1.5]), np.zeros(3))
    knee = []
    for _ in range(1000):
        backend.step(np.array([0.0, 0.0, 10.0]))
        knee.append(backend.state()[0][2])
    upper = PARAMS.upper[2]
    assert max(knee) < upper + overshoot
    assert abs(knee[-1] - upper) < rest


def test_hinge_angles_and_rates_equal_the_reset_state(loaded: list[Backend]) -> None:
    """Bodies posed by reset read back as the same q and qd (the FK and velocities given to ODE are consistent)."""
    backend = load(loaded, Physics())
    q, qd = np.array([0.3, 4.0, -1.2]), np.array([0.5, -2.0, 3.0])  # hip past pi: reported unwrapped
    backend.reset(q, qd)
    q_got, qd_got = backend.state()
    np.testing.assert_allclose(q_got, q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(qd_got, qd, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------- #
# a machine without libode


class _NoLibode(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Makes ``import odepy`` fail the way odepy does when libode is absent (its own exception, not ImportError)."""

    def find_spec(self, name: str, path: Any, target: Any = None) -> Any:
        return importlib.util.spec_from_loader(name, self) if name == "odepy" else None

    def create_module(self, spec: Any) -> None:
        return None

    def exec_module(self, module: Any) -> None:
        raise RuntimeError("ODE library not found.")  # odepy.common.OdePyError is a plain Exception


def test_missing_libode_is_an_import_error_and_the_registry_names_the_install_command(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Without libode the module import fails with ImportError; asking for ``ode`` names the one install command."""
    for name in ("odepy", "legbench.backends.ode_"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    monkeypatch.setattr(sys, "meta_path", [_NoLibode(), *sys.meta_path])
    with pytest.raises(ImportError, match="libode is missing"):
        importlib.import_module("legbench.backends.ode_")
    with pytest.raises(BackendNotFound, match=r"apt-get install -y libode8 && pip install ode-python"):
        registry.get("ode")
    assert OdeBackend.install == "apt-get install -y libode8 && pip install ode-python"


def test_version_names_the_release_and_the_library_file_loaded() -> None:
    """libode names no version of its own (its soname spans releases): the info's version is the release of the
    system package owning the file this process loaded (dpkg), then that file; a file no package owns (a library
    built from source) says so instead of guessing."""
    version = ode_._ode_version()
    path = ode_._loaded_library()
    assert path is not None and "/libode.so" in path and f"; {path}; " in version
    owner = ode_._package_release(path)
    if shutil.which("dpkg-query") is not None:  # Debian, as make installs it
        assert owner is not None and re.fullmatch(r"\d+\.\d+(\.\d+)?", owner[0]), owner
        assert version.startswith(f"{owner[0]} ({owner[1]}; ")
    assert ode_._package_release("/nonexistent/libode.so.8") is None
    assert ode_._package_release(None) is None


@pytest.mark.parametrize("mode", ["native", "reference"])
@pytest.mark.parametrize(
    ("profile", "row_order", "dt"),
    [("engine-defaults", "advancing", 1e-3), ("engine-defaults", "advancing", 5e-4), ("gazebo", "repeated", 1e-3),
     ("gazebo", "repeated", 5e-4)],
)  # fmt: skip
def test_quick_step_row_order_advances_as_odes_or_repeats_each_step_as_gazebos_fixed_order(
    loaded: list[Backend], monkeypatch: pytest.MonkeyPatch, mode: str, profile: str, row_order: str, dt: float
) -> None:
    """Quick step shuffles its constraint rows with ODE's one global generator. The backend re-seeded it before
    every step in every profile, so stock ODE's own behaviour (engine-defaults), a new order each step, was never
    run. ``row_order: advancing`` (the default) seeds at reset and carries the instance's generator on: the seed
    set before a control period is where the previous one left it, and a reset starts afresh. ``repeated``
    (gazebo: Gazebo's fork does not reorder, so one fixed order per step is the nearest) seeds before every step.
    Either way a reset run repeats bit for bit, and two instances stepped in lockstep in contact each equal a solo
    run bit for bit. At two steps per control period (dt 0.5 ms) ``advancing`` still sets the seed once a period
    (the two steps draw on in between) and ``repeated`` before each step."""
    physics = Physics(contact_mode=mode)
    a, b, solo = (load(loaded, physics, profile, dt=dt) for _ in range(3))
    assert solo.info()["row_order"] == row_order
    set_seeds: list[int] = []
    real_set = ode_._set_seed

    def recording_set(seed: int) -> None:
        set_seeds.append(int(seed))
        real_set(seed)

    monkeypatch.setattr(ode_, "_set_seed", recording_set)
    runs = [press(x, np.array([4.0, 0.0, -20.0]), duration=0.2) for x in (solo, solo)]  # a run, and after a reset
    per_period = 1 if row_order == "advancing" else round(1e-3 / dt)  # once a period, or before every step
    assert len(set_seeds) == 400 * per_period
    if row_order == "advancing":
        assert set_seeds[0] == set_seeds[200] == ode_.SEED and len(set(set_seeds[:200])) == 200
    else:
        assert set(set_seeds) == {ode_.SEED}
    for key in ("q", "F"):
        np.testing.assert_array_equal(runs[0][key], runs[1][key])
    assert runs[0]["F"][-1, 2] > 15.0  # [N] in contact: the quick step solves contact rows to shuffle
    q0 = kinematics.ik_nearest(START, np.array(PARAMS.q_star))
    for x in (a, b, solo):
        x.reset(q0, np.zeros(3))
    tau = model.gravity_torque(q0) + kinematics.jacobian_poc(q0).T @ np.array([4.0, 0.0, -20.0])
    for _ in range(200):
        a.step(tau)
        b.step(tau * 0.5)
        solo.step(tau)
    np.testing.assert_array_equal(a.state()[0], solo.state()[0])
    np.testing.assert_array_equal(a.ground_force(), solo.ground_force())
    assert not np.array_equal(a.state()[0], b.state()[0])


def _scored_with_context(monkeypatch: pytest.MonkeyPatch, profile: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The ODE drag scored (sliding_case.score): its slip-acceleration row and the info its known_deviation was
    asked with (the run's info with ``drag``, what the scoring measured of the run)."""
    from legbench.studies import sliding_case as S

    asked: dict[str, Any] = {}
    real = S.explained_note

    def spy(cls: type[Backend], case: str, quantity: str, info: Any, *rest: Any) -> str:
        asked[quantity] = info
        return real(cls, case, quantity, info, *rest)

    monkeypatch.setattr(S, "explained_note", spy)
    tr, physics = S.drag("ode", profile)
    (row,) = [r for r in S.score(tr, physics) if r["quantity"].startswith("slip acceleration")]
    return row, asked[row["quantity"]]


def test_the_dantzig_bound_explains_the_sliding_row_only_where_its_closed_form_meets_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """base.py's contract: an explanation holds the row's own measured value to a closed form. dWorldStep's Dantzig
    LCP bounds friction by mu times the normal impulse solved before any friction row: re-solving each scored
    sample without friction (frictionless_normal, one sub-step with mu = mu2 = 0) predicts that bound, Fn0 / Fn =
    1.0097, 0.7068 Fn (a reviewer's check, 28 Nov: it was taken from the run's own forces until then; the run slid
    at 0.7068, to 1e-5), and the pyramid's closed form with it gives 3.617 m/s^2 against the measured 3.620 (0.11 %;
    4.076 at mu). Nothing is said where the row is far from it, where the prediction is missing, or for the quick
    step, which bounds by the current normal force."""
    row, info = _scored_with_context(monkeypatch, "matched")
    drag = info["drag"]
    assert drag["predicted_bound"] == pytest.approx(drag["friction_bound"], abs=1e-4) and drag["mu"] == 0.7
    assert drag["predicted_bound"] == pytest.approx(0.7068, abs=5e-4) and drag["predicted_holds"] == 0.0
    assert drag["at_predicted"]["acceleration"] == pytest.approx(row["measured"], rel=0.005)
    assert not row["passed"] and row["expected"] == pytest.approx(4.076, abs=0.005), row
    assert row["note"].startswith("known: dWorldStep's Dantzig LCP") and "met to" in row["note"], row["note"]
    assert (
        f"that bound is predicted at {drag['predicted_bound']:.4g} Fn (mu 0.7 x Fn0 / Fn; measured, the run slid at"
        in row["note"]
    ), row["note"]
    assert f"reads {drag['at_predicted']['acceleration']:.4g}" in row["note"], row["note"]
    ask = OdeBackend.known_deviation
    q, expected, tol = row["quantity"], row["expected"], row["tolerance"]
    assert ask("sliding", q, info, row["measured"], expected, tol) is not None
    for far in (8.0, -50.0, expected):  # far from the closed form at the predicted bound (4.076: the one at mu)
        assert ask("sliding", q, info, far, expected, tol) is None, far
    no_prediction = {k: v for k, v in drag.items() if k not in ("predicted_bound", "predicted_holds", "at_predicted")}
    assert ask("sliding", q, {**info, "drag": no_prediction}, row["measured"], expected, tol) is None
    assert ask("sliding", q, {"stepper": "world"}, 3.62, expected, tol) is None
    assert ask("sliding", q, {**info, "stepper": "quick"}, row["measured"], expected, tol) is None


def test_the_frictionless_normal_predicts_the_bound_the_drag_slides_at() -> None:
    """frictionless_normal re-solves one dWorldStep sub-step from a logged state with mu = mu2 = 0; mu times it is
    the bound the run's friction along the drag had: at every sample of the sliding window 0.7 Fn0 meets the
    logged |F_y| to 1e-4 of Fn (measured 2e-5), where 0.7 Fn misses it by 1 %. The contact's mu is back
    afterwards; the quick step (it bounds by the current normal force) and reference contact give None."""
    from legbench.run import simulate
    from legbench.scenario import physics_of
    from legbench.studies import sliding_case as S

    sc = S._scenario()
    physics = physics_of(sc, "native")
    b = registry.load("ode", physics, {}, "matched")
    assert isinstance(b, OdeBackend)
    try:
        tr = simulate(sc, b, physics)
        ks = np.flatnonzero((tr.t >= S.WINDOW[0] - 1e-9) & (tr.t <= S.WINDOW[1] + 1e-9))
        fn0 = np.array([b.frictionless_normal(tr.q[k], tr.qd[k], tr.tau[k]) for k in ks], float)
        assert b.contacts[0].surface.mu == b.contacts[0].surface.mu2 == physics.contact.mu_s
    finally:
        b.close()
    fn, fy = tr.f[ks, 2], np.abs(tr.f[ks, 1])
    assert np.abs(0.7 * fn0 - fy).max() < 1e-4 * fn.max(), np.abs(0.7 * fn0 - fy).max()
    assert np.abs(0.7 * fn - fy).min() > 5e-3 * fn.min()
    for settings, mode in (({"stepper": "quick"}, "native"), ({}, "reference")):
        other = registry.load("ode", physics_of(sc, mode), settings, "matched")
        try:
            assert other.frictionless_normal(tr.q[ks[0]], tr.qd[ks[0]], tr.tau[ks[0]]) is None
        finally:
            other.close()


def test_the_quick_steps_pole_misses_are_plain_misses() -> None:
    """The engine-defaults quick step's six pole rows carried a fixed text (130-150 Hz spurious modes, hinge errors
    typed from another run) for any value: no closed form of a fitted pole holds them, so nothing is said now."""
    info = {"stepper": "quick", "iterations": 20, "row_order": "advancing"}
    for quantity, measured, expected in (
        ("mode 1 frequency", 129.6, 1.755),
        ("mode 2 decay rate", 23.9, 10.64),
        ("mode 1 damping ratio", 0.0035, 0.638),
        ("mode 1 frequency", -50.0, 1.755),
    ):
        assert OdeBackend.known_deviation("small_oscillation", quantity, info, measured, expected, 0.01) is None
