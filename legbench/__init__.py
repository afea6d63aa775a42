"""legbench: honest, fast comparison of physics engines on a 3-DOF quadruped leg.

Data flows ``scenario`` -> ``controllers`` -> ``backends`` -> ``run`` -> ``results`` (the run
directory) -> ``metrics`` / ``compare`` -> ``report`` (-> ``check``); the leg is ``model``
(parameters, URDF) and ``kinematics``; the studies are in ``legbench.studies``.
docs/architecture.md lists every module and what may import what.

The Python API (:mod:`legbench.api`, imported on first use so ``import legbench`` stays fast)::

    import legbench
    res = legbench.run_scenario("effort", backends=["pinocchio", "mujoco"], overrides={"duration": 0.5})
    res.frames["mujoco"], res.compare().summary(), res.report("out")
    legbench.open_run("results/latest/effort")  # a run directory already on disk, as the same Result
"""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from legbench.api import Comparison, Result, load_scenario, open_run, run_scenario

    __version__: str

__all__ = ["Comparison", "Result", "__version__", "load_scenario", "open_run", "run_scenario"]

_API = {"Comparison", "Result", "load_scenario", "open_run", "run_scenario"}


def __getattr__(name: str) -> Any:
    """The API names, imported from :mod:`legbench.api` when first asked for (it imports numpy, pandas, the engines'
    registry): ``import legbench`` alone imports nothing heavy."""
    if name == "__version__":  # importlib.metadata costs more than the rest of ``import legbench``
        from importlib import metadata

        try:
            version = metadata.version("legbench")
        except metadata.PackageNotFoundError:  # running from a source tree that is not installed
            version = "0+unknown"
        globals()["__version__"] = version
        return version
    if name in _API:
        from legbench import api

        return getattr(api, name)
    raise AttributeError(f"module 'legbench' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | _API | {"__version__"})
