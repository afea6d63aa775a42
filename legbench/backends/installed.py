"""Importing this module imports every backend that can run here (the registry's :func:`available`).

It exists for the process pool (:mod:`legbench.studies.executors`): its preload names modules, and the
fork server imports them once before it forks the workers, so each engine is imported once per pool
instead of once per worker. Nothing raised here escapes: a backend that fails to import is reported
by the registry when a run asks for it.
"""

from __future__ import annotations

import logging

from legbench import backends

__all__ = ["NAMES"]

try:
    NAMES: tuple[str, ...] = tuple(backends.available())
except Exception as exc:  # a broken engine must not stop the fork server; the run that needs it says why
    logging.getLogger("legbench.backends").debug("preloading the engines failed: %s", exc)
    NAMES = ()
