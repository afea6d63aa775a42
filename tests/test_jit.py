"""The compiled kernels' on-disk cache follows the sources a kernel is built from, not only its own file."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from legbench import jit

pytestmark = pytest.mark.skipif(not jit.available(), reason="numba is not installed")

KERNEL = """
from legbench import jit
from kpkg import law
from kpkg.law import step

jit.jitable(step)


def twice(x):
    return step(x) * 2.0


kernel = jit.njit(twice, depends_on=(law,))
"""

PLAIN = """
import numba
import kpkg.kernel  # registers step with numba
from kpkg.law import step


def twice(x):
    return step(x) * 2.0


plain = numba.njit(cache=True)(twice)  # numba's own cache: keyed on this file only
"""

PROBE = """
import json
from kpkg.kernel import kernel
from kpkg.plain import plain
print(json.dumps({"kernel": kernel(1.0), "plain": plain(1.0), "hits": sum(kernel.stats.cache_hits.values())}))
"""


def _probe(root: Path) -> dict[str, float]:
    # no .pyc: Python checks a cached one by the source's size and whole-second mtime, so an edit of the same
    # size within the second it was written would run the old bytecode (what the test edits is the source)
    env = {**os.environ, "PYTHONPATH": f"{root}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
           "NUMBA_CACHE_DIR": str(root / "cache"), "PYTHONDONTWRITEBYTECODE": "1"}  # fmt: skip
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def test_an_edit_of_a_law_in_another_module_recompiles_the_cached_kernel(tmp_path: Path) -> None:
    """kernel(x) = 2 step(x), step in another file: after step changes from x + 1 to x + 2, the cached
    kernel gives 2 (1 + 2) = 6, where numba's own cache (keyed on the kernel's file) still gives the stale 4;
    unchanged sources load from the cache."""
    pkg = tmp_path / "kpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    law = pkg / "law.py"
    law.write_text("def step(x):\n    return x + 1.0\n")
    (pkg / "kernel.py").write_text(textwrap.dedent(KERNEL))
    (pkg / "plain.py").write_text(textwrap.dedent(PLAIN))
    first = _probe(tmp_path)
    assert (first["kernel"], first["plain"]) == (4.0, 4.0)
    again = _probe(tmp_path)
    assert again["hits"] >= 1 and again["kernel"] == 4.0  # compiled once, then loaded
    law.write_text("def step(x):\n    return x + 2.0\n")
    edited = _probe(tmp_path)
    assert edited["kernel"] == 6.0
    assert edited["plain"] == 4.0  # what the dependency stamp is for: numba alone keeps the old law


def test_the_run_loops_tick_and_the_pinocchio_period_declare_their_sources() -> None:
    """Both compiled kernels are stamped with the modules whose plain functions they compile in (and the stamp
    is in place with the pinned numba: without it such kernels would be compiled uncached in every process)."""
    assert jit._STAMPED
    from legbench import contact, controllers, kinematics, tick
    from legbench.backends import joint_limits, pinocchio_kernel

    deps = {Path(k).name: {Path(f).name for f in v} for k, v in jit._DEPENDS.items()}
    assert {Path(controllers.__file__).name, Path(kinematics.__file__).name} <= deps[Path(tick.__file__).name]
    assert {Path(contact.__file__).name, Path(joint_limits.__file__).name} <= deps[Path(pinocchio_kernel.__file__).name]
