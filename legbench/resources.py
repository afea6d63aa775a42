"""Where legbench's own files are: the bundled leg model and scenarios, the active model, derived files.

The leg model (``models/``) and the scenarios (``scenarios/``) ship inside the package as
``legbench/data/models`` and ``legbench/data/scenarios`` and are found with
:mod:`importlib.resources`; in a source checkout those two entries are symbolic links to the
top-level ``models/`` and ``scenarios/`` directories, so there is one copy of each file.

The *active* leg parameter file is, first to last: the one :func:`select_model` was given (the
CLI's global ``--model PATH``), the environment variable :data:`MODEL_ENV` (``LEGBENCH_MODEL``),
the bundled ``models/leg.yaml``. :func:`select_model` also sets the environment variable, so
worker processes (``--jobs N``) use the same model.

The URDF is derived from the parameter file. Every generated URDF carries a stamp in its header comment:
:func:`param_digest` of the parameter file it was generated from (the hash of the file's bytes and
:data:`URDF_FORMAT`). The bundled model's URDF is shipped next to it and read from there while its stamp is
the bundled ``leg.yaml``'s digest now; a source checkout (re)writes it in place (``legbench model urdf``,
:func:`urdf_destination`). Any other parameter file, and the bundled one when its ``leg.urdf`` is out of date
(``leg.yaml`` edited and not regenerated, or a ``leg.urdf`` with no stamp or another generator's), gets its URDF
generated into the cache directory (:func:`cache_dir`), named by that digest, so an installed package never
writes into site-packages and a run of an edited leg names another URDF than ``leg.urdf``.

A path an environment variable gives (``LEGBENCH_MODEL``, ``LEGBENCH_CACHE_DIR``, ``XDG_CACHE_HOME``) that cannot
be used (a ``~user`` with no such user, a loop of links, a cache that is a file or cannot be created) is a one-line
:class:`~legbench.exceptions.ModelError` naming the variable and its value, raised where it is resolved.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import logging
import os
import re
import stat
import tempfile
from importlib import resources
from pathlib import Path

__all__ = [
    "CACHE_ENV",
    "MODEL_ENV",
    "bundled_model",
    "bundled_urdf",
    "cache_dir",
    "cache_subdir",
    "data_dir",
    "env_path",
    "is_bundled",
    "model_file",
    "models_dir",
    "param_digest",
    "scenario",
    "scenarios_dir",
    "select_model",
    "shown",
    "source_tree",
    "urdf_destination",
    "urdf_file",
    "urdf_name",
    "urdf_stamp",
    "urdf_target",
]

#: Environment variable naming another leg parameter file (YAML, the format of ``models/leg.yaml``).
MODEL_ENV = "LEGBENCH_MODEL"
#: Environment variable naming the cache directory for derived files (generated URDFs).
CACHE_ENV = "LEGBENCH_CACHE_DIR"

logger = logging.getLogger("legbench.resources")


@functools.cache
def data_dir() -> Path:
    """The package's data directory (``legbench/data``) on disk [cached: the package does not move]."""
    return Path(str(resources.files("legbench") / "data"))


def shown(path: str | Path) -> str:
    """How outputs name a file: relative to the working directory when it lies inside it, a bundled file
    as ``legbench/data/...``, anything else as given; so no output carries this machine's checkout path.
    """
    p = Path(path)
    try:
        cwd, real, plain = Path.cwd().resolve(), p.resolve(), p.absolute()
    except (OSError, RuntimeError):  # RuntimeError: a loop of symbolic links (Python 3.11)
        return str(path)
    for file, base, prefix in ((real, cwd, ""), (plain, data_dir(), "legbench/data/")):
        if file.is_relative_to(base):
            return prefix + str(file.relative_to(base))
    return str(path)


def models_dir() -> Path:
    """The bundled model directory (``leg.yaml``, ``leg.urdf``)."""
    return data_dir() / "models"


def scenarios_dir() -> Path:
    """The bundled scenario directory (the tasks, ``sweeps/``, ``verification/``)."""
    return data_dir() / "scenarios"


def scenario(name: str) -> Path:
    """A bundled scenario file by relative name, with or without ``.yaml`` (``"effort"``, ``"sweeps/gains"``)."""
    rel = name if name.endswith((".yaml", ".yml")) else f"{name}.yaml"
    return scenarios_dir() / rel


def bundled_model() -> Path:
    """The bundled leg parameter file."""
    return models_dir() / "leg.yaml"


def bundled_urdf() -> Path:
    """The URDF generated from the bundled parameter file, shipped beside it."""
    return models_dir() / "leg.urdf"


def source_tree() -> Path | None:
    """The checkout's root when legbench runs from a source tree (models/ is a writable directory there), else None."""
    root = Path(__file__).resolve().parent.parent
    if (root / "pyproject.toml").is_file() and (root / "models" / "leg.yaml").is_file():
        return root
    return None


def _error(message: str) -> Exception:
    """The one-line error for a path an environment variable (or the caller) gave that cannot be used: a
    :class:`legbench.exceptions.ModelError`, reached through :mod:`legbench.model` (this module's one upward
    import, docs/architecture.md), imported only when there is an error to raise."""
    from legbench import model  # deferred, as in urdf_file: model imports pinocchio

    return model.ModelError(message)


def _expanded(value: str, label: str) -> Path:
    """``value`` as a path with a leading ``~`` or ``~user`` expanded, as :meth:`pathlib.Path.expanduser`.

    Raises:
        ModelError: ``~user`` names no user, or ``~`` has no home directory (HOME unset and none in the password
            database), in one line beginning with ``label`` (``LEGBENCH_MODEL=~nouser/x.yaml``), instead of
            pathlib's ``RuntimeError: Could not determine home directory.``
    """
    try:
        return Path(value).expanduser()
    except RuntimeError:
        head = value.split("/", 1)[0]
        why = "no home directory (HOME is not set)" if head == "~" else "no such user"
        raise _error(f"{label}: cannot expand {head}: {why}") from None


def _resolved(path: Path, label: str) -> Path:
    """``path`` made absolute with its links resolved; a loop of links is a one-line ModelError beginning with
    ``label`` (Python 3.11 raises RuntimeError for it)."""
    try:
        return path.resolve()
    except RuntimeError:
        raise _error(f"{label}: a loop of symbolic links") from None
    except OSError as exc:
        raise _error(f"{label}: {exc.strerror or exc}") from None


def env_path(name: str) -> Path | None:
    """The path the environment variable ``name`` holds, ``~`` expanded; None when it is unset or empty.

    Raises:
        ModelError: the ``~`` cannot be expanded; one line naming the variable and its value
            (``LEGBENCH_MODEL=~nouser/x.yaml: cannot expand ~nouser: no such user``).
    """
    value = os.environ.get(name)
    return _expanded(value, f"{name}={value}") if value else None


_selected: Path | None = None


def select_model(path: str | Path | None) -> None:
    """Make ``path`` the active leg parameter file for this process and its workers (None: back to the default).

    Raises:
        ModelError: ``~`` in ``path`` cannot be expanded, or its links loop (one line naming ``path``).
    """
    global _selected
    if path is None:
        _selected = None
        os.environ.pop(MODEL_ENV, None)
        return
    _selected = _resolved(_expanded(str(path), str(path)), str(path))
    os.environ[MODEL_ENV] = str(_selected)


def model_file() -> Path:
    """The active leg parameter file (see the module docstring for the order).

    Raises:
        ModelError: ``LEGBENCH_MODEL``'s ``~`` cannot be expanded or its links loop, in one line naming the
            variable and its value.
    """
    if _selected is not None:
        return _selected
    env = env_path(MODEL_ENV)
    if env is not None:
        return _resolved(env, f"{MODEL_ENV}={os.environ[MODEL_ENV]}")
    return bundled_model()


def _cache_origin() -> tuple[Path, str]:
    """The cache directory and how an error names it: ``LEGBENCH_CACHE_DIR=<value>``, ``cache directory <path>
    (from XDG_CACHE_HOME=<value>)`` or ``cache directory <path>`` (the default under the home directory).

    Raises:
        ModelError: a ``~`` that cannot be expanded, or no home directory for the default (see :func:`cache_dir`).
    """
    env = env_path(CACHE_ENV)
    if env is not None:
        return env, f"{CACHE_ENV}={os.environ[CACHE_ENV]}"
    xdg = env_path("XDG_CACHE_HOME")
    if xdg is not None:
        path = xdg / "legbench"
        return path, f"cache directory {path} (from XDG_CACHE_HOME={os.environ['XDG_CACHE_HOME']})"
    default = _expanded("~", f"cache directory ~/.cache/legbench ({CACHE_ENV} chooses another)")
    path = default / ".cache" / "legbench"
    return path, f"cache directory {path}"


def _dir_problem(path: Path) -> str:
    """Why ``path`` cannot be a directory ('' if it is one, or if its nearest existing ancestor is one, so it can be
    created as far as can be told without creating it), without creating anything: a few ``stat`` calls."""
    try:
        if path.is_dir():
            return ""
        if path.exists():
            return "not a directory"
        if path.is_symlink():
            return "not a directory (a symbolic link to nothing)"
        for parent in path.parents:
            if parent.is_dir():
                return ""
            if parent.exists() or parent.is_symlink():
                return f"cannot be created: {parent} is not a directory"
    except OSError as exc:  # a name too long
        return f"cannot be used: {exc.strerror or exc}"
    return ""


def cache_dir() -> Path:
    """Derived files: ``$LEGBENCH_CACHE_DIR``, else ``$XDG_CACHE_HOME/legbench``, else ``~/.cache/legbench``.

    Nothing is created (:func:`cache_subdir` creates); a path that cannot be a directory is refused here, before
    any work, so a bad cache is one line naming where it came from, not each engine's failure to load.

    Raises:
        ModelError: in one line naming the variable and its value (``LEGBENCH_CACHE_DIR=/tmp/f: not a
            directory``): the path is a file or lies under one (``cannot be created: /tmp/f is not a
            directory``), a ``~`` in it cannot be expanded, or there is no home directory for the default.
    """
    path, origin = _cache_origin()
    problem = _dir_problem(path)
    if problem:
        raise _error(f"{origin}: {problem}")
    return path


def cache_subdir(name: str) -> Path:
    """The directory ``name`` (``urdf``) in :func:`cache_dir`, created with the cache directory if missing.

    Raises:
        ModelError: as :func:`cache_dir`, or either directory cannot be created (``LEGBENCH_CACHE_DIR=/proc/x:
            cannot be created: No such file or directory``), in one line naming the variable and its value.
    """
    root = cache_dir()
    origin = _cache_origin()[1]
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _error(f"{origin}: cannot be created: {exc.strerror or exc}") from None
    sub = root / name
    try:
        sub.mkdir(exist_ok=True)
    except FileExistsError:
        raise _error(f"{origin}: {sub}: not a directory") from None
    except OSError as exc:
        raise _error(f"{origin}: {sub}: cannot be created: {exc.strerror or exc}") from None
    return sub


def is_bundled(params: str | Path) -> bool:
    """Whether ``params`` is the bundled parameter file: the same file (device and inode, two ``stat`` calls, a
    few us where resolving both paths took 50 us), or, when either is missing, the same path once links are
    resolved."""
    try:
        return os.path.samefile(params, bundled_model())
    except OSError:
        pass
    try:
        return Path(params).resolve() == bundled_model().resolve()
    except (OSError, RuntimeError):  # RuntimeError: a loop of symbolic links (Python 3.11)
        return False


#: The version of the URDF text ``model.urdf_text`` writes, hashed into a cached URDF's name with the parameter
#: file, so a URDF cached by an earlier legbench is not reused once the generator writes something else
#: (2: numbers written exactly, ``repr``, no longer to 12 significant digits).
URDF_FORMAT = b"legbench-urdf-2\n"

#: How a generated URDF's header comment begins, up to its stamp (``model.urdf_text`` writes it as line 2, after
#: the XML declaration, so nothing the comment names later, such as a file name, comes before the stamp).
STAMP_PREFIX = "<!-- Generated by `legbench model urdf` (stamp sha256:"
_STAMP = re.compile(re.escape(STAMP_PREFIX.encode()) + rb"([0-9a-f]{16})[^0-9a-f]")
#: How much of a URDF :func:`urdf_stamp` reads: the XML declaration and the header comment.
_STAMP_HEAD = 512


def param_digest(params: str | Path) -> str:
    """The digest of the parameter file ``params``: the first 16 hex digits of sha256(:data:`URDF_FORMAT` + the
    file's bytes). It names the file's URDF in the cache (``urdf/<stem>-<digest>.urdf``) and is the stamp in the
    header of every URDF generated from a file (``model.urdf_text``).

    Raises:
        FileNotFoundError: no such file.
        ModelError: the file is not a regular file or is larger than ``limit("file_bytes")``; it is not read.
    """
    from legbench import model  # deferred, as in urdf_file: the reader comes through model (docs/architecture.md)

    return hashlib.sha256(URDF_FORMAT + model.param_bytes(Path(params))).hexdigest()[:16]


def urdf_stamp(urdf: str | Path) -> str | None:
    """The stamp in a generated URDF's header (the :func:`param_digest` of the parameter file it was generated
    from), read from its first 512 bytes; None when it has none (written by a legbench before the stamp, by
    hand, for parameters not read from a file) or cannot be read (missing, not a regular file)."""
    try:
        fd = os.open(urdf, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # a FIFO there must not block
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                return None
            head = fh.read(_STAMP_HEAD)
    except OSError:
        return None
    m = _STAMP.search(head)
    return m.group(1).decode("ascii") if m else None


#: Digests of edited bundled parameter files already warned of in this process (one warning per content).
_warned: set[str] = set()


def _warn_stale(digest: str, name: str) -> None:
    """Say once per process and content that the bundled leg.urdf is not the bundled leg.yaml's (one line)."""
    import multiprocessing  # deferred: only an out-of-date leg.urdf gets here, and the CLI's start-up stays light

    if digest in _warned or multiprocessing.parent_process() is not None:  # once, and not again from each worker
        return
    _warned.add(digest)
    checkout = source_tree() is not None
    urdf, params = (
        ("models/leg.urdf", "models/leg.yaml") if checkout else (shown(bundled_urdf()), shown(bundled_model()))
    )
    state = (
        f"is out of date with {params} (not stamped with that file's current content)"
        if bundled_urdf().is_file()
        else f"is missing beside {params}"
    )
    advice = "; `legbench model urdf` (make urdf) regenerates it" if checkout else ""
    logger.warning(
        "legbench: warning: %s %s: engines load urdf/%s, generated from %s into the cache directory, instead%s",
        urdf,
        state,
        name,
        params,
        advice,
    )


def _bundled_is_current(path: Path) -> tuple[bool, str]:
    """Whether ``path`` is the bundled parameter file and the shipped ``leg.urdf``'s stamp is its digest now; and
    the file's digest (``missing`` if there is no such file). Reads the parameter file and the URDF's first bytes.

    Raises:
        ModelError: the parameter file is not a regular file or is too large (see :func:`param_digest`).
    """
    try:
        digest = param_digest(path)
    except FileNotFoundError:  # the URDF's name says so; reading it as YAML says why
        digest = "missing"
    if not is_bundled(path):
        return False, digest
    current = urdf_stamp(bundled_urdf()) == digest
    if not current and digest != "missing":
        _warn_stale(digest, _cached_name(path, digest))
    return current, digest


def _cached_name(path: Path, digest: str) -> str:
    return f"{path.stem}-{digest}.urdf"


def _cached(path: Path, digest: str) -> Path:
    return cache_dir() / "urdf" / _cached_name(path, digest)


def urdf_name(params: str | Path | None = None) -> str:
    """The file name of :func:`urdf_target` (``leg.urdf``, or ``<stem>-<param_digest>.urdf``), what run.json
    records and a report compares: found without the cache directory, so a cache that cannot be used does not
    stop a run that never needed it (the bundled leg) at its end, nor a comparison.

    Raises:
        ModelError: as :func:`urdf_target`, the cache directory aside.
    """
    path = Path(params) if params is not None else model_file()
    current, digest = _bundled_is_current(path)
    return "leg.urdf" if current else _cached_name(path, digest)


def urdf_target(params: str | Path | None = None) -> Path:
    """Where the URDF of ``params`` (default: the active model) lives or is to be written.

    The bundled model's URDF, while its stamp is the bundled parameter file's :func:`param_digest` (see
    :func:`urdf_file`): in a source checkout ``models/leg.urdf``; installed, the shipped file for reading and the
    cache's ``urdf/leg.urdf`` for writing. Any other model, and the bundled one when its ``leg.urdf`` is out of
    date (a one-line warning says so, once per process): the cache, ``urdf/<stem>-<param_digest>.urdf``
    (``<stem>-missing.urdf`` if there is no such file), so run.json names an edited bundled leg
    ``leg-<digest>.urdf``, not ``leg.urdf``. :func:`urdf_destination` is where ``legbench model urdf`` writes.

    Costs one read of the parameter file (a few kB) and, for the bundled one, of the URDF's first 512 bytes;
    nothing is cached, so an edit is seen at the next call.

    Raises:
        ModelError: the parameter file is not a regular file (a device, a FIFO, a directory) or is larger than
            ``limit("file_bytes")``; it is not read. A URDF in the cache: the cache directory cannot be one
            (:func:`cache_dir`).
    """
    path = Path(params) if params is not None else model_file()
    current, digest = _bundled_is_current(path)
    if current:
        root = source_tree()
        return root / "models" / "leg.urdf" if root is not None else cache_dir() / "urdf" / "leg.urdf"
    return _cached(path, digest)


def urdf_destination(params: str | Path | None = None) -> Path:
    """Where ``legbench model urdf`` writes the URDF of ``params`` (default: the active model) when given no
    ``--out``: for the bundled model in a source checkout ``models/leg.urdf`` whatever its stamp says (writing it
    is how it is brought up to date), else :func:`urdf_target`.

    Raises:
        ModelError: as :func:`urdf_target`.
    """
    path = Path(params) if params is not None else model_file()
    root = source_tree()
    if root is not None and is_bundled(path):
        return root / "models" / "leg.urdf"
    return urdf_target(path)


#: How every URDF legbench writes ends (``model.urdf_text``): a cached one that does not end so is incomplete.
URDF_END = b"</robot>\n"


def _complete(urdf: Path) -> bool:
    """``urdf`` is a file that ends as a whole generated URDF does (:data:`URDF_END`; its last bytes only)."""
    try:
        with urdf.open("rb") as fh:
            fh.seek(0, os.SEEK_END)
            size = fh.tell()
            if size < len(URDF_END):
                return False
            fh.seek(size - len(URDF_END))
            return fh.read() == URDF_END
    except OSError:  # missing, or not a file
        return False


def urdf_file(params: str | Path | None = None) -> Path:
    """The URDF of ``params`` (default: the active model), generated into the cache on first use if needed.

    The bundled model's shipped ``leg.urdf`` only while its stamp is the bundled ``leg.yaml``'s
    :func:`param_digest` now; otherwise (``leg.yaml`` edited and not regenerated, a ``leg.urdf`` with no stamp or
    another generator's) the bundled parameters are treated as any other file's: ``urdf/leg-<digest>.urdf`` in
    the cache (see :func:`urdf_target`); a cached URDF cut short (not ending as :data:`URDF_END`) is generated
    again. Each call reads the parameter file and the URDF's first and last bytes again.

    Raises:
        ModelError: the parameter file is missing or malformed; or the cache directory cannot be used, in one line
            naming the variable that chose it and its value (:func:`cache_dir`, :func:`cache_subdir`).
    """
    path = Path(params) if params is not None else model_file()
    current, digest = _bundled_is_current(path)
    if current:
        return bundled_urdf()
    target = _cached(path, digest)
    if not _complete(target):  # missing, or cut short (a full disk, a hand edit): generated again
        from legbench import model  # deferred: model imports pinocchio

        leg = model.read_params(path)
        if leg.digest is not None and leg.digest != digest:  # edited between the two reads: name it by what it holds
            target = _cached(path, leg.digest)
        text = model.urdf_text(leg)
        directory = cache_subdir("urdf")  # target's directory; a cache that cannot be made is one line
        try:
            fd, tmp = tempfile.mkstemp(dir=directory, prefix=target.name, suffix=".tmp")  # unique: workers race
        except OSError as exc:  # a read-only file system
            raise _error(f"{_cache_origin()[1]}: cannot write in it: {exc.strerror or exc}") from None
        try:
            with os.fdopen(fd, "w") as fh:
                fh.write(text)
            os.replace(tmp, target)
        except BaseException:  # a full disk, an interrupt: no half-written temporary left behind
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
    return target
