"""The run directory: the one writer and the one validated reader of what a run leaves on disk.

A run directory holds, per scenario (and contact mode):

* ``<backend>.parquet`` (and optionally ``.csv``): one row per control tick,
  columns :data:`~legbench.signals.RUN_COLUMNS`;
* ``run.json``: the scenario as run, every backend's status, reason, settings
  (``info``, with its declared ``integrator_family``, ``sub_steps``, ``engine_contact`` and
  ``sliding_coefficient``), wall
  time and real-time factor, versions and platform;
* ``metrics.json``: what :mod:`legbench.compare` measured (schema
  :data:`METRICS_SCHEMA`, keys in docs/metrics.md).

:class:`RunResult` is the one shape a backend's run takes between stages: the
run loop returns it, :func:`write_run` writes it, :func:`load_run` reads it
back, the metrics, the studies and the report take it. Every reader here
raises :class:`~legbench.exceptions.ResultsError` with one line naming the
file and the problem on a missing, malformed or foreign directory.
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import json
import logging
import math
import os
import platform
import re
import shutil
import subprocess
import tempfile
from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields
from functools import cache, cached_property
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from legbench import backends as registry
from legbench import kinematics, resources
from legbench.contact import ContactParams
from legbench.exceptions import LegbenchError, ResultsError
from legbench.model import load_params
from legbench.scenario import DEFAULT_REFERENCE, Scenario
from legbench.signals import EE_COLUMNS, LABELS, RUN_COLUMNS, SLICE
from legbench.yamlfile import file_kind

__all__ = [
    "FRAME_COLUMNS",
    "METRICS_SCHEMA",
    "STATUSES",
    "CHECK_OUTPUTS",
    "INDEX_TITLE",
    "RUN_FILES",
    "SHOWN_SCALE",
    "STUDY_OUTPUTS",
    "BackendStatus",
    "EventMark",
    "Run",
    "RunProblems",
    "RunResult",
    "atomic_dir",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_out_dir",
    "check_index_pages",
    "check_out_file",
    "check_out_path",
    "check_study_out",
    "enclosing_run",
    "is_index",
    "check_out_tree",
    "checks_summary",
    "clean_stale",
    "commit_staged",
    "comparison_pending",
    "discard_staged",
    "json_default",
    "load_run",
    "log_digests",
    "load_trace",
    "metrics_text",
    "out_dir_for",
    "run_label",
    "platform_info",
    "profile_of",
    "read_log",
    "read_meta",
    "read_metrics",
    "read_study",
    "replaced_by_run",
    "result_from_frame",
    "resumable",
    "run_dirs",
    "run_problems",
    "stage_text",
    "staged_name",
    "study_dir",
    "versions",
    "write_json",
    "write_metrics",
    "write_run",
]

logger = logging.getLogger("legbench.results")

#: Version tag written into metrics.json.
METRICS_SCHEMA = "legbench.metrics/1"
#: Rows per Parquet row group of a run's log: the writer builds and encodes one group at a time (~2 MB).
PARQUET_ROW_GROUP = 16_384
#: Columns of the long metrics table (rows of metrics.json).
FRAME_COLUMNS = ("scenario", "backend", "reference", "signal", "joint", "metric", "value")


# --------------------------------------------------------------------------- #
# The run result


@dataclass(eq=False)
class RunResult:
    """One backend's run (or an imported log): arrays of shape (n,) or (n, 3), and how it went.

    Attributes:
        backend: backend name (or the name given to an imported log).
        t: tick times, strictly increasing [s].
        q: joint angles [rad].
        qd: joint velocities [rad/s].
        tau: joint torques applied over [t_k, t_k + Ts), after saturation [N m].
        f: ground force on the foot in W [N].
        controller: active controller name per tick (empty strings if unknown).
        status: ``ok``, ``failed``, ``missing`` or ``interrupted``.
        reason: why it is not ok (None when ok).
        info: the backend's settings as it reported them (:func:`legbench.run.backend_info`).
        wall_time: wall-clock time of the simulation loop [s].
        source: the file it was read from ("" for a run in memory).
        foot: foot centre in W as logged [m], or None: computed from q.
    """

    backend: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    f: np.ndarray
    controller: np.ndarray
    status: str = "ok"
    reason: str | None = None
    info: dict[str, Any] = field(default_factory=dict)
    wall_time: float = 0.0
    source: str = ""
    foot: np.ndarray | None = None

    @classmethod
    def empty(cls, backend: str, status: str, reason: str) -> RunResult:
        """A result with no ticks: a backend that is missing, failed to load or never started."""
        none = np.empty((0, 3))
        return cls(backend, np.empty(0), none, none, none, none, np.empty(0, dtype=object), status, reason)

    @property
    def ee(self) -> np.ndarray:
        """Foot centre in W [m]: as logged, else from the logged joint angles."""
        return kinematics.fk(self.q) if self.foot is None else self.foot

    @cached_property
    def data(self) -> np.ndarray:
        """The 12 :data:`~legbench.signals.LABELS` columns (q, qd, tau, f), shape (n, 12)."""
        return np.column_stack([self.q, self.qd, self.tau, self.f])

    def signal(self, signal: str) -> np.ndarray:
        """The (n, 3) columns of one signal (``q``, ``qd``, ``tau``, ``force`` or ``ee``) in its unit."""
        if signal == "ee":
            return self.ee if len(self.t) else np.empty((0, 3))
        return self.data[:, SLICE[signal]]

    def has(self, signal: str) -> bool:
        """True if the signal has at least one finite sample."""
        return bool(np.isfinite(self.signal(signal)).any())

    def arrow_table(self, start: int = 0, stop: int | None = None) -> pa.Table:
        """Rows ``start:stop`` of the log as an Arrow table with the columns of
        :data:`~legbench.signals.RUN_COLUMNS`, built column by column (one copy of each column slice; no stacked
        array, no DataFrame). :func:`write_log` writes a log slice by slice with it."""
        rows = slice(start, stop)
        q = self.q[rows]
        ee = self.foot[rows] if self.foot is not None else kinematics.fk(q)
        cols: dict[str, Any] = {"t": np.ascontiguousarray(self.t[rows], dtype=float)}
        names = iter(RUN_COLUMNS[1:-1])
        for block in (q, self.qd[rows], self.tau[rows], self.f[rows], ee):
            for j in range(3):
                cols[next(names)] = np.ascontiguousarray(block[:, j], dtype=float)
        cols["controller"] = pa.array(self.controller[rows], type=pa.string(), from_pandas=True)
        return pa.table(cols)

    def frame(self) -> pd.DataFrame:
        """The log as a DataFrame with the columns of :data:`~legbench.signals.RUN_COLUMNS`."""
        data = np.column_stack([self.t, self.q, self.qd, self.tau, self.f, self.ee])
        df = pd.DataFrame(data, columns=list(RUN_COLUMNS[:-1]))
        df["controller"] = self.controller
        return df


# --------------------------------------------------------------------------- #
# Provenance


#: The packages besides the engines whose versions decide a run's numbers or files: numba and llvmlite compile the
#: tick and the kernels, pyarrow writes the logs, PyYAML reads the scenario.
CORE_PACKAGES = ("legbench", "numpy", "scipy", "pandas", "numba", "llvmlite", "pyarrow", "PyYAML")


def versions() -> dict[str, str]:
    """Versions of legbench (with ``legbench_commit``, :func:`source_commit`, where it runs from a git checkout),
    Python, :data:`CORE_PACKAGES` and every engine package that imports."""
    out = {"python": platform.python_version()}
    for pkg in (*CORE_PACKAGES, *registry.engine_packages()):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            continue
    commit = source_commit()
    if commit:
        out["legbench_commit"] = commit
    return out


def leg_model() -> dict[str, str]:
    """The leg parameter file active now, as outputs name it (:func:`~legbench.resources.shown`), and its digest
    (:func:`~legbench.resources.param_digest`, the stamp of its URDF): run.json recorded only the URDF's name, which is
    ``leg.urdf`` for the bundled leg whatever its numbers (the leg file changed five times) and another name for a
    byte copy of it; ``legbench check`` compares the digests where both runs have them."""
    params = resources.model_file()
    return {"parameters": resources.shown(params), "digest": resources.param_digest(params)}


@cache
def source_commit(root: Path | None = None) -> str:
    """The git commit of the checkout legbench runs from (``root``: the package's parent directory), with
    `` (uncommitted changes)`` where tracked files differ from it; "" outside a git checkout (an installed wheel:
    its version says what it is) or without git. legbench's version alone said 0.1.0 over every commit, so a
    result directory could not say which code made it. Read once per process."""
    root = Path(__file__).resolve().parent.parent if root is None else root
    if not (root / ".git").exists():
        return ""
    try:

        def git(*args: str) -> str:
            return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=30,
                                  check=True).stdout.strip()  # fmt: skip

        commit = git("rev-parse", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no") != ""
    except (OSError, subprocess.SubprocessError):
        return ""
    return commit + (" (uncommitted changes)" if dirty else "")


def platform_info() -> dict[str, Any]:
    """The machine: system, architecture, processor, its CPU model (Linux's /proc/cpuinfo; ``processor``, which is
    empty on Linux, elsewhere), CPU count and host name."""
    cpu = platform.processor()
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    return {"system": platform.system(), "machine": platform.machine(), "processor": platform.processor(),
            "cpu_model": cpu, "cpus": os.cpu_count(), "node": platform.node()}  # fmt: skip


def json_default(o: Any) -> Any:
    """JSON for numpy arrays and scalars and paths (everything else as its text)."""
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    return str(o)


def write_json(doc: Any, path: Path) -> Path:
    """``doc`` as indented JSON at ``path``, written atomically (numpy values converted)."""
    return atomic_write_text(path, json.dumps(doc, indent=2, default=json_default))


# --------------------------------------------------------------------------- #
# Atomic writes: a temporary name in the same directory, then a rename

#: Temporary and displaced names this module (and earlier code) leaves while writing:
#: ``.<name>.tmp-<pid>``, ``.<name>.old-<pid>``, ``.<name>.out.tmp-<pid>``.
_TEMP_RE = re.compile(r"^\.(?P<name>.+?)\.(?P<kind>tmp|old|out\.tmp)-(?P<pid>\d+)$")


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    except OSError:
        return False
    return True


def clean_stale(parent: str | Path) -> list[Path]:
    """Remove temporary files and directories of earlier killed runs in ``parent`` (their PID is dead).

    A displaced ``.<name>.old-<pid>`` whose ``<name>`` is missing (a kill between the two renames of a
    directory swap) is renamed back, so the previous result comes back. Returns what was removed or restored.
    """
    parent = Path(parent)
    done: list[Path] = []
    try:
        entries = list(parent.iterdir())
    except OSError:
        return done
    for p in entries:
        m = _TEMP_RE.match(p.name)
        if not m or _pid_alive(int(m["pid"])):
            continue
        target = parent / m["name"]
        try:
            if m["kind"] == "old" and not target.exists():
                p.rename(target)
            elif p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            else:
                p.unlink()
            done.append(p)
        except OSError as exc:  # not ours to remove (permissions): leave it, say so in the log
            logger.info("cannot clean %s: %s", p, exc)
    return done


def _tmp_name(path: Path, kind: str = "tmp") -> Path:
    return path.with_name(f".{path.name}.{kind}-{os.getpid()}")


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same directory, renamed over ``path``.

    A failure (full disk, read-only directory, a kill) leaves the previous ``path`` intact and no
    temporary file behind (one left by a kill is removed by :func:`clean_stale`).

    Raises:
        OSError: the write or the rename failed (:mod:`legbench.cli` reports it in one line, exit 4).
    """
    path = Path(path)
    tmp = _tmp_name(path)
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        _name_it(exc, path)
        raise
    return path


def _name_it(exc: BaseException, path: Path) -> None:
    """An OSError of a write that names no file (a full disk: "No space left on device") names ``path``, the
    output it was for, so the one line the CLI prints says where (:mod:`legbench.cli`)."""
    if isinstance(exc, OSError) and exc.errno is not None and not exc.filename:  # an errno the CLI words by
        exc.filename = str(path)


def atomic_write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`atomic_write_bytes`)."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def staged_name(final: Path, tag: str) -> Path:
    """Where ``final`` is written before it is put in place by :func:`commit_staged`:
    ``.<name>.out.tmp-<tag>`` beside it (``tag`` the writing command's PID, so :func:`clean_stale` removes
    what a killed command left)."""
    return final.with_name(f".{final.name}.out.tmp-{tag}")


def stage_text(final: Path, text: str, tag: str) -> tuple[Path, Path]:
    """Write ``text`` (UTF-8, synced) under ``final``'s staged name; ``final`` is untouched until
    :func:`commit_staged`. Several files staged first and committed together put a set of files in place
    only once every one of them could be made. Returns (staged, final)."""
    staged = staged_name(final, tag)
    try:
        with open(staged, "wb") as fh:
            fh.write(text.encode("utf-8"))
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        _name_it(exc, final)
        raise
    return staged, final


def commit_staged(moves: Sequence[tuple[Path, Path]]) -> None:
    """Put staged files in place, one rename each, in the order given."""
    for staged, final in moves:
        os.replace(staged, final)


def discard_staged(finals: Sequence[Path], tag: str) -> None:
    """Remove the staged files of ``finals`` that exist (an aborted set: nothing of it is put in place)."""
    for final in finals:
        with contextlib.suppress(OSError):
            staged_name(final, tag).unlink()


@contextlib.contextmanager
def atomic_dir(path: str | Path, keep: Sequence[str] = ()) -> Iterator[Path]:
    """Build a directory whole, then swap it in place of ``path``.

    Yields a temporary sibling directory (``.<name>.tmp-<pid>``) to write into. On a normal exit it
    replaces ``path`` (the old one is moved aside, the new one renamed in, the old one removed); on an
    exception the temporary directory is removed and ``path`` is left as it was. Files named in ``keep``
    that exist in the old ``path`` and were not written anew are carried over. Stale temporaries of
    killed runs beside ``path`` are cleaned first (:func:`clean_stale`). A ``path`` that is a symbolic link is
    followed: the directory it names is the one replaced (beside it), the link stays (as a tree's root or a
    study's output directory given as a link is written through it); the link itself was once replaced by a new
    directory, the old one left as it was.
    """
    path = Path(os.path.realpath(path)) if Path(path).is_symlink() else Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_stale(path.parent)
    tmp = _tmp_name(path)
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        yield tmp
        for name in keep:
            if (path / name).exists() and not (tmp / name).exists():
                if (path / name).is_dir():
                    shutil.copytree(path / name, tmp / name)
                else:
                    shutil.copy2(path / name, tmp / name)
        if path.exists():
            old = _tmp_name(path, "old")
            shutil.rmtree(old, ignore_errors=True)
            path.rename(old)
            try:
                tmp.rename(path)
            except BaseException:
                old.rename(path)
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(path)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        _name_it(exc, path)
        raise


def _kind(path: Path) -> str:
    """What ``path``, an existing non-directory, is: ``a regular file``, ``a character device`` (/dev/null), ..."""
    try:
        return file_kind(os.stat(path).st_mode)
    except OSError:
        return "not a directory"


def _writable_dir(d: Path, what: str) -> None:
    """The nearest existing ancestor of ``d`` is a directory we can write into: its permissions say so, and a
    folder made there (and removed at once) is made, which root's permissions do not tell (/proc, a read-only
    or full file system)."""
    probe = d
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise LegbenchError(f"{what} {d}: {probe} is {_kind(probe)}, not a directory")
    if probe.exists() and not os.access(probe, os.W_OK | os.X_OK):
        raise LegbenchError(f"{what} {d}: {probe} is not writable")
    if probe.exists():
        try:
            os.rmdir(tempfile.mkdtemp(prefix=".legbench-probe-", dir=probe))
        except OSError as exc:
            raise LegbenchError(f"{what} {d}: {probe} is not writable ({exc.strerror or exc})") from None


#: Decimal digits of the largest process ID (Linux's pid_max is at most 4194304): the PID ends every temporary name.
_PID_DIGITS = 7


def _check_temp_names(path: Path, what: str) -> None:
    """The temporary siblings the writers make of ``path`` (``.<name>.tmp-<pid>``, ``.<name>.old-<pid>``;
    :func:`atomic_dir`, :func:`atomic_write_bytes`; a report's staged pages are the run's own short names) fit the file
    system's longest name (NAME_MAX of the nearest existing folder, else 255): a name that fits but whose temporary
    does not failed only when the results were written, after all the work."""
    probe = path.parent
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    try:
        name_max = os.pathconf(probe, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    longest = len(f".{path.name}.tmp-") + _PID_DIGITS  # .tmp- and .old- alike; .out.tmp- only for the pages in a run
    if path.name and longest > name_max:
        raise LegbenchError(f"{what} {path}: a name of {len(path.name)} characters; the temporary names legbench "
                            f"writes beside it must fit {name_max}, so at most {name_max - longest + len(path.name)} "
                            "characters")  # fmt: skip


def check_out_path(path: str | Path, what: str = "--out", *, run_dir_ok: bool = False) -> Path:
    """An output directory given on the command line (``what``: the option, or the Python API's argument), checked
    before any work: not a regular file, device or other non-directory (the message says which), not a link to
    nothing (the result could not be moved into place), inside a writable place (missing folders are created when
    writing), and not inside a run directory (one holding run.json): what is nested in a run would be taken for part
    of that run (its report, its check), or lost with it when the run is replaced. Nor a run directory itself,
    unless ``run_dir_ok`` (``legbench run`` resumes or replaces its own). A path that cannot be (a name too long, a
    loop of links) is one error too, and so is a name whose temporary siblings would not fit
    (:func:`_check_temp_names`)."""
    path = Path(path)
    try:
        if path.is_symlink() and not path.exists():
            raise LegbenchError(f"{what} {path}: a symbolic link to {os.readlink(path)}, which does not exist; "
                                f"choose another {what}")  # fmt: skip
        if path.exists() and not path.is_dir():
            raise LegbenchError(f"{what} {path}: is {_kind(path)}, not a directory")
        _writable_dir(path, what)
        _check_temp_names(path, what)
        if not run_dir_ok and (path / "run.json").is_file():
            raise LegbenchError(f"{what} {path}: a run directory, which holds one run; choose another {what}")
        parent = enclosing_run(path)
        if parent is not None:
            raise LegbenchError(f"{what} {path}: inside the run directory {parent}, which holds one run; "
                                f"choose another {what}")  # fmt: skip
    except (OSError, RuntimeError) as exc:  # a place that cannot be (a name too long, a loop of links)
        raise LegbenchError(f"{what} {path}: {getattr(exc, 'strerror', None) or exc}") from None
    return path


def enclosing_run(path: str | Path) -> Path | None:
    """The nearest directory above ``path`` (not ``path`` itself) that is a run directory (holds run.json), or
    None. The path is resolved first: links followed and ``..`` taken after them, so ``RUN/../x`` is not inside
    RUN and a link into a run is.

    Raises:
        OSError, RuntimeError: a path that cannot be resolved (a name too long; a loop of links).
    """
    for parent in Path(path).resolve().parents:
        if (parent / "run.json").is_file():
            return parent
    return None


#: The JSON document each study writes into its output directory: a directory holding one is legbench's.
STUDY_OUTPUTS = ("verification.json", "calibration.json", "sweep.json", "reproduce.json", "bench.json", "scaling.json")


def study_dir(root: str | Path, study: str, profile: str = registry.PROFILES[0]) -> Path:
    """Where a results tree keeps a per-profile study's output (``study``: ``verification`` for ``legbench
    verify``, ``calibration`` for ``legbench calibrate-contact``) for ``profile``: ``<root>/<study>`` for the
    matched profile, ``<root>/<study>__<profile>`` for another (the suffix the run folders take), where the index
    finds it."""
    return Path(root) / _profiled(study, profile)


def _profiled(name: str, profile: str) -> str:
    """A results folder's name in ``profile``: ``name`` for the matched profile, ``name__<profile>`` for another
    (:data:`legbench.scenario.RESERVED_SUFFIXES`), for runs and studies alike."""
    return name if profile == registry.PROFILES[0] else f"{name}__{profile}"


#: Columns of a study's output shown in another unit than the file's SI value, and the factor: the contact
#: calibration's creep [m/s] in mm/s, as on the run pages' contact-law residuals (its own page and the index's table).
SHOWN_SCALE = {"creep": 1e3, "jitter": 1e3, "creep_law": 1e3}
#: What ``legbench check`` writes by default into the results it checks (a tree's root, or a run directory).
CHECK_OUTPUTS = ("check.md", "check-junit.xml")
#: The title of a results tree's index: the first line of its report.md, the <title> of its report.html.
INDEX_TITLE = "legbench: comparison summary"


def is_index(page: Path) -> bool:
    """Whether ``page`` (a tree's report.md or report.html) is an index legbench wrote: :data:`INDEX_TITLE` where
    the index puts it, read from its first 1 kB (an unreadable file is not legbench's to replace)."""
    try:
        with page.open("rb") as fh:
            head = fh.read(1024).decode("utf-8", "replace")
    except OSError:
        return False
    if page.suffix == ".md":
        return head.startswith(f"# {INDEX_TITLE}\n")
    return f"<title>{INDEX_TITLE}</title>" in head


def check_index_pages(root: str | Path) -> None:
    """Refuse, before any work, a results tree whose report.md or report.html is not an index legbench wrote: the
    tree's index goes there, and a page of the user's was replaced by it.

    Raises:
        ResultsError: naming the page.
    """
    for page in (Path(root) / "report.md", Path(root) / "report.html"):
        if page.exists() and not is_index(page):
            raise ResultsError(str(page), "not an index legbench wrote, and this results tree's index goes there; "
                                          "move it away first")  # fmt: skip


def check_out_tree(
    root: str | Path, dirs: Collection[str], files: Collection[str], kind: str, option: str = "--out"
) -> None:
    """Refuse a results tree's root (``legbench reproduce --out``, ``legbench run`` of several runs with
    ``--out``) holding anything legbench did not put there, before any work: every entry must be a directory
    named in ``dirs`` (the tree's run directories, each checked on its own by the caller), any run directory
    (holds run.json) or study output (holds one of :data:`STUDY_OUTPUTS`), a file named in ``files`` (the
    tree's pages), or a temporary of an earlier write (:func:`clean_stale` removes it). A missing or empty
    root is fine; ``kind`` names the tree in the message, ``option`` what the caller named the root with (the
    Python API's ``out``)."""
    root = Path(root)
    if not root.is_dir():
        return
    for p in sorted(root.iterdir()):
        ours = p.is_dir() and (p.name in dirs or any((p / f).is_file() for f in ("run.json", *STUDY_OUTPUTS)))
        if _TEMP_RE.match(p.name) or ours:
            continue
        if p.is_file() and p.name in files:
            continue
        raise LegbenchError(f"{root}: not empty and not a legbench {kind} directory (it holds {p.name}); "
                            f"choose another {option}")  # fmt: skip


def check_study_out(out: str | Path, doc: str, files: Collection[str], kind: str, force: bool) -> None:
    """A study's output directory (``legbench verify``, ``calibrate-contact``, ``bench``), before any work: it holds
    nothing but the study's own ``files`` (:func:`check_out_tree`: a folder of someone else's is refused), and
    its finished document ``doc`` (one of ``files``) is replaced only with ``force``.

    Raises:
        LegbenchError: one line naming the directory and what it holds.
    """
    out = Path(out)
    check_out_tree(out, (), files, kind)
    if not force and (out / doc).is_file():
        raise LegbenchError(f"{out} holds a finished {kind} ({doc}); choose another --out for a new one, or --force "
                            "to replace it")  # fmt: skip


def check_out_file(path: str | Path, what: str = "--out", *, in_run_ok: bool = False) -> Path:
    """An output file given on the command line, checked before any work: not a directory, not a symbolic link
    (the file is written beside it and renamed over it, so the link itself was replaced, whatever it named), nor
    anything else but a regular file if it exists (a device, a FIFO, a socket: with ``--force`` one was replaced
    by a plain file); its folder exists and is writable, its temporary sibling fits (:func:`_check_temp_names`),
    and, unless ``in_run_ok`` (a caller with a rule of its own: ``legbench check``'s summaries), it is not inside
    a run directory (:func:`enclosing_run`: a run's run.json or log replaced by it was lost).

    Raises:
        LegbenchError: one line naming ``what``, the path and the problem.
        OSError, RuntimeError: a path that cannot be (a name too long, a loop of links).
    """
    path = Path(path)
    if path.is_symlink():
        raise LegbenchError(f"{what} {path}: a symbolic link (to {os.readlink(path)}); legbench would replace the "
                            "link, not write through it: give the file itself, or another name")  # fmt: skip
    if path.is_dir():
        raise LegbenchError(f"{what} {path}: is a directory, not a file")
    if path.exists() and not path.is_file():
        raise LegbenchError(f"{what} {path}: is {_kind(path)}, not a regular file; choose another file")
    if not path.parent.is_dir():
        raise LegbenchError(f"{what} {path}: no such folder {path.parent}")
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise LegbenchError(f"{what} {path}: {path.parent} is not writable")
    _check_temp_names(path, what)
    parent = None if in_run_ok else enclosing_run(path)
    if parent is not None:
        raise LegbenchError(f"{what} {path}: inside the run directory {parent}, which holds one run; choose another "
                            "file")  # fmt: skip
    return path


# --------------------------------------------------------------------------- #
# Writing a run directory


def run_label(name: str, profile: str, contact_mode: str) -> str:
    """A run's label, its directory's name in a results tree: the scenario's ``name``, with ``__<profile>`` for a
    profile other than ``matched`` and ``__reference`` in reference contact mode
    (``effort__engine-defaults__reference``); metrics.json's ``scenario``, and what ``legbench check`` pairs."""
    name = _profiled(name, profile)
    return name if contact_mode == "native" else f"{name}__reference"


def out_dir_for(root: Path, scenario: Scenario, contact_mode: str | None) -> Path:
    """Directory of one scenario in a results tree: <root>/<its run label> (:func:`run_label`)."""
    return Path(root) / run_label(scenario.name, scenario.profile, contact_mode or scenario.contact_mode)


def _previous(out_dir: Path) -> dict[str, Any] | None:
    """The run.json already in ``out_dir`` (empty if unreadable), or None."""
    try:
        return read_meta(out_dir)
    except ResultsError:
        return {} if (out_dir / "run.json").is_file() else None


#: What legbench puts in a run directory besides its backends' logs: run.json, the report (metrics.json, its
#: pages, their assets, the figures of earlier versions) and a regression check's default summaries.
RUN_FILES = ("run.json", "metrics.json", "report.md", "report.html", "assets", "figures", *CHECK_OUTPUTS)


def _foreign_in_run(out_dir: Path, prev: Mapping[str, Any]) -> str | None:
    """The first entry of the run directory ``out_dir`` (its run.json ``prev``) that legbench did not put there:
    not one of :data:`RUN_FILES`, a log (``.parquet``, ``.csv``) of a backend run.json lists, or a temporary of an
    earlier write. A run is written whole into a new directory swapped in place of the old one
    (:func:`atomic_dir`), so whatever else is there would be lost with it."""
    listed: Mapping[str, Any] = prev["backends"] if isinstance(prev.get("backends"), Mapping) else {}
    logs = {f"{n}{ext}" for n in listed for ext in (".parquet", ".csv")}
    logs |= {str(b["file"]) for b in listed.values() if isinstance(b, Mapping) and isinstance(b.get("file"), str)}
    for p in sorted(out_dir.iterdir()):
        if p.name not in RUN_FILES and p.name not in logs and not _TEMP_RE.match(p.name):
            return p.name
    return None


def check_out_dir(scenario: Scenario, out_dir: Path, option: str = "--out") -> None:
    """Refuse an output directory holding another scenario's results (or anything else: a run directory holding
    files legbench does not put in one, :func:`_foreign_in_run`, whatever ``--force`` says, since the run replaces
    the whole directory); the message says to choose another ``option`` (what the caller named the directory
    with: the Python API's ``out``)."""
    out_dir = Path(out_dir)
    prev = _previous(out_dir)
    if prev is None:
        first = min((p.name for p in out_dir.iterdir()), default=None) if out_dir.exists() else None
        if first is not None:
            raise LegbenchError(f"{out_dir}: not empty and not a legbench run directory (it holds {first}); choose "
                                f"another {option}")  # fmt: skip
        return
    name = (prev.get("scenario") or {}).get("name") if isinstance(prev.get("scenario"), Mapping) else None
    if name is None:
        raise LegbenchError(f"{out_dir}: its run.json is unreadable or corrupt (not written by legbench); "
                            f"choose another {option} or remove it")  # fmt: skip
    if name != scenario.name:
        raise LegbenchError(f"{out_dir}: holds results of scenario {name!r}, not {scenario.name!r}; choose another "
                            f"{option} or remove it")  # fmt: skip
    foreign = _foreign_in_run(out_dir, prev)
    if foreign is not None:
        raise LegbenchError(f"{out_dir}: not only a legbench run directory (it holds {foreign}), and a run replaces "
                            f"the whole directory; move it away, or choose another {option}")  # fmt: skip


def _same_settings(prev: Mapping[str, Any], scenario: Scenario, contact_mode: str | None) -> bool:
    """A run.json of the same scenario (its hash) in the same contact mode, of the leg model active now (its
    ``urdf``, where it names one: another ``--model`` is another leg): one a run of it resumes."""
    sc = prev.get("scenario") or {}
    return bool(
        sc.get("sha256") == scenario.sha256
        and sc.get("contact_mode") == (contact_mode or scenario.contact_mode)
        and prev.get("urdf", resources.urdf_name()) == resources.urdf_name()
    )


def resumable(scenario: Scenario, out_dir: Path, contact_mode: str | None) -> dict[str, Any]:
    """Entries of backends already finished in an interrupted run of the same scenario (same hash and mode)."""
    prev = _previous(Path(out_dir))
    if not prev or prev.get("complete", True) or not _same_settings(prev, scenario, contact_mode):
        return {}
    return {name: e for name, e in prev.get("backends", {}).items() if e.get("status") == "ok"}


def comparison_pending(
    scenario: Scenario, out_dir: Path, contact_mode: str | None, backends: Collection[str], csv: bool = False
) -> bool:
    """Whether ``out_dir`` holds a finished run (run.json without ``"complete": false``) of the same settings
    (:func:`_same_settings`) on exactly ``backends``, with their CSV logs too where ``csv`` asks for them, whose
    comparison was never written (no metrics.json): what a
    Ctrl-C after the last backend finished and before the comparison leaves. A rerun of the same ``legbench run``
    command compares it (as ``legbench compare`` would) and runs nothing; :func:`replaced_by_run` still calls it
    a finished run, for every other caller."""
    out_dir = Path(out_dir)
    prev = _previous(out_dir)
    return bool(
        prev
        and prev.get("complete", True) is not False
        and _same_settings(prev, scenario, contact_mode)
        and set(prev["backends"]) == set(backends)
        and not (out_dir / "metrics.json").exists()
        and not (csv and any(not (out_dir / f"{n}.csv").is_file() for n in backends))
    )


def replaced_by_run(
    scenario: Scenario, out_dir: Path, contact_mode: str | None, backends: Collection[str] | None = None
) -> str | None:
    """What of ``out_dir`` a run of ``scenario`` in ``contact_mode`` on ``backends`` would replace rather than
    resume, in words, or None: a finished run (run.json without ``"complete": false``), an interrupted run of other
    settings (another scenario hash or contact mode), or, ``backends`` given, an interrupted run holding the log
    of a backend not among them (finished or cut short: it would be dropped). An interrupted run of the same
    settings on no other logged backends is resumed (:func:`resumable`), even with no backend finished yet."""
    prev = _previous(Path(out_dir))
    if prev is None:
        return None
    if not prev:  # unreadable: check_out_dir refuses it; anything else is not ours to replace
        return "a run"
    if prev.get("complete", True) is not False:
        return "a finished run"
    if not _same_settings(prev, scenario, contact_mode):
        return "an interrupted run of other settings (it resumes only with the same scenario and options)"
    logged = {n for n, e in (prev.get("backends") or {}).items()  # a backend not run has no log to lose
              if isinstance(e, dict) and (Path(out_dir) / _log_name(n, e)).is_file()}  # fmt: skip
    others = sorted(logged - set(backends)) if backends is not None else []
    if others:
        return (
            f"an interrupted run of other backends too ({', '.join(others)}: it resumes only with them among "
            "the backends)"
        )
    return None


def write_log(tr: RunResult, path: Path) -> None:
    """A run's log as Parquet, :data:`PARQUET_ROW_GROUP` rows at a time: the writer holds one row group's
    columns and their encoding, not a copy of the whole log (a stacked array, a DataFrame and Arrow's
    conversion of it were 6.5x the log above the run's own memory)."""
    n = len(tr.t)
    first = tr.arrow_table(0, min(n, PARQUET_ROW_GROUP))
    with pq.ParquetWriter(path, first.schema) as writer:
        writer.write_table(first)
        del first
        for start in range(PARQUET_ROW_GROUP, n, PARQUET_ROW_GROUP):
            writer.write_table(tr.arrow_table(start, start + PARQUET_ROW_GROUP))


def write_run(scenario: Scenario, results: Sequence[RunResult], out_dir: Path, csv: bool = False,
              contact_mode: str | None = None, kept: dict[str, Any] | None = None) -> Path:  # fmt: skip
    """Write <backend>.parquet (and .csv) and run.json into ``out_dir``, atomically.

    Everything goes to a temporary sibling directory first, which replaces
    ``out_dir`` only when complete. ``kept`` are entries of backends finished in
    an earlier, interrupted run into the same directory; their files are carried
    over. ``run.json["complete"]`` is false when a backend was interrupted.
    """
    out_dir = Path(out_dir)
    check_out_dir(scenario, out_dir)
    meta_backends: dict[str, Any] = {}
    with atomic_dir(out_dir) as tmp:
        for name, old_entry in (kept or {}).items():
            for suffix in (".parquet", ".csv"):
                if (out_dir / f"{name}{suffix}").exists():
                    shutil.copy2(out_dir / f"{name}{suffix}", tmp / f"{name}{suffix}")
            meta_backends[name] = old_entry
        for tr in results:
            entry: dict[str, Any] = {"status": tr.status, "reason": tr.reason, "info": tr.info,
                                     "wall_time": tr.wall_time, "file": None, "rtf": None,
                                     "failed_at": None}  # fmt: skip
            if len(tr.t):
                write_log(tr, tmp / f"{tr.backend}.parquet")
                if csv:
                    tr.frame().to_csv(tmp / f"{tr.backend}.csv", index=False)
                entry["file"] = f"{tr.backend}.parquet"
                sim_time = float(tr.t[-1])
                entry["rtf"] = sim_time / tr.wall_time if tr.wall_time > 0 else None
                entry["failed_at"] = sim_time if tr.status != "ok" else None
            meta_backends[tr.backend] = entry
        sdict = scenario.to_dict()
        if contact_mode:
            sdict["contact_mode"] = contact_mode
        vers = versions()
        meta = {
            "complete": all(e["status"] != "interrupted" for e in meta_backends.values()),
            "scenario": sdict,
            "backends": meta_backends,
            "versions": vers,
            "platform": platform_info(),
            "written": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),  # UTC
            "legbench_version": vers.get("legbench", "unknown"),
            "urdf": resources.urdf_name(),  # the model active now (--model selects it after import)
            "leg": leg_model(),
        }
        write_json(meta, tmp / "run.json")
    return out_dir


def write_metrics(doc: Mapping[str, Any], path: str | Path) -> Path:
    """Write a metrics.json document (:meth:`legbench.compare.ComparisonResult.to_json`) and return its path.

    The header keys are indented, one metrics row per line (diff-friendly); the
    document is plain JSON (NaN written as null).
    """
    return atomic_write_text(Path(path), metrics_text(doc))


def log_digests(run_dir: str | Path) -> dict[str, str]:
    """SHA-256 of each backend log (``*.parquet``) of a run directory, by file name: what its metrics.json
    was computed from (``logs`` in metrics.json; :func:`legbench.check.check` measures the logs again when
    they no longer match, whatever the files' times say). Hashing a run's logs takes about 1 ms per MB."""
    logs = sorted(p for p in Path(run_dir).glob("*.parquet") if p.is_file())
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in logs}


def metrics_text(doc: Mapping[str, Any]) -> str:
    """The text :func:`write_metrics` writes for a metrics.json document.

    Raises:
        ValueError: a non-finite number in the document (NaN belongs in the rows, as null).
    """
    doc = dict(doc)
    rows = doc.pop("metrics")
    head = json.dumps(doc, indent=1, allow_nan=False)
    body = ",\n  ".join(json.dumps(r, allow_nan=False) for r in rows)
    return f'{head[:-2]},\n "metrics": [\n  {body}\n ]\n}}\n' if rows else f'{head[:-2]},\n "metrics": []\n}}\n'


# --------------------------------------------------------------------------- #
# Reading


@dataclass(frozen=True)
class BackendStatus:
    """A backend's entry of run.json.

    Attributes:
        name: backend name.
        status: one of :data:`STATUSES`: ``"ok"``, ``"failed"``, ``"missing"`` or ``"interrupted"``.
        reason: why it failed or is missing (None when ok).
        info: engine, version and settings as the backend reported them.
        wall_time: wall-clock time of the run [s] (NaN if unknown).
        rtf: real-time factor, simulated time / wall time (NaN if unknown).
        file: its parquet file name, relative to the run directory.
    """

    name: str
    status: str
    reason: str | None
    info: Mapping[str, Any] = field(default_factory=dict, hash=False)
    wall_time: float = math.nan
    rtf: float = math.nan
    file: str = ""


@dataclass(frozen=True)
class EventMark:
    """A controller switch at ``t`` [s] (for vertical lines in plots)."""

    t: float
    controller: str


@dataclass(frozen=True, eq=False)
class Run:
    """A run directory read into memory.

    Attributes:
        path: the directory.
        meta: run.json as read.
        name: scenario name.
        label: the run's label (:func:`run_label`: ``effort``, ``effort__reference``,
            ``effort__engine-defaults``), the ``scenario`` column of the metrics table.
        contact_mode: ``"native"`` or ``"reference"``.
        poc: point of contact of the analytic law, ``"true"`` or ``"centre"``.
        reference: the scenario's reference backend.
        skip: start time excluded from the deviation metrics [s].
        steady_window: final window of the steady-state means [s].
        duration: scenario duration [s].
        events: controller switches.
        backends: every backend of run.json, by name, in file order.
        traces: results of the backends whose status is ok.
        partial: results of failed backends whose file exists (plotted, not measured).
    """

    path: Path
    meta: Mapping[str, Any]
    name: str
    label: str
    contact_mode: str
    poc: str
    reference: str
    skip: float
    steady_window: float
    duration: float
    events: tuple[EventMark, ...]
    backends: Mapping[str, BackendStatus]
    traces: Mapping[str, RunResult]
    partial: Mapping[str, RunResult] = field(default_factory=dict)

    @property
    def tolerances(self) -> Mapping[str, Any]:
        """``scenario.comparison.tolerances`` of run.json (empty if absent)."""
        return tolerances_of(self.meta)

    @property
    def gravity(self) -> float:
        """``scenario.gravity`` of run.json [m/s^2], the gravity the backends simulated along -z_W (the leg
        parameter file's where run.json has none)."""
        g = (self.meta.get("scenario") or {}).get("gravity")
        return float(g) if isinstance(g, int | float) and not isinstance(g, bool) else load_params().gravity

    @property
    def profile(self) -> str:
        """``scenario.profile`` of run.json (:func:`profile_of`)."""
        return profile_of(self.meta)

    @property
    def control_dt(self) -> float:
        """The control period [s], 1 / ``scenario.control_rate`` of run.json: the logs' sample spacing (NaN where
        run.json gives no rate)."""
        return 1.0 / float((self.meta.get("scenario") or {}).get("control_rate") or math.nan)


def tolerances_of(meta: Mapping[str, Any]) -> Mapping[str, Any]:
    """``scenario.comparison.tolerances`` of a run.json document (empty if absent)."""
    tol = ((meta.get("scenario") or {}).get("comparison") or {}).get("tolerances") or {}
    return tol if isinstance(tol, Mapping) else {}


def profile_of(meta: Mapping[str, Any]) -> str:
    """``scenario.profile`` of a run.json document (``matched`` where absent: a run of an earlier legbench)."""
    return str((meta.get("scenario") or {}).get("profile") or registry.PROFILES[0])


def _read_json(path: Path) -> dict[str, Any]:
    """A JSON object from ``path``; every way it can be unreadable is one :class:`ResultsError` line."""
    try:
        doc = json.loads(path.read_bytes().decode("utf-8"))
    except json.JSONDecodeError as exc:
        raise ResultsError(str(path), f"invalid JSON at line {exc.lineno}: {exc.msg}") from exc
    except UnicodeDecodeError as exc:
        raise ResultsError(str(path), f"not UTF-8 text (byte {exc.start}): corrupt") from exc
    except IsADirectoryError as exc:
        raise ResultsError(str(path), "is a directory, not a JSON file") from exc
    except OSError as exc:
        raise ResultsError(str(path), f"cannot read: {exc.strerror or exc}") from exc
    except RecursionError as exc:
        raise ResultsError(str(path), "nested too deep") from exc
    if not isinstance(doc, dict):
        raise ResultsError(str(path), "top level is not a JSON object")
    return doc


def _get(doc: Mapping[str, Any], keys: str, file: Path, default: Any = ...) -> Any:
    cur: Any = doc
    for k in keys.split("."):
        if not isinstance(cur, Mapping) or k not in cur:
            if default is not ...:
                return default
            raise ResultsError(str(file), f"missing key '{keys}'")
        cur = cur[k]
    return cur


def _float_or_nan(v: Any) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


#: Statuses a backend can have in run.json and metrics.json (:class:`RunResult`).
STATUSES = ("ok", "failed", "missing", "interrupted")
_CONTACT_KEYS = tuple(f.name for f in fields(ContactParams))


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _number_at(doc: Mapping[str, Any], key: str, path: str, file: Path, default: float, *,
               positive: bool = False, below: float = math.inf, below_what: str = "") -> float:  # fmt: skip
    """``doc[key]`` (``default`` when absent or null): a finite number >= 0 (> 0 with ``positive``), and
    below ``below`` if given; anything else is a :class:`ResultsError` naming ``path``."""
    v = doc.get(key)
    if v is None:
        return default
    if not _is_number(v) or not math.isfinite(v) or v < 0 or (positive and v == 0):
        raise ResultsError(str(file), f"must be a finite number {'>' if positive else '>='} 0, not {v!r}", path)
    if v >= below:
        raise ResultsError(str(file), f"{v!r} s is not shorter than {below_what} ({below:g} s)", path)
    return float(v)


def _mapping_at(doc: Mapping[str, Any], key: str, path: str, file: Path) -> Mapping[str, Any]:
    """``doc[key]`` as an object (empty when absent or null); anything else is a :class:`ResultsError`."""
    v = doc.get(key)
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise ResultsError(str(file), f"must be an object, not {type(v).__name__} {v!r:.40}", path)
    return v


def _string_at(doc: Mapping[str, Any], key: str, path: str, file: Path, choices: Sequence[str] = ()) -> None:
    v = doc.get(key)
    if v is not None and (not isinstance(v, str) or (choices and v not in choices)):
        want = f"one of {list(choices)}" if choices else "a string"
        raise ResultsError(str(file), f"must be {want}, not {v!r:.40}", path)


def _check_backends(doc: Mapping[str, Any], file: Path) -> None:
    """``backends``: an object of name -> object with a known ``status``, a text or null ``reason`` (an imported
    log's ``sha256``: 64 hex digits)."""
    if doc.get("backends") is None:
        raise ResultsError(str(file), "missing key 'backends'" if "backends" not in doc else "must be an object, "
                           "not null", "" if "backends" not in doc else "backends")  # fmt: skip
    bdoc = _mapping_at(doc, "backends", "backends", file)
    for name, b in bdoc.items():
        key = f"backends.{name}"
        if not isinstance(b, Mapping):
            raise ResultsError(str(file), f"must be an object, not {type(b).__name__} {b!r:.40}", key)
        if "status" not in b:
            raise ResultsError(str(file), "missing key 'status'", key)
        if b["status"] not in STATUSES:
            raise ResultsError(str(file), f"must be one of {list(STATUSES)}, not {b['status']!r:.40}", f"{key}.status")
        _string_at(b, "reason", f"{key}.reason", file)
        _string_at(b, "file", f"{key}.file", file)
        _string_at(b, "source", f"{key}.source", file, ("run", "log"))
        _mapping_at(b, "info", f"{key}.info", file)
        sha = b.get("sha256")  # an imported log's recording (metrics.json)
        if sha is not None and not (isinstance(sha, str) and re.fullmatch(r"[0-9a-f]{64}", sha)):
            raise ResultsError(str(file), f"must be a SHA-256 (64 hex digits), not {sha!r:.40}", f"{key}.sha256")


def _check_run_json(meta: Mapping[str, Any], rj: Path) -> None:
    """Check every run.json field a reader uses (load_run, check, the report, the run's resume), once.

    Raises:
        ResultsError: naming run.json, the dotted key and the problem (wrong type, not finite, out of range,
            an unknown backend status or contact mode).
    """
    if "scenario" not in meta:
        raise ResultsError(str(rj), "missing key 'scenario'")
    sc = _mapping_at(meta, "scenario", "scenario", rj)
    if "name" not in sc:
        raise ResultsError(str(rj), "missing key 'scenario.name'")
    if not isinstance(sc["name"], str) or not sc["name"]:
        raise ResultsError(str(rj), f"must be a non-empty string, not {sc['name']!r:.40}", "scenario.name")
    _string_at(sc, "profile", "scenario.profile", rj)
    _string_at(sc, "contact_mode", "scenario.contact_mode", rj, ("native", "reference"))
    duration = _number_at(sc, "duration", "scenario.duration", rj, math.inf, positive=True)
    _number_at(sc, "control_rate", "scenario.control_rate", rj, 1.0, positive=True)
    _number_at(sc, "gravity", "scenario.gravity", rj, 0.0)  # true or "3.71" became the leg file's 9.81, silently
    events = sc.get("events")
    if events is not None and not isinstance(events, list):
        raise ResultsError(str(rj), f"must be a list of events, not {type(events).__name__} {events!r:.40}",
                           "scenario.events")  # fmt: skip
    for i, e in enumerate(events or ()):
        key = f"scenario.events[{i}]"
        if not isinstance(e, Mapping):
            raise ResultsError(str(rj), f"must be an object, not {type(e).__name__} {e!r:.40}", key)
        _number_at(e, "t", f"{key}.t", rj, 0.0)
        _number_at(e, "delay", f"{key}.delay", rj, 0.0)
        _string_at(e, "controller", f"{key}.controller", rj)
    contact = _mapping_at(sc, "contact", "scenario.contact", rj)
    for k in contact:
        if k not in _CONTACT_KEYS:
            raise ResultsError(str(rj), f"unknown contact parameter; valid: {list(_CONTACT_KEYS)}",
                               f"scenario.contact.{k}")  # fmt: skip
        if k == "poc":
            _string_at(contact, k, "scenario.contact.poc", rj, ("true", "centre"))
        else:
            _number_at(contact, k, f"scenario.contact.{k}", rj, 0.0)
    cmp_ = _mapping_at(sc, "comparison", "scenario.comparison", rj)
    _string_at(cmp_, "reference", "scenario.comparison.reference", rj)
    _number_at(cmp_, "skip", "scenario.comparison.skip", rj, 0.0, below=duration, below_what="the run")
    window = _number_at(cmp_, "steady_window", "scenario.comparison.steady_window", rj, 0.5, positive=True)
    if window > duration:
        raise ResultsError(str(rj), f"{window!r} s is longer than the run ({duration:g} s)",
                           "scenario.comparison.steady_window")  # fmt: skip
    _mapping_at(cmp_, "tolerances", "scenario.comparison.tolerances", rj)
    published = cmp_.get("published")
    if published is not None and not isinstance(published, list):
        raise ResultsError(str(rj), "must be a list of objects", "scenario.comparison.published")
    for i, row in enumerate(published or ()):
        key = f"scenario.comparison.published[{i}]"
        if not isinstance(row, Mapping) or "source" not in row:
            raise ResultsError(str(rj), "must be an object with a 'source'", key)
        for k in ("qd_abs", "force"):
            v = row.get(k)
            if v is not None and (not isinstance(v, list) or len(v) != 3 or not all(_is_number(x) for x in v)):
                raise ResultsError(str(rj), f"must be a list of 3 numbers, not {v!r:.40}", f"{key}.{k}")
    _check_backends(meta, rj)
    for bname, b in meta["backends"].items():
        _check_log_name(b.get("file"), f"backends.{bname}.file", rj)


def _check_log_name(name: Any, key: str, rj: Path) -> None:
    """A backend's ``file`` in run.json (a string or null: :func:`_check_backends`) is a plain file name inside the
    run directory: no folder in it, not absolute, not ``.`` or ``..``. A hand-edited ``../../other/x.parquet`` or
    ``/etc/passwd`` was followed by :func:`load_run`, which read (and measured) a file outside the run."""
    if not isinstance(name, str) or not name:
        return  # null or "": the default <backend>.parquet
    seps = {"/", "\\", os.sep, *((os.altsep,) if os.altsep else ())}
    if name in (".", "..") or "\0" in name or any(s in name for s in seps) or Path(name).is_absolute():
        raise ResultsError(str(rj), f"must be a plain file name inside the run directory, not {name!r:.60}", key)


def read_meta(run_dir: str | Path) -> dict[str, Any]:
    """A run directory's run.json, checked (:func:`_check_run_json`): every field a reader uses has its type
    and range, so a hand-edited or corrupt file is one :class:`ResultsError` line naming the key.

    Raises:
        ResultsError: the directory or run.json is missing, or run.json is malformed or foreign.
    """
    path = Path(run_dir)
    if not path.is_dir():
        raise ResultsError(str(path), "no such run directory")
    rj = path / "run.json"
    if not rj.is_file():
        raise ResultsError(str(path), "no run.json here: not a legbench run directory")
    meta = _read_json(rj)
    _check_run_json(meta, rj)
    return meta


def run_dirs(root: str | Path) -> dict[str, Path]:
    """Run directories of a results tree by name (subdirectories with run.json or metrics.json, sorted).

    A run directory itself maps ``""`` to itself.

    Raises:
        ResultsError: ``root`` is missing or holds no run directory.
    """
    root = Path(root)
    if not root.is_dir():
        raise ResultsError(str(root), "no such results directory")
    if (root / "run.json").is_file() or (root / "metrics.json").is_file():
        return {"": root}
    dirs = {p.name: p for p in sorted(root.iterdir()) if (p / "run.json").is_file() or (p / "metrics.json").is_file()}
    if not dirs:
        raise ResultsError(str(root), "no run directories (with run.json or metrics.json) here")
    return dirs


def _log_name(backend: str, entry: Mapping[str, Any]) -> str:
    """The file of ``backend``'s log in its run directory: its run.json entry's ``file``, else ``<backend>.parquet``."""
    return str(entry.get("file") or f"{backend}.parquet")


def _missing_log(path: Path, fname: str) -> str:
    return f"run.json says ok but {fname} is not in {path}"


@dataclass(frozen=True)
class RunProblems:
    """What the run directories under a root say went wrong, one line per item, from their run.json alone
    (:func:`run_problems`).

    Attributes:
        missing: ``<backend> missing: why`` for each log of a backend run.json says ran ok that is not there, as
            :func:`load_run` reports it (that backend left out of the comparison; the why names the directory).
        incomplete: each run an interrupt left unfinished (run.json's ``"complete": false``), naming the directory
            and its interrupted backends.
        failed: ``<run directory name>/<backend>`` of each backend that failed (diverged or raised), as
            ``legbench run`` names them.
    """

    missing: list[str]
    incomplete: list[str]
    failed: list[str]


def run_problems(root: str | Path) -> RunProblems:
    """The :class:`RunProblems` of the run directories under ``root`` (or ``root`` itself), each run.json read once.

    Raises:
        ResultsError: as :func:`run_dirs` and :func:`read_meta`.
    """
    out = RunProblems([], [], [])
    for d in run_dirs(root).values():
        if not (d / "run.json").is_file():
            continue
        meta = read_meta(d)
        for bname, b in meta["backends"].items():
            fname = _log_name(bname, b)
            if str(b["status"]) == "ok" and not (d / fname).exists():
                out.missing.append(f"{bname} missing: {_missing_log(d, fname)}")
            elif str(b["status"]) == "failed":
                out.failed.append(f"{d.name}/{bname}")
        if meta.get("complete", True) is False:
            cut = sorted(b for b, e in meta["backends"].items() if str(e["status"]) == "interrupted")
            out.incomplete.append(f"{resources.shown(d)}: an interrupted run ({', '.join(cut)} not finished), "
                                  "compared as far as it went; rerun the command that wrote it to finish "
                                  "it")  # fmt: skip
    return out


def read_log(path: str | Path) -> pd.DataFrame:
    """A backend's parquet log as written (every column, the controller names included).

    Raises:
        ResultsError: the file is missing or not readable parquet.
    """
    path = Path(path)
    if not path.is_file():
        raise ResultsError(str(path), "no such file")
    try:
        return pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises several unrelated types
        raise ResultsError(str(path), f"not a readable parquet file ({type(exc).__name__}: {exc})") from exc


def result_from_frame(df: pd.DataFrame, name: str, source: str = "<frame>",
                      required: Sequence[str] = ("t",), allow_nan: bool = True) -> RunResult:  # fmt: skip
    """A :class:`RunResult` from a DataFrame with (some of) :data:`~legbench.signals.RUN_COLUMNS`.

    Signals absent from the frame are NaN; the foot centre is taken as logged (NaN if absent). An infinite
    value is refused in every column (no leg logs one, and the metrics would turn it into numpy warnings and
    NaN). A column that is NaN throughout is a signal not logged (as if absent: no figure, metrics n/a); NaN
    in some rows only is refused unless ``allow_nan`` (an imported log's missing sample, such as a ROS bag's
    ground force outside the wrench topic's span; the run loop never logs one, so in a run's log it is damage).

    Raises:
        ResultsError: a ``required`` column missing, a value not numeric, an infinite value, NaN in ``t`` or
            (without ``allow_nan``) in some rows of a column, ``t`` not strictly increasing, or fewer than 2
            rows; naming the column, the row and its time.
    """
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise ResultsError(source, f"missing column(s) {missing}; columns present: {list(df.columns)}")
    n = len(df)
    if n < 2:
        raise ResultsError(source, f"has {n} row(s); at least 2 are needed")

    def block(cols: Sequence[str], t: np.ndarray | None = None, nan_ok: bool = allow_nan) -> np.ndarray:
        out = np.full((n, len(cols)), np.nan)
        for i, c in enumerate(cols):
            if c in df.columns:
                try:
                    out[:, i] = pd.to_numeric(df[c], errors="raise").to_numpy(dtype=float, na_value=np.nan)
                except (ValueError, TypeError) as exc:
                    raise ResultsError(source, f"column '{c}' is not numeric ({exc})") from exc
                nan = np.isnan(out[:, i])
                bad = np.isinf(out[:, i]) if nan_ok or nan.all() else ~np.isfinite(out[:, i])
                if bad.any():
                    k = int(np.argmax(bad))
                    when = f" (t = {float(t[k]):g} s)" if t is not None else ""
                    what = f"column '{c}' holds {float(out[k, i])} at data row {k + 1}{when}"  # counted from 1
                    raise ResultsError(source, f"{what} ({int(bad.sum())} such value(s)): a log must hold finite "
                                               "numbers")  # fmt: skip
        return out

    t = block(["t"], nan_ok=False)[:, 0]
    if np.isnan(t).any():
        raise ResultsError(source, "column 't' has non-finite values")
    steps = np.diff(t)
    if (steps <= 0).any():
        i = int(np.argmax(steps <= 0))
        raise ResultsError(source, f"time is not strictly increasing at data row {i + 2} (t = {float(t[i + 1]):.9g} s "
                                   f"after {float(t[i]):.9g} s)")  # fmt: skip
    ctrl = (
        df["controller"].astype(str).to_numpy(dtype=object)
        if "controller" in df.columns
        else np.full(n, "", dtype=object)
    )
    data = block(LABELS, t)
    return RunResult(name, t, data[:, 0:3], data[:, 3:6], data[:, 6:9], data[:, 9:12], ctrl, source=source,
                     foot=block(EE_COLUMNS, t))  # fmt: skip


def load_trace(path: str | Path, name: str | None = None, allow_nan: bool = False) -> RunResult:
    """Read one backend's parquet log (every column of :data:`~legbench.signals.RUN_COLUMNS` required,
    every value finite or a column NaN throughout, a signal not logged: the run loop logs only checked,
    finite states; ``allow_nan`` for a failed backend's partial log, which is only plotted).

    Raises:
        ResultsError: the file is missing, unreadable, lacks a column or holds a non-finite value.
    """
    path = Path(path)
    df = read_log(path)
    return result_from_frame(df, name or path.stem, str(path), [c for c in RUN_COLUMNS if c != "controller"],
                             allow_nan)  # fmt: skip


def _check_span(tr: RunResult, duration: float, rate: float, file: Path, rj: Path) -> None:
    """An ok backend's log covers the scenario, t = 0 .. duration (half a control period either way)."""
    if not math.isfinite(duration):
        return  # a run.json without scenario.duration (older or foreign): nothing to hold the log to
    tol = 0.5 / rate if math.isfinite(rate) and rate > 0 else 1e-9 * max(duration, 1.0)
    if tr.t[0] > tol or tr.t[-1] < duration - tol:
        raise ResultsError(str(file), f"column 't' spans {tr.t[0]:g} .. {tr.t[-1]:g} s ({len(tr.t)} rows), not the "
                                      f"scenario's 0 .. {duration:g} s, though {rj} says {tr.backend} is ok: the log "
                                      "is cut short")  # fmt: skip


def load_run(run_dir: str | Path) -> Run:
    """Read a run directory (run.json and one parquet per backend whose status is ok).

    A backend listed as ok whose file is absent is reported as ``missing`` (compare notes it, check fails it);
    a failed backend's file, if present, is kept in :attr:`Run.partial`. A log that *is* there for a backend
    listed as ok must be whole: every column, finite values, and t spanning the scenario's 0 .. duration
    (to half a control period). One that is not (cut short by a full disk or a copy, a NaN or inf written into
    it) is not a failed backend run.json could report, but a damaged file: a :class:`ResultsError` naming the
    file and the column, rather than metrics computed silently over what is left of it.

    Raises:
        ResultsError: the directory or run.json is missing or malformed, or an ok backend's parquet file is
            unreadable, lacks a column, holds a non-finite value or is shorter than the scenario.
    """
    path = Path(run_dir)
    meta = read_meta(path)
    rj = path / "run.json"
    sc = _get(meta, "scenario", rj)
    name = str(_get(sc, "name", rj))
    mode = str(sc.get("contact_mode") or "native")
    cmp_ = sc.get("comparison") or {}
    duration, rate = float(sc.get("duration") or math.nan), float(sc.get("control_rate") or math.nan)
    events = tuple(  # at the switch: t plus the event's delay, if any
        EventMark(float(e.get("t") or 0.0) + float(e.get("delay") or 0.0), str(e.get("controller") or ""))
        for e in (sc.get("events") or [])
    )
    backends: dict[str, BackendStatus] = {}
    traces: dict[str, RunResult] = {}
    partial: dict[str, RunResult] = {}
    for bname, b in meta["backends"].items():
        status, reason = str(b["status"]), b.get("reason")
        fname = _log_name(bname, b)
        fpath = path / fname
        if status == "ok" and fpath.exists() and not fpath.is_file():  # a folder or a device: not a log to read
            raise ResultsError(str(fpath), f"is {_kind(fpath)}, not a backend log (run.json says {bname} ran ok)")
        if status == "ok" and not fpath.is_file():
            status, reason = "missing", _missing_log(path, fname)
        if status == "ok":
            traces[bname] = load_trace(fpath, bname)
            _check_span(traces[bname], duration, rate, fpath, rj)
        elif fpath.is_file():
            try:
                partial[bname] = load_trace(fpath, bname, allow_nan=True)
            except ResultsError as exc:
                logger.info("partial log of %s not readable: %s", bname, exc)
        backends[bname] = BackendStatus(
            name=bname,
            status=status,
            reason=None if reason is None else str(reason),
            info=dict(b.get("info") or {}),
            wall_time=_float_or_nan(b.get("wall_time")),
            rtf=_float_or_nan(b.get("rtf")),
            file=fname,
        )
    return Run(
        path=path,
        meta=meta,
        name=name,
        label=run_label(name, profile_of(meta), mode),
        contact_mode=mode,
        poc=str((sc.get("contact") or {}).get("poc") or "true"),
        reference=str(cmp_.get("reference") or DEFAULT_REFERENCE),
        skip=float(cmp_.get("skip") or 0.0),
        steady_window=float(cmp_.get("steady_window") or 0.5),
        duration=duration,
        events=events,
        backends=backends,
        traces=traces,
        partial=partial,
    )


def read_study(path: str | Path, key: str) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """A study's JSON document (verification.json, calibration.json, bench.json): (header, rows).

    Args:
        path: the study's JSON file.
        key: the key of its rows (``checks``, ``rows``, ``results``).

    Raises:
        ResultsError: missing or unreadable file, or ``key`` is not a list of objects.
    """
    path = Path(path)
    if not path.is_file():
        raise ResultsError(str(path), "no such study output")
    doc = _read_json(path)
    rows = doc.pop(key, None)
    if not isinstance(rows, list) or any(not isinstance(r, dict) for r in rows):
        raise ResultsError(str(path), f"'{key}' must be a list of objects")
    return doc, rows


def checks_summary(statuses: Sequence[str]) -> str:
    """``"110 of 117 checks pass, 1 fail, 6 not applicable"`` from each check's status (``pass``, ``fail``,
    ``not-applicable``; a verification study's rows), the parts that are zero left out."""
    failed, na = sum(s == "fail" for s in statuses), sum(s == "not-applicable" for s in statuses)
    text = f"{sum(s == 'pass' for s in statuses)} of {len(statuses)} checks pass"
    return text + (f", {failed} fail" if failed else "") + (f", {na} not applicable" if na else "")


def read_metrics(path: str | Path) -> tuple[dict[str, Any], pd.DataFrame]:
    """Read a metrics.json: (header without the rows, long table with NaN for null).

    The header fields its readers use are checked like run.json's: ``scenario``, ``name``, ``reference``
    text, ``contact_mode`` native or reference, ``backends`` an object of name -> {status (one of
    :data:`STATUSES`), reason, source}. Each row's ``value`` is a finite number or null (:func:`metrics_text`
    writes nothing else; a text, a list or a non-finite number was read as n/a, which a check passes as "new"),
    and no two rows share their key columns (which of them counted was an accident of the table's order).

    Raises:
        ResultsError: missing file, wrong schema, a malformed header field (naming its key) or malformed rows
            (naming ``metrics[i]`` and the bad value or the row it repeats).
    """
    path = Path(path)
    if not path.is_file():
        raise ResultsError(str(path), "no such metrics file")
    doc = _read_json(path)
    if doc.get("schema") != METRICS_SCHEMA:
        raise ResultsError(str(path), f"schema is {doc.get('schema')!r}, expected {METRICS_SCHEMA!r}")
    for key in ("scenario", "name", "reference"):
        _string_at(doc, key, key, path)
    _string_at(doc, "contact_mode", "contact_mode", path, ("native", "reference"))
    _check_backends(doc, path)
    logs = doc.get("logs")
    if logs is not None and (
        not isinstance(logs, dict)
        or not all(
            isinstance(k, str) and isinstance(v, str) and re.fullmatch(r"[0-9a-f]{64}", v) for k, v in logs.items()
        )
    ):
        raise ResultsError(str(path), "must be an object of log file name -> SHA-256 (64 hex digits)", "logs")
    rows = doc.pop("metrics", None)
    if not isinstance(rows, list) or any(not isinstance(r, dict) or set(r) != set(FRAME_COLUMNS) for r in rows):
        raise ResultsError(str(path), f"'metrics' must be a list of objects with keys {list(FRAME_COLUMNS)}")
    seen: dict[tuple[str, ...], int] = {}
    for i, r in enumerate(rows):
        v, row = r["value"], tuple(str(r[c]) for c in FRAME_COLUMNS[:-1])
        if v is not None and not (_is_number(v) and math.isfinite(v)):  # "corrupt", [1], "NaN", NaN, Infinity
            raise ResultsError(str(path), f"must be a finite number or null (n/a), not {v!r:.40} (row "
                                          f"{'/'.join(row)})", f"metrics[{i}].value")  # fmt: skip
        if row in seen:
            raise ResultsError(str(path), f"the same row as metrics[{seen[row]}] ({'/'.join(row)}): a metric is given "
                                          "once", f"metrics[{i}]")  # fmt: skip
        seen[row] = i
    df = pd.DataFrame(rows, columns=list(FRAME_COLUMNS))
    df["value"] = pd.to_numeric(df["value"], errors="coerce").astype(float)
    for c in FRAME_COLUMNS[:-1]:
        df[c] = df[c].astype(str)
    return doc, df
