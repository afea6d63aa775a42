"""numba for legbench's compiled kernels, with an on-disk cache that knows what a kernel is built from.

A kernel (the run loop's tick, :mod:`legbench.tick`; the Pinocchio backend's control period) is plain
Python compiled by numba, calling plain functions that live in other modules (the controllers' laws, the
contact law, the limit law): one implementation, run as Python by the reference paths and compiled into
the kernels. numba's on-disk cache (``cache=True``) checks only the kernel's own source file, so an edit
of a law in another module would leave the old law compiled into a cached kernel. :func:`njit` records
the source files a kernel module depends on and folds their contents' SHA-256 into the stamp numba
checks (a cache locator placed ahead of numba's own, for those modules only): any change to any of them
recompiles.

Without numba every function here hands back the plain function: the kernels then run as Python (slow,
the same numbers).
"""

from __future__ import annotations

import hashlib
import inspect
from collections.abc import Callable, Iterable
from pathlib import Path
from types import ModuleType
from typing import Any, TypeVar

try:
    import numba
    from numba.core import caching
    from numba.extending import register_jitable
except ImportError:  # the kernels run as Python
    numba = None  # type: ignore[assignment]

F = TypeVar("F", bound=Callable[..., Any])

#: kernel source file -> the source files it is built from (besides itself)
_DEPENDS: dict[str, tuple[str, ...]] = {}


def available() -> bool:
    """numba is installed: :func:`njit` compiles."""
    return numba is not None


def sources_hash(files: Iterable[str]) -> str:
    """SHA-256 of the files' contents, in the order given [hex]."""
    h = hashlib.sha256()
    for f in files:
        h.update(Path(f).read_bytes())
    return h.hexdigest()


def jitable(*fns: Callable[..., Any]) -> None:
    """Let compiled code call these plain functions (numba's ``register_jitable``; they stay plain)."""
    if numba is not None:
        for fn in fns:
            register_jitable(fn)


def njit(fn: F, depends_on: Iterable[ModuleType | Callable[..., Any]] = ()) -> F:
    """``fn`` compiled (nopython, cached on disk, releasing the GIL), or ``fn`` itself without numba.

    Args:
        fn: a plain function of numbers and arrays.
        depends_on: the modules (or functions, by their module) whose plain functions ``fn``
            compiles in: their sources join the cache's stamp for ``fn``'s whole module.
    """
    if numba is None:
        return fn
    here = inspect.getfile(fn)
    files = {inspect.getfile(m) for m in depends_on} - {here}
    if files:
        _DEPENDS[here] = tuple(sorted(set(_DEPENDS.get(here, ())) | files))
    # without the stamp (a numba whose cache internals moved) a kernel with dependencies is not cached
    # at all: compiled afresh in every process rather than stale after an edit
    cache = _STAMPED or not files
    return numba.njit(cache=cache, nogil=True)(fn)  # type: ignore[return-value]


#: the dependency stamp is in place (numba's cache locators found where numba 0.68-0.69 keeps them)
_STAMPED = False

if numba is not None and all(
    hasattr(caching, n) for n in ("CacheImpl", "UserProvidedCacheLocator", "InTreeCacheLocator", "UserWideCacheLocator")
):

    class _DependencyStamp:
        """Mixin for numba's cache locators: the source stamp of a registered kernel module also holds
        the hash of the files it depends on (:data:`_DEPENDS`); other modules are left to numba's own."""

        _py_file: str

        def get_source_stamp(self) -> Any:
            own = super().get_source_stamp()  # type: ignore[misc]
            return (own, sources_hash(_DEPENDS[self._py_file]))

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if py_file not in _DEPENDS:
                return None
            return super().from_function(py_func, py_file)  # type: ignore[misc]

    class _UserProvided(_DependencyStamp, caching.UserProvidedCacheLocator):
        pass

    class _InTree(_DependencyStamp, caching.InTreeCacheLocator):
        pass

    class _UserWide(_DependencyStamp, caching.UserWideCacheLocator):
        pass

    # numba tries its locators in order: ours first, in numba's own order of preference
    _locators = getattr(caching.CacheImpl, "_locator_classes", None)
    if isinstance(_locators, list):
        _locators[0:0] = [_UserProvided, _InTree, _UserWide]
        _STAMPED = True
