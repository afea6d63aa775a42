"""External logs (hardware, another simulator such as Gazebo) read as one more backend.

Two kinds, told apart by the path:

- a CSV file, matched to legbench's columns by header name;
- a ROS bag, read with the ``rosbags`` library (pure Python, no ROS install; ``pip install
  'legbench[ros]'``): a ROS 1 ``.bag`` file, or a ROS 2 bag directory (sqlite3 or MCAP storage; its
  ``.db3`` / ``.mcap`` file may be named instead). ``sensor_msgs/JointState`` gives q, qd and tau per
  joint (position [rad], velocity [rad/s], effort [N m]), a ``geometry_msgs/WrenchStamped`` topic the
  ground force on the foot in W [N], resampled linearly onto the joint-state times.

Either becomes a DataFrame of :data:`~legbench.signals.RUN_COLUMNS` (then a
:class:`~legbench.results.RunResult` in :func:`legbench.compare.compare`).
"""

from __future__ import annotations

import hashlib
import logging
import math
import re
import stat
import warnings
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from legbench import kinematics
from legbench.exceptions import LegbenchError, ResultsError
from legbench.results import result_from_frame
from legbench.signals import EE_COLUMNS, LABELS, RUN_COLUMNS, SIGNAL_OF, UNITS
from legbench.yamlfile import file_kind

__all__ = ["API_WORDS", "CLI_WORDS", "JOINT_STATE", "WRENCH", "LogWords", "RosOptions", "digest", "is_ros_bag",
           "load_log", "load_ros_bag", "worded"]  # fmt: skip

#: The message types read from a bag (rosbags' names, the same for ROS 1 and ROS 2).
JOINT_STATE = "sensor_msgs/msg/JointState"
WRENCH = "geometry_msgs/msg/WrenchStamped"
#: legbench's joint names (the generated URDF's), the default joint mapping of a bag.
DEFAULT_JOINTS = ("q1_abad", "q2_hip", "q3_knee")

logger = logging.getLogger("legbench.logs")


@dataclass(frozen=True)
class LogWords:
    """How this module's messages name the settings of a log, in the caller's words: by default
    (:data:`CLI_WORDS`) the options of ``legbench compare``; :data:`API_WORDS` the arguments of
    :func:`legbench.compare.compare` (``Result.compare`` of the Python API). Chosen with :func:`worded`.

    Attributes:
        time_scale: the time scale factor, before its value (``--log-time-scale 0.0: ...``).
        time_scale_ms: the time scale for a log in ms.
        pick_column: what chooses one of several header columns matching one legbench column.
        map_columns: a mapping of header names to legbench columns, by example.
        map_joints: a mapping of a bag's joint names to q1, q2, q3.
        joints: a bag's joint mapping alone, by example.
        joint_topic: what names the JointState topic of a bag.
        wrench_topic: what names the WrenchStamped topic of a bag.
    """

    time_scale: str = "--log-time-scale"
    t0: str = "--log-t0"
    time_scale_ms: str = "--log-time-scale 1e-3"
    pick_column: str = "--log-columns (column_map in the Python API)"
    map_columns: str = "--log-columns 'theirs=t, ...' (column_map in the Python API)"
    map_joints: str = "--log-columns NAME=q1,NAME=q2,NAME=q3"
    joints: str = "NAME=q1,NAME=q2,NAME=q3"
    joint_topic: str = "--ros-joint-topic"
    wrench_topic: str = "--ros-wrench-topic"


#: The command line's words (``legbench compare``): the default.
CLI_WORDS = LogWords()
#: The Python API's words: the arguments of :func:`legbench.compare.compare`.
API_WORDS = LogWords(
    time_scale="log_time_scale",
    t0="log_t0",
    time_scale_ms="log_time_scale=1e-3",
    pick_column="column_map",
    map_columns="column_map={'theirs': 't', ...}",
    map_joints="column_map={NAME: 'q1', NAME: 'q2', NAME: 'q3'}",
    joints="{NAME: 'q1', NAME: 'q2', NAME: 'q3'}",
    joint_topic="ros=RosOptions(joint_topic=...)",
    wrench_topic="ros=RosOptions(wrench_topic=...)",
)
_WORDS: ContextVar[LogWords] = ContextVar("legbench_log_words", default=CLI_WORDS)


@contextmanager
def worded(words: LogWords) -> Iterator[None]:
    """Within the block (this thread or task), the messages of this module, raised and logged, name the log's
    settings in ``words``: :mod:`legbench.api` calls :func:`legbench.compare.compare` (which reads the log) in
    ``worded(API_WORDS)``, so a Python caller is told of ``log_time_scale``, not ``--log-time-scale``."""
    token = _WORDS.set(words)
    try:
        yield
    finally:
        _WORDS.reset(token)


#: Header names (after unit stripping, lower case) taken for legbench columns.
ALIASES = {"time": "t", "fn": "fz", "f_x": "fx", "f_y": "fy", "f_z": "fz"}


def _normalise_header(col: str) -> str:
    """``"q1 [rad]"`` -> ``"q1"``; ``" Fz (N)"`` -> ``"fz"``; ``"time"`` -> ``"t"``."""
    base = re.sub(r"\s*[\[(].*?[\])]\s*$", "", str(col)).strip().lower()
    return ALIASES.get(base, base)


#: The units a header may give each signal's columns in, each with its factor to legbench's unit
#: (:data:`~legbench.signals.UNITS`); written lower case, spaces as one.
HEADER_UNITS: dict[str, dict[str, float]] = {
    "t": {"s": 1.0, "sec": 1.0, "seconds": 1.0, "ms": 1e-3, "us": 1e-6},
    "q": {"rad": 1.0, "radians": 1.0, "deg": math.pi / 180.0, "degrees": math.pi / 180.0},
    "qd": {"rad/s": 1.0, "rad/sec": 1.0, "radians/s": 1.0, "deg/s": math.pi / 180.0, "deg/sec": math.pi / 180.0},
    "tau": {"n m": 1.0, "nm": 1.0, "n*m": 1.0, "n.m": 1.0, "n-m": 1.0, "n·m": 1.0},
    "force": {"n": 1.0},
    "ee": {"m": 1.0, "mm": 1e-3},
}
#: Units legbench does not convert, refused where a header gives one (read as legbench's own they would be off by
#: their factor); an index in square brackets (``pos[0]``) is part of the name, and other text in parentheses
#: (``q1 (measured)``) is read as a note (:func:`_unit_factor`).
OTHER_UNITS = frozenset({"rpm", "rev", "rev/s", "grad", "mrad", "cm", "km", "ns", "min", "h", "kn", "mn", "lbf", "ft",
                         "in", "kgf", "n mm", "nmm", "mm/s", "m/s", "m/s^2", "rad/s^2", "deg/s^2", "%"})  # fmt: skip


def _unit_factor(path: Path, col: str, target: str) -> float | None:
    """The factor taking header column ``col`` (legbench's column ``target``) to legbench's unit, from the unit it
    writes after its name (``"q1 [deg]"``: pi/180), or None where it writes none. A unit legbench does not read for
    that signal is refused: read as its own unit it would be compared silently off by the unit's factor. Text in
    square brackets is a unit (``q1 [arcmin]`` refused), unless it is an integer index (``pos[0]``, ``pos[-1]``);
    text in parentheses is a unit where it is one of :data:`HEADER_UNITS` or :data:`OTHER_UNITS`, else a note the
    column is read without (``q1 (measured)``, in legbench's unit: a warning says so); brackets that do not pair,
    ``q1 [deg)``, are refused."""
    m = re.search(r"([\[(])\s*([^\[\]()]*?)\s*([\])])\s*$", str(col))
    if m is None or target == "controller":
        return None
    signal = "t" if target == "t" else "ee" if target in EE_COLUMNS else SIGNAL_OF[LABELS.index(target)]
    unit = " ".join(m.group(2).lower().split())
    known = HEADER_UNITS[signal]
    if (m.group(1), m.group(3)) not in (("[", "]"), ("(", ")")):
        raise ResultsError(str(path), f"column {col!r}: its brackets do not pair ({m.group(1)} ... {m.group(3)}); "
                                      "write the unit as [unit] or (unit)")  # fmt: skip
    if unit in known:
        return known[unit]
    if unit == "" or re.fullmatch(r"-?[0-9]+", unit):  # an index, or nothing: part of the name
        return None
    if m.group(1) == "[" or unit in OTHER_UNITS or any(unit in units for units in HEADER_UNITS.values()):
        raise ResultsError(str(path), f"column {col!r}: unit [{m.group(2)}] is not one legbench reads for "
                                      f"{target} ({', '.join(known)}); convert the column, or write its unit as "
                                      "one of these")  # fmt: skip
    logger.warning("legbench: warning: %s: column %r: (%s) is not a unit legbench reads; the column is read in %s",
                   path, col, m.group(2), UNITS[signal])  # fmt: skip
    return None


#: Largest magnitude a logged value may have [SI units]: beyond it the column is not a physical signal.
PLAUSIBLE_MAX = 1e9


def _check_plausible(t: np.ndarray, data: np.ndarray, source: str, foot: np.ndarray | None = None) -> None:
    """Refuse a log with no finite joint angle or with values no leg produces (in the signals and in the foot
    centre ``foot`` as logged, (n, 3), if given); warn, with the evidence, on units that look wrong (time in ms,
    angles in degrees)."""
    q = data[:, 0:3]
    if not np.isfinite(q).any():
        raise ResultsError(source, "q1..q3 hold no finite value (NaN only): nothing to compare")
    values, names = (data, LABELS) if foot is None else (np.hstack([data, foot]), (*LABELS, *EE_COLUMNS))
    finite = np.abs(np.where(np.isfinite(values), values, 0.0))
    if finite.max(initial=0.0) > PLAUSIBLE_MAX:
        i, j = np.unravel_index(int(np.argmax(finite)), finite.shape)
        raise ResultsError(source, f"column '{names[j]}' reaches {values[i, j]:.3g} at data row {i + 1} (t = "
                                   f"{t[i]:g} s): not a physical value (limit {PLAUSIBLE_MAX:g})")  # fmt: skip
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    if step > 0.1:
        logger.warning("legbench: warning: %s: median time step %.4g s: is the time in ms? (%s)", source, step,
                       _WORDS.get().time_scale_ms)  # fmt: skip
    qmax = float(np.nanmax(np.abs(q)))
    if qmax > 2 * np.pi + 0.1:
        logger.warning("legbench: warning: %s: joint angles reach %.4g: above 2 pi rad, are they in degrees? "
                       "legbench logs radians", source, qmax)  # fmt: skip


def _foot(foot: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Foot centre in W [m], shape (n, 3): each column of ``foot`` as logged, or from ``q`` [rad]
    (:func:`legbench.kinematics.fk`, as for a run) where the log holds no value of it (NaN throughout)."""
    logged = ~np.isnan(foot).all(axis=0)
    if logged.all():
        return foot
    return np.where(logged, foot, kinematics.fk(q))


def _check_regular(path: Path) -> None:
    """Refuse a CSV log path that is not a regular file, saying what it is, without opening it (a FIFO would block
    until a writer comes, a device such as ``/dev/zero`` has no end)."""
    try:
        mode = path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):
        raise ResultsError(str(path), "no such log file") from None
    except OSError as exc:  # a name too long, a loop of links, a directory on the way not searchable
        raise ResultsError(str(path), f"cannot be read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):  # not a ROS 2 bag either (is_ros_bag): no metadata.yaml
        raise ResultsError(str(path), "is a directory, not a log file (a ROS 2 bag directory holds metadata.yaml; "
                                      "this one has none)")  # fmt: skip
    if not stat.S_ISREG(mode):
        raise ResultsError(str(path), f"is {file_kind(mode)}, not a regular file (a CSV log is read only from one)")


def _written_header(path: Path) -> list[str]:
    """The CSV's header row as written, read by the same parser as the data (quotes, a BOM, blank lines before
    it): ``pd.read_csv`` renames a repeated name (``q2``, ``q2.1``) and an empty one (``Unnamed: 4``)."""
    row = pd.read_csv(path, header=None, nrows=1, dtype=str, keep_default_na=False, na_filter=False)
    return [str(v) for v in row.iloc[0]] if len(row) else []


def _check_unique_header(path: Path, header: list[str]) -> None:
    """Refuse a header that names two columns alike (as written; empty names, unnamed columns, aside): pandas
    would keep the first under that name and call the other ``q2.1``, a name that is not in the file."""
    where: dict[str, list[int]] = {}
    for i, name in enumerate(header, start=1):
        if name.strip():
            where.setdefault(name, []).append(i)
    repeated = [(name, cols) for name, cols in where.items() if len(cols) > 1]
    if repeated:
        said = ", ".join(f"{name!r} names columns {', '.join(map(str, cols[:-1]))} and {cols[-1]}"
                         for name, cols in repeated)  # fmt: skip
        raise ResultsError(str(path), f"header {said}: each column needs a name of its own")


def load_log(
    path: str | Path,
    column_map: Mapping[str, str] | None = None,
    time_scale: float = 1.0,
    ros: RosOptions | None = None,
    t0: float | None = None,
) -> pd.DataFrame:
    """Read an external log, a CSV file or a ROS bag (:func:`is_ros_bag`), into the run columns, as one more "backend".

    A bag is read by :func:`load_ros_bag` with ``ros`` (default :class:`RosOptions`); there
    ``column_map`` maps joint names of the JointState messages to ``q1``, ``q2``, ``q3`` (the joint's
    position, velocity and effort all go to that joint) and ``time_scale`` is not used (bag time is
    in ns). What follows is the CSV case.

    Header names are matched to :data:`RUN_COLUMNS` case-insensitively, a
    trailing unit in brackets or parentheses read (``"q1 [rad]"`` is ``q1``; ``"q1 [deg]"`` is ``q1``
    converted to rad, :data:`HEADER_UNITS`; another unit is refused; ``time`` is ``t``).
    ``column_map`` maps other names, ``{"their name": "q1"}``,
    and wins over the automatic match: a header column whose automatic match is a column the map
    already targets is ignored. Only ``t`` and ``q1..q3`` are required;
    other missing signals become NaN and are left out of the metrics. A missing value in some rows
    (an empty cell, ``NaN``, ``n/a``: what ``pd.read_csv`` reads as NaN) is a missing sample, left out
    of the metrics that need it (docs/metrics.md), as a ROS bag's force outside the wrench's span is;
    ``inf`` is refused. The foot centre
    (``ee_x..ee_z`` [m]) is taken as logged, or computed from q (:func:`legbench.kinematics.fk`)
    where the log has none.

    Args:
        path: the CSV file.
        column_map: header name in the file -> legbench column name.
        time_scale: factor taking the file's time unit to seconds (1e-3 for ms).
        t0: the log's time [s, after the scale] that is the run's t = 0 (a log stamped in epoch seconds, or
            started before the run); None: 0. For a bag, :attr:`RosOptions.t0` (None: its first sample).

    Returns:
        DataFrame with the columns of :data:`RUN_COLUMNS` (controller "" if absent).

    Raises:
        ResultsError: the file is missing, not a regular file or unreadable, a header name
            names two columns, a header unit is not one legbench reads for its column, a mapped
            column is absent, two columns map to one name, a
            required column is missing, a value is not numeric or infinite, or time is not
            strictly increasing.
    """
    path = Path(path)
    words = _WORDS.get()
    if is_ros_bag(path):
        opts = ros or RosOptions()
        if t0 is not None:
            opts = RosOptions(opts.joint_topic, opts.wrench_topic, opts.joints, opts.force_sign, t0)
        if column_map:
            opts = RosOptions(opts.joint_topic, opts.wrench_topic, _joints_from_map(path, column_map),
                              opts.force_sign, opts.t0)  # fmt: skip
        return load_ros_bag(path, opts)
    if not (math.isfinite(time_scale) and time_scale > 0):
        raise LegbenchError(f"{words.time_scale} {time_scale!r}: must be a finite number > 0 (1e-3 for ms)")
    _check_regular(path)
    try:
        with warnings.catch_warnings():
            # index_col=False: a trailing comma on every data row (an empty extra field) is no index column; a
            # non-empty extra value, which pandas would drop with a ParserWarning, is refused below
            warnings.simplefilter("error", pd.errors.ParserWarning)
            raw = pd.read_csv(path, index_col=False)
        written = _written_header(path)
    except pd.errors.ParserWarning:
        raise ResultsError(str(path), "data rows hold more values than the header names: name every column, or "
                                      "drop the extra values (a trailing comma is fine)") from None  # fmt: skip
    except Exception as exc:  # parser errors come in several types
        raise ResultsError(str(path), f"not a readable CSV file ({type(exc).__name__}: {exc})") from exc
    if raw.shape[1] == 1 and any(sep in str(raw.columns[0]) for sep in ";\t"):  # read as one column
        raise ResultsError(str(path), f"one column, its header {str(raw.columns[0])[:60]!r}: separated by ';' or "
                                      "tabs? a log is read as comma-separated CSV")  # fmt: skip
    _check_unique_header(path, written if len(written) == raw.shape[1] else list(map(str, raw.columns)))
    cmap = dict(column_map or {})
    unknown_targets = sorted(set(cmap.values()) - set(RUN_COLUMNS))
    if unknown_targets:
        raise ResultsError(
            str(path), f"column_map targets {unknown_targets} are not legbench columns {list(RUN_COLUMNS)}"
        )
    absent = sorted(set(cmap) - set(map(str, raw.columns)))
    if absent:
        raise ResultsError(str(path), f"column_map names {absent} are not in the header {list(map(str, raw.columns))}")
    claimed = set(cmap.values())  # an explicit mapping wins: automatic matches to these targets are ignored
    rename: dict[str, str] = {}
    for col in map(str, raw.columns):
        target = cmap.get(col) or _normalise_header(col)
        if target in RUN_COLUMNS and (col in cmap or target not in claimed):
            rename[col] = target
    targets = list(rename.values())
    dupes = sorted({c for c in targets if targets.count(c) > 1})
    if dupes:
        raise ResultsError(str(path), f"several header columns map to {dupes}; choose one with {words.pick_column}")
    df = raw[list(rename)].rename(columns=rename)
    required = ["t", "q1", "q2", "q3"]
    unmatched = [c for c in required if c not in df.columns]
    if unmatched:  # name the file's own header: the usual cause is a header of other names, to be mapped
        header = list(map(str, raw.columns))
        moved = [(c, cmap[c]) for c in header if c in cmap and _normalise_header(c) in unmatched]
        if moved:  # the column of that name is there, mapped elsewhere: nothing is left to give it
            col, target = moved[0]
            raise ResultsError(str(path), f"column {col!r} is mapped to {target} ({words.pick_column}), so no column "
                                          f"gives {_normalise_header(col)}; map one to it too")  # fmt: skip
        raise ResultsError(str(path), f"no column matches {unmatched} in the header {header}; map them with "
                                      f"{words.map_columns}")  # fmt: skip
    given = {target: _unit_factor(path, col, target) for col, target in rename.items()}
    factor = {target: 1.0 if f is None else f for target, f in given.items()}
    if given["t"] is not None and time_scale != 1.0:  # both say the time's unit: one would be ignored or doubled
        raise LegbenchError(f"{words.time_scale} {time_scale!r}: {path}'s header gives the time's unit already "
                            f"({[c for c, t in rename.items() if t == 't'][0]!r}); give one or the other")  # fmt: skip
    scale, shift = time_scale * factor["t"], float(t0 or 0.0)
    if scale != 1.0 or shift:  # in the run's seconds before it is checked, so an error reads its times so
        try:
            raw_t = pd.to_numeric(df["t"], errors="raise").to_numpy(dtype=float)
        except (ValueError, TypeError):
            pass  # not numbers: result_from_frame says so, naming the column
        else:
            new_t = raw_t * scale - shift
            if np.all(np.diff(raw_t) > 0) and not np.all(np.diff(new_t) > 0):  # the file's times were fine
                option, fix = (
                    (f"{words.t0} {shift:g}", "give a t0 near the log's own times")
                    if shift
                    else (f"{words.time_scale} {time_scale:g}", "give the scale of the log's time unit")
                )
                raise LegbenchError(f"{option}: {path}'s times, strictly increasing as written, are no longer "
                                    f"distinct once converted ({scale:g} x t - {shift:g} s, in double precision): "
                                    f"{fix}")  # fmt: skip
            df = df.assign(t=new_t)
    try:
        trace = result_from_frame(df, path.stem, str(path), required)  # validates
    except ResultsError as exc:  # name a column as the file's header does, with legbench's name for it
        problem = exc.problem
        for col, target in rename.items():
            if col != target:
                problem = problem.replace(f"column '{target}'", f"column '{col}' ({target})")
        raise ResultsError(exc.file, problem, exc.key) from None
    data = trace.data * np.array([factor.get(c, 1.0) for c in LABELS])
    ee = trace.ee * np.array([factor.get(c, 1.0) for c in EE_COLUMNS])
    t = trace.t
    _check_plausible(t, data, str(path), ee)
    out = {"t": t}
    out |= {c: data[:, i] for i, c in enumerate(LABELS)}
    out |= {c: v for c, v in zip(EE_COLUMNS, _foot(ee, data[:, 0:3]).T, strict=True)}
    out["controller"] = trace.controller.astype(str) if "controller" in df.columns else np.full(len(df), "")
    return pd.DataFrame(out, columns=list(RUN_COLUMNS))


# --------------------------------------------------------------------------- #
# ROS bags


@dataclass(frozen=True)
class RosOptions:
    """How a ROS bag maps to legbench's signals.

    Attributes:
        joint_topic: the ``sensor_msgs/JointState`` topic; None: the bag's only one.
        wrench_topic: the ``geometry_msgs/WrenchStamped`` topic of the ground force; None: the bag's only
            one, or no force (NaN) if it has none; ``""``: no force even if there is one.
        joints: the JointState names of joints 1, 2, 3 (ab/ad, hip, knee); None: legbench's own
            (:data:`DEFAULT_JOINTS`).
        force_sign: +1 if the wrench is the force the ground exerts on the foot (legbench's convention),
            -1 if it is the force the foot exerts on the ground. Its frame is taken as W: a bag carries
            no transform legbench could apply.
        t0: the bag time [s] that is legbench's t = 0; None: the first joint-state sample. Times are
            the messages' header stamps when both topics have them, else both topics' recording times.
    """

    joint_topic: str | None = None
    wrench_topic: str | None = None
    joints: tuple[str, str, str] | None = None
    force_sign: float = 1.0
    t0: float | None = None


def is_ros_bag(path: str | Path) -> bool:
    """True for a ROS 1 ``.bag`` file, a ROS 2 bag directory (``metadata.yaml``) or its ``.db3`` / ``.mcap`` file."""
    path = Path(path)
    if path.suffix == ".bag":
        return True
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix in (".db3", ".mcap")


def digest(path: str | Path) -> str:
    """SHA-256 [hex] of what a log holds: a file's bytes, or for a ROS 2 bag directory each of its files' name
    (relative to the directory) and SHA-256, in name order; so a log re-recorded under the same name is told from
    the one a result was computed with (metrics.json records it; ``legbench check`` compares it)."""
    path = Path(path)
    if not path.is_dir():
        with path.open("rb") as stream:
            return hashlib.file_digest(stream, "sha256").hexdigest()
    h = hashlib.sha256()
    for f in sorted(p for p in path.rglob("*") if p.is_file()):
        h.update(f"{f.relative_to(path).as_posix()}\0{digest(f)}\n".encode())
    return h.hexdigest()


def _joints_from_map(path: Path, column_map: Mapping[str, str]) -> tuple[str, str, str]:
    """``{"hip_aa": "q1", "hip_fe": "q2", "knee": "q3"}`` -> the names of joints 1, 2, 3."""
    by_col = {v: k for k, v in column_map.items()}
    wrong = sorted(set(by_col) - {"q1", "q2", "q3"})
    if wrong or len(by_col) != 3 or len(column_map) != 3:
        raise ResultsError(
            str(path), f"a bag's column map names its three joints, {_WORDS.get().joints}; got {dict(column_map)}"
        )
    return (by_col["q1"], by_col["q2"], by_col["q3"])


def _stamp(msg: Any) -> int:
    """Header stamp [ns] (``sec``/``nanosec`` in rosbags' types for ROS 1 and ROS 2). Integer: a float of
    seconds since 1970 resolves only 0.24 us."""
    st = msg.header.stamp
    return int(st.sec) * 1_000_000_000 + int(st.nanosec)


def _pick_topic(path: Path, topics: Mapping[str, str], msgtype: str, asked: str | None, required: bool) -> str | None:
    have = sorted(t for t, typ in topics.items() if typ == msgtype)
    short = msgtype.replace("/msg/", "/")
    if asked is not None:
        if asked == "" and not required:
            return None
        if topics.get(asked) != msgtype:
            found = f"it is {topics[asked]}" if asked in topics else "no such topic"
            raise ResultsError(str(path), f"topic '{asked}': expected {short}, {found}; {short} topics: {have}")
        return asked
    if len(have) == 1:
        return have[0]
    if not have and not required:
        return None
    words = _WORDS.get()
    option = words.joint_topic if msgtype == JOINT_STATE else words.wrench_topic
    if not have:
        raise ResultsError(str(path), f"no {short} topic in the bag (topics: {sorted(topics)})")
    raise ResultsError(str(path), f"several {short} topics ({', '.join(have)}); name one with {option}")


def load_ros_bag(path: str | Path, options: RosOptions | None = None) -> pd.DataFrame:
    """Read a ROS 1 or ROS 2 bag into the run columns (see the module docstring and :class:`RosOptions`).

    Returns:
        DataFrame with the columns of :data:`RUN_COLUMNS`: t [s] from ``t0``; q, qd, tau per joint
        (NaN where a JointState has no velocity or effort); fx, fy, fz, the ground force on the foot in
        W [N] linearly interpolated at the joint-state times (NaN outside the wrench samples or
        without a wrench topic); ee from q; controller "".

    Raises:
        ResultsError: rosbags is not installed, the bag is unreadable, a topic is missing or ambiguous,
            a joint name is absent, or time is not strictly increasing.
    """
    opts = options or RosOptions()
    path = Path(path)
    try:
        from rosbags.highlevel import AnyReader
    except ImportError as exc:
        raise ResultsError(str(path), "reading ROS bags needs rosbags: pip install 'legbench[ros]'") from exc
    bag = path.parent if path.suffix in (".db3", ".mcap") and (path.parent / "metadata.yaml").is_file() else path
    if not bag.exists():
        raise ResultsError(str(path), "no such bag")
    mode = bag.stat().st_mode
    if not (stat.S_ISDIR(mode) or stat.S_ISREG(mode)):  # a FIFO would block the reader until a writer came
        raise ResultsError(str(path), f"is {file_kind(mode)}, not a regular file (a bag is read only from one)")
    if stat.S_ISDIR(mode) and bag.suffix == ".bag":  # rosbags takes any '.bag' name for a ROS 1 file
        raise ResultsError(str(path), "a ROS 2 bag directory named '.bag': rosbags reads that name as a ROS 1 bag "
                                      "file; rename the directory (e.g. without the suffix)")  # fmt: skip
    joints = opts.joints or DEFAULT_JOINTS
    try:
        reader = AnyReader([bag])
        reader.open()
    except Exception as exc:  # rosbags raises several types for unreadable bags
        raise ResultsError(str(path), f"not a readable ROS bag ({type(exc).__name__}: {exc})") from exc
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        jt = _pick_topic(path, topics, JOINT_STATE, opts.joint_topic, required=True)
        wt = _pick_topic(path, topics, WRENCH, opts.wrench_topic, required=False)
        j_stamp: list[int] = []
        j_rec: list[int] = []
        rows: list[np.ndarray] = []  # (9,): q1..q3, qd1..qd3, tau1..tau3
        w_stamp: list[int] = []
        w_rec: list[int] = []
        forces: list[tuple[float, float, float]] = []
        index: dict[tuple[str, ...], list[int]] = {}
        conns = [c for c in reader.connections if c.topic in (jt, wt)]
        for conn, recorded, raw in reader.messages(connections=conns):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            if conn.topic == jt:
                names = tuple(msg.name)
                idx = index.get(names)
                if idx is None:
                    missing = [j for j in joints if j not in names]
                    if missing:
                        raise ResultsError(
                            str(path),
                            f"topic '{jt}': joints {missing} not in the message's names {list(names)}; "
                            f"map them with {_WORDS.get().map_joints}",
                        )
                    idx = index[names] = [names.index(j) for j in joints]
                row = np.full(9, np.nan)
                for k, field in enumerate(("position", "velocity", "effort")):
                    values = np.asarray(getattr(msg, field), float)
                    if values.size == len(names):
                        row[3 * k : 3 * k + 3] = values[idx]
                rows.append(row)
                j_stamp.append(_stamp(msg))
                j_rec.append(recorded)
            else:
                f = msg.wrench.force
                forces.append((f.x, f.y, f.z))
                w_stamp.append(_stamp(msg))
                w_rec.append(recorded)
    except ResultsError:
        raise
    except Exception as exc:
        raise ResultsError(str(path), f"not a readable ROS bag ({type(exc).__name__}: {exc})") from exc
    finally:
        reader.close()
    if not rows:
        raise ResultsError(str(path), f"topic '{jt}' has no messages")
    # one clock for both topics: the header stamps when every topic has them, else the recording times (a
    # topic with zero stamps next to one stamped in simulation time would share no time with it)
    stamped = any(j_stamp) and (not forces or any(w_stamp))
    ns = np.asarray(j_stamp if stamped else j_rec, np.int64)
    ns0 = int(ns[0]) if opts.t0 is None else round(opts.t0 * 1e9)
    t_abs = (ns - ns0) * 1e-9  # [s] from t0, exact to the ns
    data = np.vstack(rows)
    force = np.full((len(rows), 3), np.nan)
    if forces:
        tw = (np.asarray(w_stamp if stamped else w_rec, np.int64) - ns0) * 1e-9
        order = np.argsort(tw, kind="stable")
        fw = opts.force_sign * np.asarray(forces, float)[order]
        for i in range(3):
            force[:, i] = np.interp(t_abs, tw[order], fw[:, i], left=np.nan, right=np.nan)
        if np.isnan(force[:, 0]).all():
            clock = "header stamps" if stamped else "recording times"
            logger.warning("legbench: warning: %s: the wrench topic '%s' spans [%.6g, %.6g] s and the joint states "
                           "[%.6g, %.6g] s (%s): no shared time, the ground force is left out", path, wt,
                           tw.min(), tw.max(), t_abs[0], t_abs[-1], clock)  # fmt: skip
    df = pd.DataFrame(np.column_stack([t_abs, data, force]), columns=["t", *LABELS])
    trace = result_from_frame(df, path.stem, str(path), ["t", "q1", "q2", "q3"])  # validates (t increasing)
    out = {"t": trace.t}
    out |= {c: trace.data[:, i] for i, c in enumerate(LABELS)}
    out |= {c: v for c, v in zip(EE_COLUMNS, _foot(trace.ee, trace.q).T, strict=True)}
    out["controller"] = np.full(len(df), "")
    return pd.DataFrame(out, columns=list(RUN_COLUMNS))
