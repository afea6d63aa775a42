"""The leg model: parameter file -> mass properties -> URDF -> Pinocchio model.

``models/leg.yaml`` is the one source of truth. This module reads it into frozen
dataclasses, composes each link's inertia from the CAD primitives (scaled by the
calibration factors), writes ``models/leg.urdf`` and builds the Pinocchio model
that :mod:`legbench.kinematics` uses for G(q).

Frames: W is the world (z up, ground z = 0); link frames are the modified-DH
frames of docs/spec.md section 1, so the URDF child frame of joint i *is* DH
frame i and the foot frame is E (the foot-sphere centre).
"""

from __future__ import annotations

import functools
import math
import os
import re
import tempfile
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from legbench import resources
from legbench.exceptions import ModelError, ScenarioError
from legbench.yamlfile import check_magnitude, one_line, other_file, read_bytes, read_yaml

#: The source checkout's root (only meaningful when running from one; data paths come from
#: :mod:`legbench.resources`).
ROOT = Path(__file__).resolve().parent.parent


if TYPE_CHECKING:  # resolved by __getattr__ below
    PARAMS_FILE: Path
    URDF_FILE: Path
    MODELS_DIR: Path


def __getattr__(name: str) -> Path:
    """``PARAMS_FILE`` (the active parameter file), ``URDF_FILE`` (where ``legbench model urdf`` writes its URDF:
    ``models/leg.urdf`` for the bundled model in a source checkout even when it is out of date,
    :func:`legbench.resources.urdf_destination`), ``MODELS_DIR`` (the bundled model directory), resolved when
    asked for: ``--model`` and ``LEGBENCH_MODEL`` can change them after import."""
    if name == "PARAMS_FILE":
        return resources.model_file()
    if name == "URDF_FILE":
        return resources.urdf_destination()
    if name == "MODELS_DIR":
        return resources.models_dir()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


JOINT_NAMES = ("q1_abad", "q2_hip", "q3_knee")
LINK_NAMES = ("link1", "link2", "link3")
BODY_NAMES = ("base", "link1", "link2", "link3", "foot")
FOOT_FRAME = "foot"


@dataclass(frozen=True)
class Geometry:
    """Lengths of docs/spec.md section 1 [m]."""

    H: float
    L_B0: float
    L_01: float
    L_12: float
    L_23: float
    L_3E: float
    R_foot: float


@dataclass(frozen=True)
class Joint:
    """One actuated joint with its joint-side limits."""

    name: str
    type: str  # "revolute" or "continuous"
    lower: float  # [rad], -inf for continuous
    upper: float  # [rad], +inf for continuous
    reduction: float
    effort: float  # torque limit [N m]
    velocity: float  # speed limit [rad/s]


@dataclass(frozen=True)
class Inertial:
    """Mass properties of one body in its link frame (URDF convention I_xy = -sum x y dm)."""

    mass: float  # [kg]
    com: tuple[float, ...]  # [m] in the link frame, (3,)
    inertia: tuple[tuple[float, ...], ...]  # 3x3 about the COM [kg m^2]

    @property
    def I(self) -> np.ndarray:  # noqa: E743 - spec name
        return np.array(self.inertia)


@dataclass(frozen=True)
class Contact:
    """Ground contact law parameters (docs/spec.md section 4)."""

    Kp: float  # [N/m]
    Kd: float  # [N s/m]
    mu_s: float
    mu_k: float
    v_th: float  # [m/s]
    restitution: float = 0.0
    torsional_friction: float = 0.0


@dataclass(frozen=True)
class LegParams:
    """Everything the parameter file holds, resolved to numbers."""

    geometry: Geometry
    joints: tuple[Joint, ...]
    inertials: dict[str, Inertial] = field(hash=False)
    collision: dict[str, dict[str, Any]] = field(hash=False)
    contact: Contact
    q_star: tuple[float, float, float]
    G_star: tuple[float, float, float]
    gravity: float
    scale: dict[str, float] = field(hash=False)
    #: The parameter file the numbers were read from (:func:`read_params`, :func:`load_params`); None for
    #: parameters built from a dict (:func:`params_from_raw`). With :attr:`digest`, what the header of the URDF
    #: generated from them names and is stamped with (:func:`urdf_text`). Not compared: equal numbers are equal.
    source: Path | None = field(default=None, compare=False)
    #: :func:`legbench.resources.param_digest` of :attr:`source`, taken before the file was parsed (so a file
    #: edited in between leaves a stamp that is not its numbers', which reads as out of date, never the reverse);
    #: None when not read from a file.
    digest: str | None = field(default=None, compare=False)

    @property
    def lower(self) -> np.ndarray:
        """Joint position lower limits [rad] (-inf for the continuous hip)."""
        return np.array([j.lower for j in self.joints])

    @property
    def upper(self) -> np.ndarray:
        """Joint position upper limits [rad] (+inf for the continuous hip)."""
        return np.array([j.upper for j in self.joints])

    @property
    def effort(self) -> np.ndarray:
        """Joint torque limits [N m]."""
        return np.array([j.effort for j in self.joints])

    @property
    def velocity(self) -> np.ndarray:
        """Joint speed limits [rad/s]."""
        return np.array([j.velocity for j in self.joints])

    @property
    def continuous(self) -> np.ndarray:
        """Mask of continuous joints."""
        return np.array([j.type == "continuous" for j in self.joints])

    def body_inertial(self, body: str) -> Inertial:
        """Composite mass properties of a moving body: link3 includes the foot."""
        if body != "link3":
            return self.inertials[body]
        L3E = self.geometry.L_3E
        foot = self.inertials["foot"]
        shifted = Inertial(foot.mass, (foot.com[0] + L3E, foot.com[1], foot.com[2]), foot.inertia)
        return combine([self.inertials["link3"], shifted])


# --------------------------------------------------------------------------- #
# Mass properties of primitives


def _axis_index(axis: str) -> int:
    return "xyz".index(axis)


def _cylinder_inertia(m: float, r_out: float, r_in: float, length: float, axis: str) -> np.ndarray:
    """Hollow cylinder about its centre [kg m^2]."""
    i_axial = 0.5 * m * (r_out**2 + r_in**2)
    i_trans = m * (3 * (r_out**2 + r_in**2) + length**2) / 12.0
    diag = [i_trans] * 3
    diag[_axis_index(axis)] = i_axial
    return np.diag(diag)


def _holed_sphere(rho: float, R: float, r: float, axis: str) -> tuple[float, np.ndarray]:
    """Mass and central inertia of a sphere of radius R with a coaxial hole of radius r.

    Slices at height z along the hole's axis are rings r <= s <= sqrt(R^2 - z^2), |z| <= h = sqrt(R^2 - r^2);
    the integrals over z are of polynomials, in closed form:
    m = rho pi int (h^2 - z^2) dz = rho pi 4 h^3 / 3 (the napkin ring);
    I_axis = int s^2 dm = rho pi / 2 int ((R^2 - z^2)^2 - r^4) dz = rho pi / 2 (2 h (R^4 - r^4) - 4 R^2 h^3 / 3
    + 2 h^5 / 5); int z^2 dm = rho pi int z^2 (h^2 - z^2) dz = rho pi 4 h^5 / 15.
    """
    h = math.sqrt(R * R - r * r)
    mass = rho * math.pi * 4.0 * h**3 / 3.0
    i_axis = rho * 0.5 * math.pi * (2.0 * h * (R**4 - r**4) - 4.0 * R * R * h**3 / 3.0 + 2.0 * h**5 / 5.0)
    z2 = rho * math.pi * 4.0 * h**5 / 15.0
    i_trans = 0.5 * i_axis + z2
    diag = [i_trans] * 3
    diag[_axis_index(axis)] = i_axis
    return mass, np.diag(diag)


def part_inertial(part: dict[str, Any], density: float, where: str = "part") -> Inertial:
    """Mass properties of one CAD primitive of the parameter file (``where``: how an error names it, the file and
    the key path; :func:`check_physical` has refused any other shape before)."""
    shape = part["shape"]
    if shape == "box":
        sx, sy, sz = part["size"]
        m = density * sx * sy * sz
        I = np.diag([m * (sy**2 + sz**2), m * (sx**2 + sz**2), m * (sx**2 + sy**2)]) / 12.0
    elif shape in ("tube", "cylinder"):
        r_out = part["r_out"] if shape == "tube" else part["r"]
        r_in = part["r_in"] if shape == "tube" else 0.0
        m = density * math.pi * (r_out**2 - r_in**2) * part["length"]
        I = _cylinder_inertia(m, r_out, r_in, part["length"], part["axis"])
    elif shape == "sphere":
        m, I = _holed_sphere(density, part["r"], part.get("hole_r", 0.0), part.get("axis", "z"))
    else:
        raise ModelError(one_line(f"{where}.shape: unknown shape {_value(shape)} (known: {_listing(_PART_KEYS)})"))
    pos = tuple(float(v) for v in part["pos"])
    return Inertial(m, pos, tuple(map(tuple, I)))  # type: ignore[arg-type]


def combine(parts: list[Inertial]) -> Inertial:
    """Composite of several bodies in one frame (parallel-axis theorem)."""
    m = sum(p.mass for p in parts)
    c = np.sum([p.mass * np.array(p.com) for p in parts], axis=0) / m
    I = np.zeros((3, 3))
    for p in parts:
        d = np.array(p.com) - c
        I += p.I + p.mass * (d @ d * np.eye(3) - np.outer(d, d))
    return Inertial(float(m), tuple(c.tolist()), tuple(map(tuple, I.tolist())))


def scaled(inertial: Inertial, k: float) -> Inertial:
    """Same COM, mass and inertia times k (uniform density change)."""
    return Inertial(inertial.mass * k, inertial.com, tuple(tuple(k * v for v in row) for row in inertial.inertia))


def cad_estimate(raw: dict[str, Any], path: Path | str = "leg parameters") -> dict[str, Inertial]:
    """Unscaled mass properties per URDF link from the CAD primitives (of a file :func:`check_physical` passed;
    ``path`` names it in an error)."""
    out = {}
    for link, spec in raw["links"].items():
        parts = [
            part_inertial(p, raw["materials"][p["material"]], f"{path}: links.{link}.parts[{i}]")
            for i, p in enumerate(spec["parts"])
        ]
        out[link] = combine(parts)
    return out


# --------------------------------------------------------------------------- #
# Loading


def load_raw(path: Path | str | None = None, check: bool = True) -> dict[str, Any]:
    """The parameter file (default: the active one, :func:`legbench.resources.model_file`) as a dict,
    read through the guarded YAML reader (size, nesting, duplicate keys) and checked by :func:`check_physical`
    (unless ``check`` is false), so an error names this file and the key.

    Raises:
        ModelError: the file is missing, not a regular file, or malformed (one line: the file, the key, why).
        ScenarioError: the YAML itself is malformed or beyond the reader's limits (one line, with the line).
    """
    path = Path(path) if path is not None else resources.model_file()
    if path.is_dir():
        raise ModelError(f"{path}: is a directory, not a parameter file")
    if not path.exists():
        raise ModelError(f"{path}: no such parameter file")
    raw, _ = read_yaml(path)
    if not isinstance(raw, dict):
        raise ModelError(f"{path}: expected a mapping at the top level")
    if check:
        check_physical(raw, path)
    return raw


def param_bytes(path: Path) -> bytes:
    """The content of the leg parameter file ``path`` [bytes], read as the YAML reader reads any file
    (:func:`legbench.yamlfile.read_bytes`: a regular file within ``limit("file_bytes")``), for the hash that names
    its URDF (:func:`legbench.resources.urdf_target`, which may import no reader but this module).

    Raises:
        FileNotFoundError: no such file (its URDF is then named ``-missing``; reading it as YAML says why).
        ModelError: anything else that cannot be read (a device, a FIFO, a directory, too large), in one line.
    """
    os.stat(path)  # FileNotFoundError as it is
    try:
        return read_bytes(path, "leg parameter file")
    except ScenarioError as exc:
        raise ModelError(str(exc)) from None


#: The sections of a leg parameter file, in the order they are checked.
SECTIONS = ("geometry", "joints", "materials", "links", "calibration", "collision", "contact")

#: The bodies with CAD parts (``links``) and collision primitives (``collision``): the moving links and the foot.
_BODIES = (*LINK_NAMES, "foot")

#: The roles of the joints, and their types, in the order of ``joints`` (and of :data:`JOINT_NAMES`): the URDF,
#: every backend and the Pinocchio configuration (the hip's (cos, sin), :func:`q_to_pin`) are built on these.
_JOINT_ROLES = ("ab/ad", "hip", "knee")
_JOINT_TYPES = ("revolute", "continuous", "revolute")

#: The CAD primitives of ``links.<body>.parts``: the keys each takes beside ``material``, ``shape``, ``pos``
#: (required) and ``name`` (optional), as (required, optional).
_PART_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "box": (("size",), ()),
    "tube": (("r_out", "r_in", "length", "axis"), ()),
    "cylinder": (("r", "length", "axis"), ()),
    "sphere": (("r",), ("hole_r", "axis")),
}

#: The collision primitives of ``collision.<body>`` (what the URDF's <geometry> takes): the keys each takes beside
#: ``shape`` (required) and ``pos`` (optional), as (required, optional). The foot's is a sphere.
_COLLISION_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "sphere": (("r",), ()),
    "cylinder": (("r", "length", "axis"), ()),
}

#: The least mass [kg] of a body of the URDF (link1, link2, link3 and the foot, each after its scale factor): MuJoCo
#: refuses a moving body lighter than its mjMINVAL (1e-15) and Pinocchio, which merges the fixed foot into link3,
#: divides the sum by max(m, 2.2e-16), so a lighter link3 gets a wrong COM (1e-21 m for 0.127 m).
MIN_MASS = 1e-15

#: The least principal moment of inertia [kg m^2] of a body of the URDF about its COM, each after its scale factor:
#: MuJoCo refuses an inertia tensor whose smallest eigenvalue is below its mjEPS (1e-14), "inertia must have
#: positive eigenvalues", for every URDF link (the foot too). The bundled leg's smallest is 2.6e-5 kg m^2 (the foot's).
MIN_INERTIA = 1e-14

#: Lengths and radii of CAD parts and collision primitives, which must be > 0 [m].
_POSITIVE_DIMS = ("r", "r_out", "length")

#: The axes a cylinder, a tube or a sphere's hole can lie along (of its link frame).
_AXES = ("x", "y", "z")

#: The geometry entries (docs/spec.md section 1) that are lengths, so > 0, with what each is. The others
#: (``L_B0``, ``L_01``) are positions of the base and the chain along a line they can move on without changing
#: the leg, and may be 0 or negative: ``L_B0`` is x_W of frame 0 (where the leg stands along the ground: the
#: ground is the whole plane z_W = 0), ``L_01`` the DH offset d1 = -L_01 of frame 1 along the ab/ad axis, the axis
#: q1 turns about (it shifts the chain along y_W only: G(q), M(q) and the workspace's shape are the same).
_GEOMETRY_LENGTHS = {
    "H": "the height of frame 0, the hip, above the ground z_W = 0",
    "L_12": "a length: the lever from the ab/ad axis to the hip",
    "L_23": "a length: the thigh",
    "L_3E": "a length: the shank",
    "R_foot": "a length: the foot sphere's radius",
}


def _value(v: Any) -> str:
    """A value as an error message quotes it: ``repr``, cut to 60 characters (a section given as a long list)."""
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _listing(names: Any) -> str:
    """Names as an error message lists them: ``a, b, c``; ``none`` for none (a file with no materials)."""
    return ", ".join(str(n) for n in names) or "none"


def _check_physical(raw: Any, path: Path | str) -> None:
    """:func:`check_physical`'s checks, in the order of the file's sections."""

    def fail(key: str, problem: str) -> ModelError:
        return ModelError(one_line(f"{path}: {key}: {problem}"))

    def bad(key: str, v: Any, why: str) -> ModelError:
        return fail(key, f"{_value(v)} {why}")

    def num(key: str, v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise bad(key, v, "is not a finite number")
        try:
            x = float(v)
        except OverflowError:  # an integer of hundreds of digits
            raise bad(key, v, "is not a finite number (too large for a float)") from None
        if not math.isfinite(x):
            raise bad(key, v, "is not a finite number")
        check_magnitude(x, lambda why: fail(key, why))
        return x

    def positive(key: str, v: Any, why: str = "must be > 0") -> float:
        x = num(key, v)
        if x <= 0:
            raise bad(key, v, why)
        return x

    def three(key: str, v: Any, what: str = "a position (a list of three numbers [m])") -> None:
        """Three finite numbers of any sign (a position [m], one value per joint)."""
        if not isinstance(v, list) or len(v) != 3:
            raise bad(key, v, f"is not {what}")
        for i, x in enumerate(v):
            num(f"{key}[{i}]", x)

    def mapping(key: str, v: Any, what: str) -> dict[Any, Any]:
        if not isinstance(v, dict):
            raise bad(key, v, f"is not {what}")
        return v

    def keys(key: str, d: dict[Any, Any], required: tuple[str, ...], optional: tuple[str, ...] = (), *,
             unknown: str = "", missing: str = "") -> None:  # fmt: skip
        """``d`` (at ``key``, "" for the top level) has every ``required`` key and no key but those and the
        ``optional`` ones; ``unknown`` and ``missing`` say what is wrong otherwise (default: the keys it takes)."""
        known = (*required, *optional)
        for k in d:
            if k not in known:
                raise fail(f"{key}.{k}" if key else str(k), unknown or f"unknown key (known: {_listing(known)})")
        for k in required:
            if k not in d:
                raise fail(f"{key}.{k}" if key else k, missing or f"missing (required: {_listing(required)})")

    def shape_of(key: str, d: dict[Any, Any], known: dict[str, Any]) -> str:
        """The ``shape`` of a part or collision primitive at ``key``: given, and one of ``known``."""
        if "shape" not in d:
            raise fail(f"{key}.shape", f"missing (one of {_listing(known)})")
        shape = d["shape"]
        if not isinstance(shape, str) or shape not in known:
            raise fail(f"{key}.shape", f"unknown shape {_value(shape)} (known: {_listing(known)})")
        return shape

    def axis(key: str, v: Any) -> None:
        if not isinstance(v, str) or v not in _AXES:
            raise fail(key, f"expected one of {_listing(_AXES)}, got {_value(v)}")

    def dims(key: str, d: dict[Any, Any]) -> None:
        """The lengths and radii of a part or collision primitive > 0, its axis one of x, y, z."""
        for k in _POSITIVE_DIMS:
            if k in d:
                positive(f"{key}.{k}", d[k])
        if "axis" in d:
            axis(f"{key}.axis", d["axis"])

    if not isinstance(raw, dict):
        raise ModelError(one_line(f"{path}: expected a mapping at the top level, got {_value(raw)}"))
    other = other_file(raw, "a leg parameter file")
    if other is not None and not set(map(str, raw)) & set(SECTIONS):  # a scenario given to --model
        raise ModelError(one_line(f"{path}: {other}"))
    sections = f"a leg parameter file has {_listing(SECTIONS)}"
    keys("", raw, SECTIONS, unknown=f"unknown section ({sections})", missing=f"missing ({sections})")

    # geometry: the lengths and offsets of docs/spec.md section 1
    lengths = [f.name for f in fields(Geometry)]
    geometry = raw["geometry"]
    if not isinstance(geometry, dict):
        raise bad("geometry", geometry, f"is not a mapping of the leg's lengths ({', '.join(lengths)})")
    for k in geometry:
        if k not in lengths:
            raise bad(f"geometry.{k}", geometry[k], f"is not a length of the leg ({', '.join(lengths)})")
    for k in lengths:  # every entry finite (NaN or inf made a URDF no parser reads), the lengths > 0
        if k not in geometry:
            raise fail(f"geometry.{k}", f"missing (the leg's geometry is {', '.join(lengths)})")
        if num(f"geometry.{k}", geometry[k]) <= 0 and k in _GEOMETRY_LENGTHS:
            raise bad(f"geometry.{k}", geometry[k], f"must be > 0 ({_GEOMETRY_LENGTHS[k]})")

    # joints: the three of the leg, by name and type in this order (the URDF and every backend are built on them)
    joints = raw["joints"]
    order = ", ".join(f"{n} ({t})" for n, t in zip(JOINT_NAMES, _JOINT_TYPES, strict=True))
    if not isinstance(joints, list):
        raise bad("joints", joints, f"is not a list of the leg's three joints: {order}")
    if len(joints) != 3:
        raise bad("joints", len(joints), "joints: the leg has three (ab/ad, hip, knee)")
    for i, j in enumerate(joints):
        key = f"joints[{i}]"
        mapping(key, j, "a joint (a mapping: name, type, reduction, effort, velocity, and lower, upper if revolute)")
        if "type" not in j:
            raise fail(f"{key}.type", f"missing (the {_JOINT_ROLES[i]} joint is {_JOINT_TYPES[i]})")
        if j["type"] not in ("revolute", "continuous"):
            raise bad(f"{key}.type", j["type"], "is not a rotary joint (revolute or continuous)")
        if j["type"] != _JOINT_TYPES[i]:
            raise bad(f"{key}.type", j["type"], f"is not the {_JOINT_ROLES[i]} joint's type: the joints are {order}")
        limits = ("lower", "upper") if j["type"] == "revolute" else ()
        for k in ("lower", "upper"):
            if k in j and not limits:
                raise fail(f"{key}.{k}", "a continuous joint has no position limits (lower, upper: revolute only)")
        keys(key, j, ("name", "type", *limits, "reduction", "effort", "velocity"))
        name = j["name"]
        earlier = [n for n in range(i) if joints[n]["name"] == name]
        if earlier:
            raise bad(f"{key}.name", name, f"is not unique (joints[{earlier[0]}].name too): the joints are {order}")
        if name != JOINT_NAMES[i]:
            raise bad(f"{key}.name", name, f"is not the {_JOINT_ROLES[i]} joint's name: the joints are {order}")
        for k in ("reduction", "effort", "velocity"):
            positive(f"{key}.{k}", j[k])
        if limits and num(f"{key}.lower", j["lower"]) >= num(f"{key}.upper", j["upper"]):
            raise bad(f"{key}.lower", j["lower"], f"must be below upper ({j['upper']!r})")

    # materials: densities by name
    materials = mapping("materials", raw["materials"], "a mapping of material names to densities [kg/m^3]")
    for name, rho in materials.items():
        positive(f"materials.{name}", rho, "must be > 0 (a density [kg/m^3])")

    # links: the CAD parts of each body
    links = mapping("links", raw["links"], f"a mapping of the leg's bodies ({_listing(_BODIES)}) to their parts")
    bodies = f"the leg's bodies {_listing(LINK_NAMES)} and foot each have their parts"
    keys("links", links, _BODIES, unknown=f"not a body of the leg ({bodies})", missing=f"missing ({bodies})")
    for link, spec in links.items():
        mapping(f"links.{link}", spec, "a body (a mapping with its list of parts)")
        keys(f"links.{link}", spec, ("parts",))
        parts = spec["parts"]
        if not isinstance(parts, list) or not parts:
            raise fail(f"links.{link}.parts", f"expected a non-empty list of parts, got {_value(parts)}")
        names: dict[str, int] = {}
        for i, part in enumerate(parts):
            key = f"links.{link}.parts[{i}]"
            mapping(key, part, "a part (a mapping: name, material, shape, pos and the shape's sizes)")
            shape = shape_of(key, part, _PART_KEYS)
            required, optional = _PART_KEYS[shape]
            known = _listing(("name", "material", "shape", "pos", *required, *optional))
            keys(key, part, ("material", "shape", "pos", *required), ("name", *optional),
                 unknown=f"unknown key of a {shape} (known: {known})")  # fmt: skip
            if "name" in part:
                name = part["name"]
                if not isinstance(name, str):
                    raise bad(f"{key}.name", name, "is not a name (a string)")
                if name in names:
                    raise bad(f"{key}.name", name, f"is not unique (links.{link}.parts[{names[name]}].name too)")
                names[name] = i
            material = part["material"]
            if not isinstance(material, str) or material not in materials:
                raise fail(f"{key}.material", f"unknown material {_value(material)} (known: {_listing(materials)})")
            dims(key, part)
            if "size" in part:
                if not isinstance(part["size"], list) or len(part["size"]) != 3:
                    raise bad(f"{key}.size", part["size"], "is not a size (a list of three lengths [m])")
                for n, v in enumerate(part["size"]):
                    positive(f"{key}.size[{n}]", v)
            if "r_in" in part and not 0 <= num(f"{key}.r_in", part["r_in"]) < part["r_out"]:
                raise bad(f"{key}.r_in", part["r_in"], "must be in [0, r_out)")
            if "hole_r" in part and not 0 <= num(f"{key}.hole_r", part["hole_r"]) < part["r"]:
                raise bad(f"{key}.hole_r", part["hole_r"], "must be in [0, r)")
            three(f"{key}.pos", part["pos"])  # the part's centre in its link frame

    # calibration: q*, G(q*), gravity and the mass scale factor of each link
    cal = mapping("calibration", raw["calibration"], "a mapping: q_star, G_star, gravity, scale")
    keys("calibration", cal, ("q_star", "G_star", "gravity", "scale"))
    for k in ("q_star", "G_star"):
        three(f"calibration.{k}", cal[k], "a list of three numbers (one per joint)")
    # calibrate's solve is singular at 0; metrics divide by it
    positive("calibration.gravity", cal["gravity"], "must be > 0 (the gravity G_star is for [m/s^2])")
    scale = mapping("calibration.scale", cal["scale"], f"a mapping of mass scale factors ({_listing(LINK_NAMES)})")
    links_known = f"known: {_listing(LINK_NAMES)}; the foot is scaled with link3"
    keys("calibration.scale", scale, LINK_NAMES, unknown=f"unknown key ({links_known})",
         missing=f"missing ({links_known})")  # fmt: skip
    for k, v in scale.items():
        positive(f"calibration.scale.{k}", v, "must be > 0 (a mass scale factor)")
    # each body of the URDF, as scaled, heavy enough for every engine to hold it (:data:`MIN_MASS`,
    # :data:`MIN_INERTIA`); the key named is the factor that scales it (the parts are checked above)
    for body, inr in cad_estimate(raw, path).items():
        factor = "link3" if body == "foot" else body
        k = scale[factor]
        mass, smallest = inr.mass * k, float(np.linalg.eigvalsh(inr.I).min()) * k
        which = f"the {body} (scaled with link3)" if body == "foot" else body
        if mass < MIN_MASS:
            why = "the least mass the engines hold (MuJoCo's mjMINVAL; Pinocchio divides by max(m, 2.2e-16))"
            raise bad(f"calibration.scale.{factor}", k, f"leaves {which} {mass:.3g} kg, below {MIN_MASS:g} kg, {why}")
        if smallest < MIN_INERTIA:
            why = "the least MuJoCo holds (its mjEPS: 'inertia must have positive eigenvalues')"
            raise bad(f"calibration.scale.{factor}", k, f"leaves {which} a principal moment of inertia of "
                      f"{smallest:.3g} kg m^2, below {MIN_INERTIA:g} kg m^2, {why}")  # fmt: skip

    # collision: primitives by body, the foot's sphere among them
    collision = mapping("collision", raw["collision"], "a mapping of collision primitives by body, with the foot's")
    keys("collision", collision, ("foot",), LINK_NAMES,
         unknown=f"not a body of the leg (known: {_listing(_BODIES)})",
         missing="missing (the foot's collision sphere, what touches the ground)")  # fmt: skip
    for link, prim in collision.items():
        key = f"collision.{link}"
        mapping(key, prim, "a collision primitive (a mapping: shape, r, ...)")
        shape = shape_of(key, prim, _COLLISION_KEYS)
        if link == "foot" and shape != "sphere":
            raise fail(f"{key}.shape", f"expected sphere (the foot touches the ground as a sphere), got {shape!r}")
        required, optional = _COLLISION_KEYS[shape]
        known = _listing(("shape", "pos", *required, *optional))
        keys(key, prim, ("shape", *required), ("pos", *optional), unknown=f"unknown key of a {shape} (known: {known})")
        dims(key, prim)
        if "pos" in prim:
            three(f"{key}.pos", prim["pos"])
    # the foot's sphere is the spec's foot (docs/spec.md section 1): radius R_foot, centred at E, the foot frame's
    # origin. The engines collide this sphere and the contact law (and every metric of the penetration) uses
    # geometry.R_foot about E: two feet made the backends simulate different legs, and no parity row sees it.
    foot, r_foot = collision["foot"], geometry["R_foot"]
    if foot["r"] != r_foot:
        raise bad("collision.foot.r", foot["r"], f"is not the foot's radius geometry.R_foot = {r_foot!r} "
                  "(the engines' contact sphere is the spec's foot: give both the same value)")  # fmt: skip
    if "pos" in foot and any(x != 0 for x in foot["pos"]):
        why = "the foot frame's origin, where the contact law puts it with geometry.L_3E"
        raise bad("collision.foot.pos", foot["pos"], f"is not E, the foot sphere's centre ({why}): leave pos out or "
                  "give [0, 0, 0]")  # fmt: skip

    # contact: the law's constants (docs/spec.md section 4)
    c = mapping("contact", raw["contact"], "a mapping of the contact law's constants")
    keys("contact", c, tuple(f.name for f in fields(Contact) if f.default is MISSING),
         tuple(f.name for f in fields(Contact) if f.default is not MISSING))  # fmt: skip
    for k in c:
        if num(f"contact.{k}", c[k]) < 0:
            what = {"Kp": "stiffness", "Kd": "damping", "v_th": "slip speed", "restitution": "restitution"}.get(
                k, "friction"
            )
            raise bad(f"contact.{k}", c[k], f"must be >= 0 (a negative {what})")
    for k in ("Kp", "v_th"):
        if c[k] <= 0:
            raise bad(f"contact.{k}", c[k], "must be > 0")
    if c["mu_k"] > c["mu_s"]:
        raise bad("contact.mu_k", c["mu_k"], f"above the static coefficient mu_s = {c['mu_s']!r}")


def check_physical(raw: dict[str, Any], path: Path | str = "leg parameters") -> None:
    """Refuse a malformed or physically meaningless parameter file, naming the file, the key path
    (``links.link2.parts[1].axis``) and the problem in one line, before anything is built from it.

    The shape of the file: the sections :data:`SECTIONS`, each with its keys and no others (the three joints
    by their names and types, :data:`JOINT_NAMES`; the bodies link1, link2, link3, foot in ``links``, each with
    a non-empty list of ``parts``, every part one of :data:`_PART_KEYS` of a known material; ``collision`` by
    body, the foot's a sphere; ``calibration``'s q*, G(q*), gravity and a scale factor per link;
    the contact law's constants). The physics: the geometry (every entry finite, the lengths and H > 0, the
    positions ``L_B0`` and ``L_01`` of any sign: :data:`_GEOMETRY_LENGTHS`), lengths, radii and positions of the
    CAD parts and collision primitives, densities, scale factors (each body of the URDF, scaled, at least
    :data:`MIN_MASS` and :data:`MIN_INERTIA`, what every engine holds), the foot's collision sphere (the spec's
    foot: radius ``geometry.R_foot``, centred at E), q*, G(q*), gravity, joint limits, the contact law's
    constants (Kp > 0, Kd >= 0, 0 <= mu_k <= mu_s, v_th > 0). Every number must be finite and
    within ``limit("float_abs")``: a NaN or inf reached the URDF, which no parser reads.

    Raises:
        ModelError: naming the file, the key and the problem.
    """
    try:
        _check_physical(raw, path)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError, OverflowError) as exc:  # a check missed
        raise ModelError(one_line(f"{path}: missing or malformed entry: {exc!r}")) from exc


def params_from_raw(raw: dict[str, Any], path: Path | str = "leg parameters", check: bool = True) -> LegParams:
    """Resolve a raw parameter dict to :class:`LegParams` (checked by :func:`check_physical` first unless
    ``check`` is false: :func:`calibrate`'s basis solves set scale factors to 0 on purpose)."""
    if check:
        check_physical(raw, path)
    try:
        geom = Geometry(**{k: float(v) for k, v in raw["geometry"].items()})
        joints = []
        for j in raw["joints"]:
            cont = j["type"] == "continuous"
            joints.append(
                Joint(
                    name=j["name"],
                    type=j["type"],
                    lower=-math.inf if cont else float(j["lower"]),
                    upper=math.inf if cont else float(j["upper"]),
                    reduction=float(j["reduction"]),
                    effort=float(j["effort"]),
                    velocity=float(j["velocity"]),
                )
            )
        cal = raw["calibration"]
        scale = {k: float(v) for k, v in cal["scale"].items()}
        est = cad_estimate(raw, path)
        inertials = {name: scaled(inr, scale["link3" if name == "foot" else name]) for name, inr in est.items()}
        contact = Contact(**{k: float(v) for k, v in raw["contact"].items()})
        return LegParams(
            geometry=geom,
            joints=tuple(joints),
            inertials=inertials,
            collision=raw["collision"],
            contact=contact,
            q_star=tuple(cal["q_star"]),  # type: ignore[arg-type]
            G_star=tuple(cal["G_star"]),  # type: ignore[arg-type]
            gravity=float(cal["gravity"]),
            scale=scale,
        )
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:  # unchecked (check=False) only
        raise ModelError(one_line(f"{path}: missing or malformed entry: {exc}")) from exc


def load_params(path: Path | str | None = None) -> LegParams:
    """The leg's parameters from ``path`` (default: the active parameter file) [cached per file and its
    modification time, size and inode: read again, as :func:`read_params` reads it, once the file changes, so
    a process (a notebook, a script) that outlives an edit of the file uses the edited leg, as the URDF does]."""
    resolved = _resolved(Path(path) if path is not None else resources.model_file())
    return _load_params(resolved, _file_stamp(resolved))  # None if missing: read_params says why, in its words


def _file_stamp(path: str | Path) -> tuple[int, int, int] | None:
    """A file's identity for the caches keyed on it: (modification time [ns], size [bytes], inode); None where it
    cannot be read (a file rewritten, or replaced atomically, is another key)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_mtime_ns, st.st_size, st.st_ino)


def read_params(path: Path | str) -> LegParams:
    """The leg's parameters read from the file ``path`` now (not cached), with the file and its digest
    (:attr:`LegParams.source`, :attr:`LegParams.digest`) for the stamp of the URDF generated from them.

    The file is hashed first and parsed after, so an edit in between gives a stamp that is not the numbers'
    (read as out of date, never as current). Errors are :func:`load_raw`'s and :func:`params_from_raw`'s.

    Raises:
        ModelError: the file is missing, not a regular file, too large or malformed.
    """
    path = Path(path)
    try:
        digest: str | None = resources.param_digest(path)
    except (OSError, ModelError):  # load_raw says why, in its words
        digest = None
    return replace(params_from_raw(load_raw(path), path, check=False), source=path, digest=digest)  # load_raw checks


@functools.cache
def _resolved(path: Path) -> Path:
    # resolving walks the symlinks of the package data on every call otherwise (0.4 ms, thousands of calls
    # in a sweep); a path's target does not change under a running process
    return path.resolve()


@functools.lru_cache(maxsize=32)
def _load_params(path: Path, stamp: tuple[int, int, int] | None) -> LegParams:
    return read_params(path)


# --------------------------------------------------------------------------- #
# URDF


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def W_T_0(geom: Geometry) -> np.ndarray:
    """Pose of the fixed base frame 0 in W (docs/spec.md section 1)."""
    return np.array([[0, -1, 0, geom.L_B0], [0, 0, -1, 0], [1, 0, 0, geom.H], [0, 0, 0, 1]], dtype=float)


def _rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw with R = Rz(y) Ry(p) Rx(r)."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if abs(math.cos(pitch)) < 1e-12:
        return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def joint_origins(geom: Geometry) -> dict[str, np.ndarray]:
    """Fixed part of each URDF joint (parent frame -> child DH frame at q = 0)."""

    def T(R: np.ndarray, p: list[float] | np.ndarray) -> np.ndarray:
        out = np.eye(4)
        out[:3, :3] = R
        out[:3, 3] = p
        return out

    base = W_T_0(geom) @ T(np.eye(3), [0, 0, -geom.L_01])  # alpha0 = 0, a0 = 0, d1 = -L01
    hip = T(_rx(math.pi / 2) @ _rz(-math.pi / 2), _rx(math.pi / 2) @ np.array([0, 0, geom.L_12]))
    knee = T(np.eye(3), [geom.L_23, 0, 0])
    foot = T(np.eye(3), [geom.L_3E, 0, 0])
    return {"q1_abad": base, "q2_hip": hip, "q3_knee": knee, "foot_joint": foot}


def _fmt(v: float) -> str:
    """A number for the URDF: the shortest text that reads back as the same double (``repr``), so the URDF
    carries the parameter file's numbers exactly (12 significant digits put 5e-12 into the rotation of
    every rpy of pi/2 and the products of inertia)."""
    return repr(float(v))


def _vec(v: Any) -> str:
    return " ".join(_fmt(float(x)) for x in v)


def _origin(T: np.ndarray) -> str:
    return f'<origin xyz="{_vec(T[:3, 3])}" rpy="{_vec(_rpy(T[:3, :3]))}"/>'


def _geometry_xml(shape: dict[str, Any], where: str = "collision") -> tuple[str, np.ndarray]:
    """URDF <geometry> of a collision primitive and its pose in the link frame (``where``: how an error names it,
    the file and the key path; :func:`check_physical` has refused any other shape before)."""
    T = np.eye(4)
    T[:3, 3] = shape.get("pos", [0.0, 0.0, 0.0])
    if shape["shape"] == "sphere":
        return f'<sphere radius="{_fmt(shape["r"])}"/>', T
    if shape["shape"] == "cylinder":  # URDF cylinders lie along z
        axis = shape["axis"]
        if axis == "x":
            T[:3, :3] = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]])
        elif axis == "y":
            T[:3, :3] = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]])
        return f'<cylinder radius="{_fmt(shape["r"])}" length="{_fmt(shape["length"])}"/>', T
    known = _listing(_COLLISION_KEYS)
    raise ModelError(one_line(f"{where}.shape: unknown shape {_value(shape['shape'])} (known: {known})"))


def _inertial_xml(inr: Inertial) -> str:
    I = inr.I
    return (
        f'    <inertial>\n      <origin xyz="{_vec(inr.com)}" rpy="0 0 0"/>\n'
        f'      <mass value="{_fmt(inr.mass)}"/>\n'
        f'      <inertia ixx="{_fmt(I[0, 0])}" ixy="{_fmt(I[0, 1])}" ixz="{_fmt(I[0, 2])}" '
        f'iyy="{_fmt(I[1, 1])}" iyz="{_fmt(I[1, 2])}" izz="{_fmt(I[2, 2])}"/>\n    </inertial>\n'
    )


def urdf_header(params: LegParams) -> str:
    """The URDF's header comment: the stamp (:attr:`LegParams.digest`, which
    :func:`legbench.resources.urdf_stamp` reads back) and the parameter file by the name outputs give it.

    The bundled file is ``models/leg.yaml`` from any working directory (the committed ``models/leg.urdf`` does
    not depend on where it was generated); another file as :func:`legbench.resources.shown` names it when that
    is relative, else by its file name alone (no machine path). Control characters are escaped and ``--``
    (which may not stand in an XML comment) is split. Parameters not read from a file get no stamp.
    """
    if params.source is None or params.digest is None:
        return "<!-- Generated by legbench from leg parameters not read from a file (no stamp). Do not edit. -->"
    if resources.is_bundled(params.source):
        name = "models/leg.yaml"
    else:
        name = resources.shown(params.source)
        name = params.source.name if Path(name).is_absolute() else name
    name = re.sub(r"-(?=-)", "- ", one_line(name.encode("utf-8", "backslashreplace").decode("utf-8")))
    fmt = resources.URDF_FORMAT.decode("ascii").strip()
    return f"{resources.STAMP_PREFIX}{params.digest}, of {fmt} and the file's bytes) from {name}. Do not edit. -->"


def urdf_text(params: LegParams) -> str:
    """The URDF of the leg, generated from the parameters, headed by :func:`urdf_header` (its stamp).

    Inertia products follow the URDF convention (ixy = -integral(x y dm), the
    entry of the inertia tensor); CAD printouts use the opposite sign.
    """
    geom = params.geometry
    origins = joint_origins(geom)
    source = params.source if params.source is not None else "leg parameters"
    lines = [
        '<?xml version="1.0"?>',
        urdf_header(params),
        '<robot name="legbench_leg">',
        '  <link name="base">',
        _inertial_xml(Inertial(1.0, (0.0, 0.0, geom.H), ((1e-3, 0, 0), (0, 1e-3, 0), (0, 0, 1e-3)))).rstrip(),
        "  </link>",
    ]
    parents = ["base", "link1", "link2"]
    for joint, parent, child in zip(params.joints, parents, LINK_NAMES, strict=True):
        lim = ""
        if joint.type == "continuous":
            lim = f'<limit effort="{_fmt(joint.effort)}" velocity="{_fmt(joint.velocity)}"/>'
        else:
            lim = (
                f'<limit lower="{_fmt(joint.lower)}" upper="{_fmt(joint.upper)}" '
                f'effort="{_fmt(joint.effort)}" velocity="{_fmt(joint.velocity)}"/>'
            )
        lines += [
            f'  <joint name="{joint.name}" type="{joint.type}">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{child}"/>',
            f"    {_origin(origins[joint.name])}",
            '    <axis xyz="0 0 1"/>',
            f"    {lim}",
            '    <dynamics damping="0" friction="0"/>',
            "  </joint>",
        ]
        lines.append(f'  <link name="{child}">')
        lines.append(_inertial_xml(params.inertials[child]).rstrip())
        if child in params.collision:
            geo, T = _geometry_xml(params.collision[child], f"{source}: collision.{child}")
            lines.append(f"    <collision>\n      {_origin(T)}\n      <geometry>{geo}</geometry>\n    </collision>")
        lines.append("  </link>")
    geo, T = _geometry_xml(params.collision["foot"], f"{source}: collision.foot")
    lines += [
        '  <joint name="foot_joint" type="fixed">',
        '    <parent link="link3"/>',
        '    <child link="foot"/>',
        f"    {_origin(origins['foot_joint'])}",
        "  </joint>",
        '  <link name="foot">',
        _inertial_xml(params.inertials["foot"]).rstrip(),
        f"    <collision>\n      {_origin(T)}\n      <geometry>{geo}</geometry>\n    </collision>",
        "  </link>",
        "</robot>",
        "",
    ]
    return "\n".join(lines)


def write_urdf(params: LegParams | None = None, path: Path | str | None = None) -> Path:
    """Write the generated URDF (atomically) to ``path`` (default: the active model's, where ``legbench model
    urdf`` writes it, see :func:`legbench.resources.urdf_destination`) and return its path."""
    params = params or load_params()
    path = Path(path) if path is not None else resources.urdf_destination()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")  # the name results.clean_stale knows
    try:
        tmp.write_text(urdf_text(params))
        tmp.replace(path)
    except BaseException:  # full disk, read-only, a kill: the previous file stays, no temporary is left
        tmp.unlink(missing_ok=True)
        raise
    return path


# --------------------------------------------------------------------------- #
# Pinocchio


def pinocchio_model(urdf: str | Path | None = None, gravity: float | None = None) -> Any:
    """Pinocchio model of the URDF (default: the active model's; fixed base; gravity -g z_W) [cached per file,
    its modification time, size and inode]."""
    path = str(urdf) if urdf is not None else str(resources.urdf_file())
    g = load_params().gravity if gravity is None else gravity
    return _pinocchio_model(path, g, _file_stamp(path))  # a URDF regenerated in place is a new model


@functools.lru_cache(maxsize=32)
def _pinocchio_model(path: str, g: float, stamp: tuple[int, int, int] | None) -> Any:
    if not Path(path).exists():
        raise ModelError(f"{path}: URDF not found; run `legbench model urdf`")
    model = pin.buildModelFromUrdf(path)
    model.gravity.linear = np.array([0.0, 0.0, -g])
    return model


class Dynamics:
    """Rigid-body dynamics of the leg on the reference model (generated URDF), one model and data bound once.

    The closed-form answers of the verification cases are computed with it.
    """

    def __init__(self, gravity: float | None = None, urdf: str | None = None) -> None:
        """Args:
        gravity: magnitude along -z_W [m/s^2] (default: the parameter file's).
        urdf: the URDF (default ``models/leg.urdf``).
        """
        self.model = pinocchio_model(urdf, gravity)
        self.data = self.model.createData()

    def energy(self, q: np.ndarray, qd: np.ndarray) -> tuple[float, float]:
        """Kinetic and potential energy (T [J], V [J]) at joint angles q [rad] and velocities qd [rad/s]."""
        qp = q_to_pin(q)
        T = pin.computeKineticEnergy(self.model, self.data, qp, np.asarray(qd, float))
        V = pin.computePotentialEnergy(self.model, self.data, qp)
        return float(T), float(V)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q) [kg m^2], symmetric."""
        M = pin.crba(self.model, self.data, q_to_pin(q))
        return np.triu(M) + np.triu(M, 1).T  # type: ignore[no-any-return]

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """G(q) [N m] at this model's gravity (``gravity_torque`` and ``kinematics.gravity`` take the parameter
        file's): the joint torques that hold the leg still."""
        return np.array(pin.computeGeneralizedGravity(self.model, self.data, q_to_pin(np.asarray(q, float))))

    def inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """tau = M(q) qdd + C(q, qd) qd + G(q) [N m]; with qdd = 0 the bias b(q, qd)."""
        return np.array(pin.rnea(self.model, self.data, q_to_pin(q), np.asarray(qd, float), np.asarray(qdd, float)))

    def bias_velocity_derivative(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """D = d b / d qd at (q, qd) [N m s/rad], b = C(q, qd) qd + G(q)."""
        pin.computeRNEADerivatives(self.model, self.data, q_to_pin(q), np.asarray(qd, float), np.zeros(3))
        return np.array(self.data.dtau_dv)


def q_to_pin(q: np.ndarray) -> np.ndarray:
    """Joint angles [rad] (3,) -> Pinocchio configuration (nq = 4: the hip is (cos, sin))."""
    return np.array([q[0], math.cos(q[1]), math.sin(q[1]), q[2]])


def q_from_pin(qp: np.ndarray) -> np.ndarray:
    """Pinocchio configuration -> joint angles [rad] (3,)."""
    return np.array([qp[0], math.atan2(qp[2], qp[1]), qp[3]])


def calibrate(raw: dict[str, Any] | None = None) -> dict[str, float]:
    """Scale factors per link that make G(q*) match the report's figure.

    G is linear in the link masses when each link's COM is held, and the chain
    makes the 3x3 system triangular (link 1 moves only G1, link 2 G1 and G2),
    so one solve gives the factors exactly.
    """
    raw = raw or load_raw()
    check_physical(raw)
    base = dict(raw)
    A = np.zeros((3, 3))
    with tempfile.TemporaryDirectory() as tmp:
        for col, link in enumerate(LINK_NAMES):
            cal = dict(raw["calibration"])
            cal["scale"] = {n: (1.0 if n == link else 0.0) for n in LINK_NAMES}
            base["calibration"] = cal
            p = params_from_raw(base, check=False)  # one link at scale 1, the others at 0
            # zero-mass links are replaced by a negligible mass so the URDF stays loadable
            inertials = {
                k: (v if v.mass > 0 else Inertial(1e-12, v.com, ((1e-15, 0, 0), (0, 1e-15, 0), (0, 0, 1e-15))))
                for k, v in p.inertials.items()
            }
            p = replace(p, inertials=inertials)
            path = Path(tmp) / f"{link}.urdf"
            write_urdf(p, path)
            A[:, col] = gravity_torque(np.array(p.q_star), urdf=str(path))
    k = np.linalg.solve(A, np.array(raw["calibration"]["G_star"]))
    return dict(zip(LINK_NAMES, k.tolist(), strict=True))


def gravity_torque(q: np.ndarray, urdf: str | None = None) -> np.ndarray:
    """G(q) [N m]: joint torques that hold the leg still against gravity."""
    model = pinocchio_model(urdf)
    data = model.createData()
    return np.array(pin.computeGeneralizedGravity(model, data, q_to_pin(np.asarray(q, float))))
