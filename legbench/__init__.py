"""legbench: honest, fast comparison of physics engines on a 3-DOF quadruped leg.

Data flows ``scenario`` -> ``controllers`` -> ``backends`` -> ``run`` -> ``results`` (the run
directory) -> ``metrics`` / ``compare`` -> ``report`` (-> ``check``); the leg is ``model``
(parameters, URDF) and ``kinematics``; the studies are in ``legbench.studies``.
docs/architecture.md lists every module and what may import what.
"""

from importlib import metadata

try:
    __version__ = metadata.version("legbench")
except metadata.PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

__all__ = ["__version__"]
