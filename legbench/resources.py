"""Where legbench's own files are: the bundled leg model and scenarios, the active model, derived files.

The leg model (``models/``) and the scenarios (``scenarios/``) ship inside the package as
``legbench/data/models`` and ``legbench/data/scenarios`` and are found with
:mod:`importlib.resources`; in a source checkout those two entries are symbolic links to the
top-level ``models/`` and ``scenarios/`` directories, so there is one copy of each file.

The *active* leg parameter file is, first to last: the one :func:`select_model` was given (the
CLI's global ``--model PATH``), the environment variable :data:`MODEL_ENV` (``LEGBENCH_MODEL``),
the bundled ``models/leg.yaml``. :func:`select_model` also sets the environment variable, so
worker processes (``--jobs N``) use the same model.

The URDF is derived from the parameter file. The bundled model's URDF is shipped next to it and
read from there; a source checkout (re)writes it in place (``legbench model urdf``). Any other
parameter file gets its URDF generated into the cache directory (:func:`cache_dir`), named by the
hash of its content, so an installed package never writes into site-packages.
"""

from __future__ import annotations

import functools
import hashlib
import os
import tempfile
from importlib import resources
from pathlib import Path

__all__ = [
    "CACHE_ENV",
    "MODEL_ENV",
    "bundled_model",
    "bundled_urdf",
    "cache_dir",
    "data_dir",
    "model_file",
    "models_dir",
    "scenario",
    "scenarios_dir",
    "select_model",
    "shown",
    "source_tree",
    "urdf_file",
    "urdf_target",
]

#: Environment variable naming another leg parameter file (YAML, the format of ``models/leg.yaml``).
MODEL_ENV = "LEGBENCH_MODEL"
#: Environment variable naming the cache directory for derived files (generated URDFs).
CACHE_ENV = "LEGBENCH_CACHE_DIR"


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
    except OSError:
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


_selected: Path | None = None


def select_model(path: str | Path | None) -> None:
    """Make ``path`` the active leg parameter file for this process and its workers (None: back to the default)."""
    global _selected
    if path is None:
        _selected = None
        os.environ.pop(MODEL_ENV, None)
        return
    _selected = Path(path).expanduser().resolve()
    os.environ[MODEL_ENV] = str(_selected)


def model_file() -> Path:
    """The active leg parameter file (see the module docstring for the order)."""
    if _selected is not None:
        return _selected
    env = os.environ.get(MODEL_ENV)
    if env:
        return Path(env).expanduser().resolve()
    return bundled_model()


def cache_dir() -> Path:
    """Derived files: ``$LEGBENCH_CACHE_DIR``, else ``$XDG_CACHE_HOME/legbench``, else ``~/.cache/legbench``."""
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg).expanduser() if xdg else Path.home() / ".cache") / "legbench"


def _is_bundled(params: Path) -> bool:
    try:
        return params.resolve() == bundled_model().resolve()
    except OSError:
        return False


#: The version of the URDF text ``model.urdf_text`` writes, hashed into a cached URDF's name with the parameter
#: file, so a URDF cached by an earlier legbench is not reused once the generator writes something else
#: (2: numbers written exactly, ``repr``, no longer to 12 significant digits).
URDF_FORMAT = b"legbench-urdf-2\n"


def urdf_target(params: str | Path | None = None) -> Path:
    """Where the URDF of ``params`` (default: the active model) lives or is to be written.

    The bundled model's URDF in a source checkout: ``models/leg.urdf``; installed: the shipped file
    for reading, and the cache for writing (see :func:`urdf_file`). Any other model: the cache,
    ``urdf/<stem>-<hash of the parameter file and URDF_FORMAT>.urdf`` (``<stem>-missing.urdf`` if there is no
    such file).

    Raises:
        ModelError: the parameter file is not a regular file (a device, a FIFO, a directory) or is larger than
            ``limit("file_bytes")``; it is not read.
    """
    path = Path(params) if params is not None else model_file()
    if _is_bundled(path):
        root = source_tree()
        return root / "models" / "leg.urdf" if root is not None else cache_dir() / "urdf" / "leg.urdf"
    from legbench import model  # deferred, as in urdf_file: the reader comes through model (docs/architecture.md)

    try:
        digest = hashlib.sha256(URDF_FORMAT + model.param_bytes(path)).hexdigest()[:16]
    except FileNotFoundError:  # the URDF's name says so; reading it as YAML says why
        digest = "missing"
    return cache_dir() / "urdf" / f"{path.stem}-{digest}.urdf"


def urdf_file(params: str | Path | None = None) -> Path:
    """The URDF of ``params`` (default: the active model), generated into the cache on first use if needed.

    Raises:
        ModelError: the parameter file is missing or malformed.
    """
    path = Path(params) if params is not None else model_file()
    if _is_bundled(path) and bundled_urdf().is_file():
        return bundled_urdf()
    target = urdf_target(path)
    if not target.is_file():
        from legbench import model  # deferred: model imports pinocchio

        text = model.urdf_text(model.load_params(path))
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=target.name, suffix=".tmp")  # unique: workers race
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, target)
    return target
