"""The wheel: built from the tree, installed into a fresh venv, every subcommand run from another directory.

The venv is made with ``--system-site-packages`` and a ``.pth`` line naming this interpreter's site-packages, so the
engines come from the shared environment while legbench itself comes from the wheel (checked: ``legbench.__file__``
is inside the new venv). Durations are cut with ``--set`` / ``--duration`` and one fast backend runs.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow


def _copy_tracked(dest: Path) -> None:
    """The files git tracks (as in the working tree, symbolic links kept), or the whole tree without a git checkout."""
    try:
        files = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        shutil.copytree(ROOT, dest, symlinks=True, ignore=shutil.ignore_patterns(".venv", "results", "build", ".git"))
        return
    for rel in filter(None, files.decode().split("\0")):
        src, dst = ROOT / rel, dest / rel
        if not os.path.lexists(src):
            continue  # deleted in the working tree
        dst.parent.mkdir(parents=True, exist_ok=True)
        if src.is_symlink():
            os.symlink(os.readlink(src), dst)
        else:
            shutil.copy2(src, dst)


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    _copy_tracked(src)
    dist = tmp / "dist"
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(dist), str(src)],
                           capture_output=True, text=True, check=False)  # fmt: skip
    assert build.returncode == 0, build.stderr[-3000:]
    (wheel,) = dist.glob("legbench-*.whl")
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    purelib = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "LEGBENCH_MODEL", "VIRTUAL_ENV")}
    inst = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "--quiet",
                           str(wheel)], capture_output=True, text=True, check=False, env=clean)  # fmt: skip
    assert inst.returncode == 0, inst.stderr[-3000:]
    # after the install: pip would take the shared environment's legbench for an installed one
    shared = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    # addsitedir, not a bare path line: the engines' own .pth files (pin's cmeel prefix) must be processed too
    lines = "".join(f"import site; site.addsitedir({p!r})\n" for p in sorted(shared))
    (Path(purelib) / "shared_env.pth").write_text(lines)
    cache = tmp / "cache"
    lagrange = Path.home() / ".cache" / "legbench" / "lagrange"
    if lagrange.is_dir():  # the lagrange backend's generated equations (sympy, slow): reuse them
        shutil.copytree(lagrange, cache / "lagrange")
    env = clean | {"LEGBENCH_CACHE_DIR": str(cache), "PATH": f"{venv / 'bin'}{os.pathsep}{clean.get('PATH', '')}"}
    work = tmp / "elsewhere"
    work.mkdir()
    return {"venv": venv, "py": py, "purelib": Path(purelib), "env": env, "work": work, "wheel": wheel,
            "cache": cache}  # fmt: skip


def _legbench(inst: dict[str, object], *args: str, ok: tuple[int, ...] = (0,)) -> str:
    exe = Path(str(inst["venv"])) / "bin" / "legbench"
    proc = subprocess.run([str(exe), *args], cwd=str(inst["work"]), env=inst["env"], capture_output=True, text=True,
                          timeout=900, check=False)  # type: ignore[call-overload]  # fmt: skip
    assert proc.returncode in ok, f"legbench {' '.join(args)}: exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    return str(proc.stdout)


def _py(inst: dict[str, object], code: str) -> str:
    proc = subprocess.run([str(inst["py"]), "-c", code], cwd=str(inst["work"]), env=inst["env"], capture_output=True,
                          text=True, check=True)  # type: ignore[call-overload]  # fmt: skip
    return str(proc.stdout).strip()


def test_wheel_holds_the_model_and_scenarios(installed: dict[str, object]) -> None:
    import zipfile

    names = set(zipfile.ZipFile(str(installed["wheel"])).namelist())
    data = "legbench/data/"
    # py.typed: a user's type checker reads legbench's annotations (PEP 561; without it mypy calls legbench untyped)
    expected = {f"{data}models/leg.yaml", f"{data}models/leg.urdf", f"{data}scenarios/effort.yaml",
                f"{data}scenarios/sweeps/gains.yaml", f"{data}scenarios/verification/energy.yaml",
                "legbench/py.typed"}  # fmt: skip
    assert expected <= names
    tracked = {p.relative_to(ROOT / "scenarios").as_posix() for p in (ROOT / "scenarios").rglob("*.yaml")}
    assert {n.removeprefix("legbench/data/scenarios/") for n in names if n.startswith("legbench/data/scenarios/")} == (
        tracked
    )


def test_every_subcommand_from_another_directory(installed: dict[str, object]) -> None:
    inst = installed
    where = _py(inst, "import legbench, legbench.resources as r; print(legbench.__file__); print(r.scenarios_dir())")
    pkg_file, scen = where.splitlines()
    assert Path(pkg_file).is_relative_to(Path(str(inst["venv"]))), pkg_file  # legbench from the wheel
    assert Path(scen).is_relative_to(Path(str(inst["purelib"])))
    s = Path(scen)
    assert _legbench(inst, "--version").startswith("legbench ")
    from legbench import kinematics

    x, y, z = kinematics.fk(np.zeros(3))  # the installed model is the tree's: the same foot position
    assert f"x = {x:.6f}, y = {y:.6f}, z = {z:.6f}" in _legbench(inst, "model", "fk", "0", "0", "0")
    assert "solution 2:" in _legbench(inst, "model", "ik", "0.1667", "0", "0.0225")
    _legbench(inst, "model", "gravity", "0", "-0.5", "-1", "--json")
    _legbench(inst, "model", "calibrate")
    _legbench(inst, "model", "check")
    shipped = Path(str(inst["purelib"])) / "legbench" / "data" / "models" / "leg.urdf"
    before = shipped.read_bytes()
    out = _legbench(inst, "model", "urdf")  # installed: written into the cache, never into site-packages
    assert str(inst["cache"]) in out and shipped.read_bytes() == before
    _legbench(inst, "validate", str(s / "effort.yaml"), str(s / "sweeps" / "gains.yaml"))
    short = ["--set", "duration=0.05", "--set", "comparison.steady_window=0.01"]
    out = _legbench(inst, "run", str(s / "effort.yaml"), "--backends", "pinocchio,mujoco", *short, "--out", "r", "-q")
    assert "pinocchio  ok" in out and (Path(str(inst["work"])) / "r" / "report.html").is_file()
    _legbench(inst, "compare", "r")
    shutil.copytree(Path(str(inst["work"])) / "r", Path(str(inst["work"])) / "r_baseline")
    assert "PASS" in _legbench(inst, "check", "r", "--baseline", "r_baseline")
    _legbench(inst, "doctor", str(s / "effort.yaml"), "--backends", "pinocchio,mujoco")
    sweep = Path(str(inst["work"])) / "tiny_sweep.yaml"
    sweep.write_text(
        f"name: tiny\nscenario: {s / 'verification' / 'free_space.yaml'}\n"
        "set: {duration: 0.05, comparison.steady_window: 0.01}\n"
        "studies:\n  - label: '{backend}'\n    backends: [mujoco]\n    grid: {gains: [{Kp: 5, Kd: 0.5}]}\n"
        "    reference: {backend: pinocchio}\n"
    )
    _legbench(inst, "sweep", str(sweep), "--out", "sw", "--jobs", "1")
    # exit 1 would be a failed physics check, which is not what this test is about; 2 or 3 would be packaging
    _legbench(inst, "verify", "--backends", "pinocchio", "--cases", "energy", "--out", "ver", ok=(0, 1))
    _legbench(inst, "calibrate-contact", "--backends", "pinocchio", "--out", "cal")
    _legbench(inst, "bench", "--backends", "pinocchio", "--quick", "--duration", "0.05", "--no-memory", "--out", "b")
    _legbench(inst, "reproduce", "--duration", "0.05", "--backends", "pinocchio", "--out", "rep", "--no-report", "-q")
    assert "legbench" in _legbench(inst, "completion", "bash")
    # another leg model, by option and by environment variable, its URDF in the cache
    model = Path(str(inst["work"])) / "my_leg.yaml"
    model.write_text((Path(str(inst["purelib"])) / "legbench" / "data" / "models" / "leg.yaml").read_text())
    out = _legbench(inst, "--model", str(model), "run", str(s / "position.yaml"), "--backends", "pinocchio", *short,
                    "--out", "m", "-q", "--no-compare")  # fmt: skip
    assert list((Path(str(inst["cache"])) / "urdf").glob("my_leg-*.urdf"))
