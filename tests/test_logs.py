"""External logs: ROS 1 bags, ROS 2 sqlite3 and MCAP bags written by rosbags' own writers, read back into the run
columns, and compared from the command line."""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from fakerun import scale, write_run

from legbench import cli, logs
from legbench.exceptions import LegbenchError, ResultsError
from legbench.signals import EE_COLUMNS, LABELS, RUN_COLUMNS

rosbags = pytest.importorskip("rosbags", reason="pip install 'legbench[ros]'")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

T_BAG0_NS = 1_700_000_000_250_000_000  # bag time of legbench's t = 0 [ns]: a hardware clock, far from 0
KINDS = ("ros1", "sqlite3", "mcap")


def _writer(kind: str, path: Path):  # type: ignore[no-untyped-def]
    if kind == "ros1":
        ts = get_typestore(Stores.ROS1_NOETIC)
        return ts, Writer1(path), ts.serialize_ros1, {}
    ts = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.SQLITE3 if kind == "sqlite3" else StoragePlugin.MCAP
    return ts, Writer2(path, version=9, storage_plugin=plugin), ts.serialize_cdr, {}


def write_bag(
    kind: str,
    path: Path,
    t: np.ndarray,
    data: np.ndarray,
    names: tuple[str, ...],
    order: tuple[int, ...],
    force_t: np.ndarray | None = None,
    force: np.ndarray | None = None,
    joint_topic: str = "/leg/joint_states",
    wrench_topic: str = "/leg/foot_force",
    extra_joint_topic: str | None = None,
    joint_stamp0_ns: int = T_BAG0_NS,
    wrench_stamped: bool = True,
    force_recorded: np.ndarray | None = None,
) -> Path:
    """A bag of JointState messages at times t [s from T_BAG0_NS] carrying data[:, 0:9] (q, qd, tau of joints 1..3)
    under ``names`` (message slot i holds legbench joint order[i]; a slot with order -1 is another joint, 0.5 rad),
    and WrenchStamped messages of ``force`` at ``force_t``. Header stamps count from ``joint_stamp0_ns`` for the
    joint states (another clock, e.g. simulation time, when not T_BAG0_NS) and T_BAG0_NS for the wrench (zero
    without ``wrench_stamped``); recording times from T_BAG0_NS, 3 ms after the time (for the wrench, 3 ms after
    ``force_recorded`` [s] where given: the order the messages are written in)."""
    ts, writer, ser, _ = _writer(kind, path)
    JointState = ts.types["sensor_msgs/msg/JointState"]
    Wrench = ts.types["geometry_msgs/msg/WrenchStamped"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    Vector3 = ts.types["geometry_msgs/msg/Vector3"]
    WrenchBody = ts.types["geometry_msgs/msg/Wrench"]

    def header(tt: float, k: int, ns0: int | None = T_BAG0_NS) -> object:
        ns = 0 if ns0 is None else ns0 + round(tt * 1e9)
        stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        return Header(seq=k, stamp=stamp, frame_id="world") if kind == "ros1" else Header(stamp=stamp, frame_id="world")

    def pick(row: np.ndarray, block: int) -> np.ndarray:
        return np.array([row[3 * block + j] if j >= 0 else 0.5 for j in order], dtype=np.float64)

    with writer:
        jc = writer.add_connection(joint_topic, JointState.__msgtype__, typestore=ts)
        ec = None
        if extra_joint_topic:
            ec = writer.add_connection(extra_joint_topic, JointState.__msgtype__, typestore=ts)
        wc = writer.add_connection(wrench_topic, Wrench.__msgtype__, typestore=ts) if force is not None else None
        events: list[tuple[float, int, object, object]] = []
        for k, (tt, row) in enumerate(zip(t, data, strict=True)):
            msg = JointState(header=header(tt, k, joint_stamp0_ns), name=list(names), position=pick(row, 0),
                             velocity=pick(row, 1), effort=pick(row, 2))  # fmt: skip
            events.append((tt, 0, jc, msg))
            if ec is not None:
                events.append((tt, 1, ec, msg))
        if force is not None and force_t is not None:
            rec_t = force_t if force_recorded is None else force_recorded
            for k, (tt, rt, f) in enumerate(zip(force_t, rec_t, force, strict=True)):
                w = WrenchBody(force=Vector3(x=f[0], y=f[1], z=f[2]), torque=Vector3(x=0.0, y=0.0, z=0.0))
                events.append(
                    (rt, 2, wc, Wrench(header=header(tt, k, T_BAG0_NS if wrench_stamped else None), wrench=w))
                )
        for tt, _, conn, msg in sorted(events, key=lambda e: (e[0], e[1])):
            rec = T_BAG0_NS + round((tt + 0.003) * 1e9)  # recorded 3 ms after the stamp: stamps must win
            writer.write(conn, rec, ser(msg, msg.__msgtype__))  # type: ignore[attr-defined]
    return path


def _bag_path(tmp_path: Path, kind: str) -> Path:
    return tmp_path / ("run.bag" if kind == "ros1" else f"run_{kind}")


def _signals(t: np.ndarray) -> np.ndarray:
    """Smooth q [rad], qd [rad/s], tau [N m] of three joints, shape (N, 9)."""
    w = 2 * np.pi
    return np.column_stack([a * np.sin(w * f * t + p) for a, f, p in
                            [(0.1, 0.5, 0), (0.3, 1, 0.3), (0.2, 1.5, 1), (0.5, 0.5, 0), (1, 1, 0), (2, 1.5, 0),
                             (1, 1, 0), (2, 0.7, 0), (1.5, 2, 0)]])  # fmt: skip


@pytest.mark.parametrize("kind", KINDS)
def test_bag_round_trip(tmp_path: Path, kind: str) -> None:
    """JointState at 1 kHz (names in another order than legbench's, a fourth joint among them) and WrenchStamped at
    500 Hz offset by 0.3 ms: q, qd, tau come back exactly (float64 through the serialisation) in legbench's joint
    order, t starts at 0 from the header stamps (not the recording times, 3 ms later), and the force, linear in t,
    is interpolated onto the joint-state ticks to 1e-9 N (rounding only); outside the wrench samples it is NaN."""
    t = np.arange(0, 0.2, 1e-3)
    data = _signals(t)
    ft = np.arange(0.0003, 0.2, 2e-3)
    force = np.column_stack([1.0 + 2.0 * ft, -3.0 * ft, 20.0 + 50.0 * ft])
    names = ("knee", "extra", "hip_aa", "hip_fe")
    bag = write_bag(kind, _bag_path(tmp_path, kind), t, data, names, (2, -1, 0, 1), ft, force)
    df = logs.load_log(bag, {"hip_aa": "q1", "hip_fe": "q2", "knee": "q3"})
    assert list(df.columns) == list(RUN_COLUMNS)
    np.testing.assert_allclose(df["t"], t, rtol=0, atol=1e-12)  # integer ns stamps, t exact to rounding
    np.testing.assert_array_equal(df[list(LABELS[:9])].to_numpy(), data)
    inside = (t >= ft[0]) & (t <= ft[-1])
    expected = np.column_stack([1.0 + 2.0 * t, -3.0 * t, 20.0 + 50.0 * t])
    np.testing.assert_allclose(df[["fx", "fy", "fz"]].to_numpy()[inside], expected[inside], rtol=0, atol=1e-9)
    # t = 0 is before the first wrench (0.3 ms), t = 0.199 s after the last (0.1983 s)
    assert df.loc[~inside, ["fx", "fy", "fz"]].isna().all().all() and (~inside).sum() == 2


def test_a_bag_whose_wrench_has_no_stamps_puts_both_topics_on_the_recording_clock(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Joint states stamped in simulation time (from 0) beside a wrench topic with zero stamps: each topic on
    its own clock shared no time (0 of 200 force samples). One clock for both, the recording times: the
    force, linear in t, comes back at the joint-state ticks to 1e-9 N. Joint states stamped in simulation
    time beside a wrench stamped in wall time: no shared time, said in a warning, and the force is NaN."""
    t = np.arange(0, 0.2, 1e-3)
    data = _signals(t)
    ft = np.arange(0.0003, 0.2, 2e-3)
    force = np.column_stack([1.0 + 2.0 * ft, -3.0 * ft, 20.0 + 50.0 * ft])
    names = ("q1_abad", "q2_hip", "q3_knee")  # legbench's own names: no mapping
    bag = write_bag("ros1", tmp_path / "a.bag", t, data, names, (0, 1, 2), ft, force, joint_stamp0_ns=0,
                    wrench_stamped=False)  # fmt: skip
    df = logs.load_log(bag)
    np.testing.assert_allclose(df["t"], t, rtol=0, atol=1e-12)  # recording times, from the first joint state
    inside = (t >= ft[0]) & (t <= ft[-1])
    assert inside.sum() == 198
    expected = np.column_stack([1.0 + 2.0 * t, -3.0 * t, 20.0 + 50.0 * t])
    np.testing.assert_allclose(df[["fx", "fy", "fz"]].to_numpy()[inside], expected[inside], rtol=0, atol=1e-9)
    bag2 = write_bag("ros1", tmp_path / "b.bag", t, data, names, (0, 1, 2), ft, force, joint_stamp0_ns=0)
    with caplog.at_level("WARNING"):
        df2 = logs.load_log(bag2)
    assert df2[["fx", "fy", "fz"]].isna().all().all()
    assert "no shared time, the ground force is left out" in caplog.text


def test_defaults_force_sign_and_ros2_file_path(tmp_path: Path) -> None:
    """legbench's own joint names need no mapping; the .mcap file inside a ROS 2 bag directory names the bag;
    force_sign -1 flips a foot-on-ground wrench into legbench's ground-on-foot force; without a wrench topic the
    force is NaN."""
    t = np.arange(0, 0.05, 1e-3)
    data = _signals(t)
    own = ("q1_abad", "q2_hip", "q3_knee")
    bag = write_bag("mcap", tmp_path / "b", t, data, own, (0, 1, 2), t, np.ones((len(t), 3)))
    mcap = next(bag.glob("*.mcap"))
    df = logs.load_log(mcap, ros=logs.RosOptions(force_sign=-1.0))
    np.testing.assert_array_equal(df[["fx", "fy", "fz"]].to_numpy(), -np.ones((len(t), 3)))
    no_force = write_bag("ros1", tmp_path / "nf.bag", t, data, own, (0, 1, 2))
    assert logs.load_log(no_force)[["fx", "fy", "fz"]].isna().all().all()


def test_a_bag_s_t0_in_seconds_is_its_time_zero(tmp_path: Path) -> None:
    """``RosOptions.t0`` is the bag time [s] that is the run's t = 0: joint states stamped from 100 s (every 1 ms)
    read with t0 = 99.5 s start at t = 0.5 s, each 1 ms after the last (to 1e-12 s: stamps are integer ns,
    t0 * 1e9 ns an integer); load_log's t0 does the same. A mutation audit found no test setting a bag's t0 (t0
    taken in ms passed)."""
    t = np.arange(0, 0.01, 1e-3)
    bag = write_bag("ros1", tmp_path / "a.bag", t, _signals(t), logs.DEFAULT_JOINTS, (0, 1, 2),
                    joint_stamp0_ns=100_000_000_000)  # fmt: skip
    np.testing.assert_allclose(logs.load_log(bag)["t"], t, rtol=0, atol=1e-12)  # no t0: the first sample
    df = logs.load_log(bag, ros=logs.RosOptions(t0=99.5))
    assert df["t"].iloc[0] == 0.5
    np.testing.assert_allclose(df["t"], 0.5 + t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(logs.load_log(bag, t0=99.5)["t"], 0.5 + t, rtol=0, atol=1e-12)


def test_wrench_messages_written_out_of_time_order_are_read_in_stamp_order(tmp_path: Path) -> None:
    """A wrench topic's messages in the bag in another order than their stamps (a sensor's messages arriving late:
    stamped 4.5, 0.5, 6.5, 2.5, 8.5 ms, written in that order) are sorted by stamp before the force is
    interpolated onto the joint-state ticks (every 1 ms, 0 .. 9 ms): fz = 1000 x its stamp in s comes back as the
    tick's time in ms (to 1e-9 N) from 1 to 8 ms, NaN at 0 and 9 ms (outside 0.5 .. 8.5 ms). A mutation audit found
    no bag written out of order (interpolating in the file's order passed)."""
    t = np.arange(10) * 1e-3
    ft = np.array([4.5, 0.5, 6.5, 2.5, 8.5]) * 1e-3
    force = np.column_stack([np.zeros(5), -ft, 1e3 * ft])
    bag = write_bag("ros1", tmp_path / "late.bag", t, _signals(t), logs.DEFAULT_JOINTS, (0, 1, 2), ft, force,
                    force_recorded=np.arange(5) * 2e-3)  # fmt: skip
    df = logs.load_log(bag)
    inside = slice(1, 9)
    np.testing.assert_allclose(df["fz"].to_numpy()[inside], 1e3 * t[inside], rtol=0, atol=1e-9)
    np.testing.assert_allclose(df["fy"].to_numpy()[inside], -t[inside], rtol=0, atol=1e-12)
    assert df.loc[[0, 9], ["fx", "fy", "fz"]].isna().all().all()


def test_bag_foot_position_is_the_run_s_own_from_q(tmp_path: Path) -> None:
    """Backend a's log written as a bag (a JointState carries no foot position): ee_x..ee_z come back as a's own
    foot centre, kinematics.fk of its q as the run logged it, to 1e-12 m, not NaN."""
    run_dir = write_run(tmp_path / "fake", {"ref": None, "a": scale(1.02)})
    run = pd.read_parquet(run_dir / "a.parquet")
    t = run["t"].to_numpy()
    bag = write_bag("ros1", tmp_path / "a.bag", t, run[list(LABELS[:9])].to_numpy(), logs.DEFAULT_JOINTS, (0, 1, 2))
    ee = list(EE_COLUMNS)
    np.testing.assert_allclose(logs.load_log(bag)[ee].to_numpy(), run[ee].to_numpy(), rtol=0, atol=1e-12)


def test_bag_errors_name_the_problem(tmp_path: Path) -> None:
    t = np.arange(0, 0.01, 1e-3)
    data = _signals(t)
    bag = write_bag("ros1", tmp_path / "two.bag", t, data, ("a", "b", "c"), (0, 1, 2), extra_joint_topic="/other/js")
    with pytest.raises(ResultsError, match=r"several sensor_msgs/JointState topics? .*/leg/joint_states"):
        logs.load_log(bag)
    with pytest.raises(ResultsError, match=r"joints \['q1_abad', 'q2_hip', 'q3_knee'\] not in .*\['a', 'b', 'c'\]"):
        logs.load_log(bag, ros=logs.RosOptions(joint_topic="/leg/joint_states"))
    with pytest.raises(ResultsError, match="topic '/nope': expected sensor_msgs/JointState, no such topic"):
        logs.load_log(bag, ros=logs.RosOptions(joint_topic="/nope"))
    with pytest.raises(ResultsError, match="NAME=q1,NAME=q2,NAME=q3"):
        logs.load_log(bag, {"a": "q1", "b": "q2"})
    (tmp_path / "junk.bag").write_bytes(b"not a bag")
    with pytest.raises(ResultsError, match="not a readable ROS bag"):
        logs.load_log(tmp_path / "junk.bag")


def test_a_ros2_bag_directory_named_bag_is_refused_with_the_fix(tmp_path: Path) -> None:
    """rosbags reads any '.bag' name as a ROS 1 file, so a ROS 2 bag directory named run.bag failed with 'not a
    readable ROS bag (AnyReaderError: ... Is a directory)'. It is refused saying why and what to do; the same
    directory renamed reads."""
    t = np.arange(0, 0.01, 1e-3)
    bag = write_bag("sqlite3", tmp_path / "run", t, _signals(t), ("hip_aa", "hip_fe", "knee"), (0, 1, 2))
    named = bag.rename(tmp_path / "run.bag")
    with pytest.raises(ResultsError, match=r"a ROS 2 bag directory named '\.bag': rosbags reads that name as a ROS 1"):
        logs.load_log(named)
    assert len(logs.load_log(named.rename(tmp_path / "run2"), {"hip_aa": "q1", "hip_fe": "q2", "knee": "q3"})) == len(t)


@pytest.mark.parametrize("kind", KINDS)
def test_compare_reads_a_bag_from_the_command_line(tmp_path: Path, kind: str) -> None:
    """Backend a's own log written as a bag (joint names of the lab's, topics named by option) and made the reference:
    a deviates from it by 0 in every signal (to 1e-9: stamps are integer ns), as with the CSV import."""
    run_dir = tmp_path / "fake"
    write_run(run_dir, {"ref": None, "a": scale(1.02)})
    df = pd.read_parquet(run_dir / "a.parquet")
    t = df["t"].to_numpy()
    bag = write_bag(kind, _bag_path(tmp_path, kind), t, df[list(LABELS[:9])].to_numpy(), ("j1", "j2", "j3"),
                    (0, 1, 2), t, df[["fx", "fy", "fz"]].to_numpy(), joint_topic="/js", wrench_topic="/ft",
                    extra_joint_topic="/cmd")  # fmt: skip
    argv = ["compare", str(run_dir), "--reference-log", str(bag), "--log-columns", "j1=q1,j2=q2,j3=q3",
            "--ros-joint-topic", "/js", "--ros-wrench-topic", "/ft", "--log-is-reference"]  # fmt: skip
    assert cli.main(argv) == 0
    rows = json.loads((run_dir / "metrics.json").read_text())["metrics"]
    ours = [r for r in rows if r["backend"] == "a" and r["metric"] == "max_abs" and r["value"] is not None]
    assert {r["signal"] for r in ours} == {"q", "qd", "tau", "force"}
    assert max(abs(r["value"]) for r in ours) < 1e-9


def test_ros_options_without_a_bag_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run_dir = tmp_path / "fake"
    write_run(run_dir, {"ref": None, "a": scale(1.02)})
    assert cli.main(["compare", str(run_dir), "--ros-joint-topic", "/js"]) == 2
    assert "need --reference-log naming a ROS bag" in capsys.readouterr().err


def test_bag_errors_name_the_settings_in_the_callers_words(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The messages naming a setting of the bag: by default the options of ``legbench compare`` (byte for byte, also
    through the command line), within ``logs.worded(logs.API_WORDS)`` (as Result.compare of the Python API calls
    legbench.compare.compare) the arguments of compare: ros=RosOptions(joint_topic=...), column_map={...}."""
    t = np.arange(0, 0.01, 1e-3)
    bag = write_bag("ros1", tmp_path / "two.bag", t, _signals(t), ("a", "b", "c"), (0, 1, 2), extra_joint_topic="/x")
    cli_words = {
        "topic": "several sensor_msgs/JointState topics (/leg/joint_states, /x); name one with --ros-joint-topic",
        "wrench": "several geometry_msgs/WrenchStamped topics (/f1, /f2); name one with --ros-wrench-topic",
        "names": "topic '/leg/joint_states': joints ['q1_abad', 'q2_hip', 'q3_knee'] not in the message's names "
        "['a', 'b', 'c']; map them with --log-columns NAME=q1,NAME=q2,NAME=q3",
        "map": "a bag's column map names its three joints, NAME=q1,NAME=q2,NAME=q3; got {'a': 'q1', 'b': 'q2'}",
    }
    api_words = {
        "topic": "several sensor_msgs/JointState topics (/leg/joint_states, /x); name one with "
        "ros=RosOptions(joint_topic=...)",
        "wrench": "several geometry_msgs/WrenchStamped topics (/f1, /f2); name one with "
        "ros=RosOptions(wrench_topic=...)",
        "names": "topic '/leg/joint_states': joints ['q1_abad', 'q2_hip', 'q3_knee'] not in the message's names "
        "['a', 'b', 'c']; map them with column_map={NAME: 'q1', NAME: 'q2', NAME: 'q3'}",
        "map": "a bag's column map names its three joints, {NAME: 'q1', NAME: 'q2', NAME: 'q3'}; got {'a': 'q1', "
        "'b': 'q2'}",
    }

    def problems() -> dict[str, str]:
        calls = {
            "topic": lambda: logs.load_log(bag),
            "wrench": lambda: logs._pick_topic(bag, {"/f1": logs.WRENCH, "/f2": logs.WRENCH}, logs.WRENCH, None, False),
            "names": lambda: logs.load_log(bag, ros=logs.RosOptions(joint_topic="/leg/joint_states")),
            "map": lambda: logs.load_log(bag, {"a": "q1", "b": "q2"}),
        }
        got = {}
        for what, call in calls.items():
            with pytest.raises(ResultsError) as exc:
                call()
            got[what] = exc.value.problem
        return got

    assert problems() == cli_words
    with logs.worded(logs.API_WORDS):
        assert problems() == api_words
    assert problems() == cli_words  # the block's words end with it
    run_dir = write_run(tmp_path / "fake", {"ref": None, "a": scale(1.02)})
    assert cli.main(["compare", str(run_dir), "--reference-log", str(bag)]) == 2
    assert capsys.readouterr().err == f"legbench: error: {bag}: {cli_words['topic']}\n"


# --------------------------------------------------------------------------- #
# CSV logs

CSV_ROWS = "0,0.1,0.2,0.3\n0.001,0.11,0.21,0.31\n0.002,0.12,0.22,0.32\n"


@pytest.mark.parametrize(
    ("header", "column_map", "problem"),
    [  # a second q2 of 999s was read silently (the first one used); one hiding q2 was named 'q1.1', not in the file
        ("t,q1,q2,q3,q2", {"q2": "q2"}, "header 'q2' names columns 3 and 5"),
        ("t,q1,q1,q3", {"q1": "q1"}, "header 'q1' names columns 2 and 3"),
        ('t,q1,"q2",q3,q2,fz,fz', {"fz": "fz"}, "header 'q2' names columns 3 and 5, 'fz' names columns 6 and 7"),
        ("t,q1,q2,q3,note,note,note", {"note": "tau1"}, "header 'note' names columns 5, 6 and 7"),
    ],
)
def test_a_header_name_given_to_two_columns_is_refused_naming_it_and_its_columns(
    tmp_path: Path, header: str, column_map: dict[str, str], problem: str
) -> None:
    """A header naming two columns alike (as written, quotes read as the data's parser reads them; names alike only
    once normalised, q2 and 'Q2 [rad]', are 'several header columns map to') is refused in one line naming the name
    and its columns (1-based), also when the map names it; not read on under pandas' invented names (q2.1)."""
    log = tmp_path / "dup.csv"
    width = header.count(",") + 1
    log.write_text(header + "\n" + "".join(f"{k * 1e-3}" + ",0.5" * (width - 1) + "\n" for k in range(3)))
    for cmap in (None, column_map):
        with pytest.raises(ResultsError) as err:
            logs.load_log(log, cmap)
        assert str(err.value) == f"{log}: {problem}: each column needs a name of its own"


def test_a_repeated_header_is_refused_from_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The audit's case: a run's log written to CSV with a second q2 column of 999s compared with rc 0; now rc 2 and
    the one line, and nothing written into the run directory."""
    run_dir = write_run(tmp_path / "fake", {"ref": None, "a": scale(1.02)})
    df = pd.read_parquet(run_dir / "a.parquet")
    df.insert(4, "q2 ", 999.0)
    log = tmp_path / "dup.csv"
    df.rename(columns={"q2 ": "q2"}).to_csv(log, index=False)
    assert log.read_text().startswith("t,q1,q2,q3,q2,qd1")
    before = {f.name: f.read_bytes() for f in run_dir.iterdir() if f.is_file()}
    assert cli.main(["compare", str(run_dir), "--reference-log", str(log)]) == 2
    assert capsys.readouterr().err == (
        f"legbench: error: {log}: header 'q2' names columns 3 and 5: each column needs a name of its own\n"
    )
    assert {f.name: f.read_bytes() for f in run_dir.iterdir() if f.is_file()} == before


def test_unnamed_csv_columns_are_not_a_repeated_header(tmp_path: Path) -> None:
    """Empty header cells (a spreadsheet's trailing columns) name nothing: two of them are no clash, and the log
    reads as without them."""
    plain, padded = tmp_path / "plain.csv", tmp_path / "padded.csv"
    plain.write_text("t,q1,q2,q3\n" + CSV_ROWS)
    padded.write_text("t,q1,q2,q3,,\n" + "".join(line + ",,\n" for line in CSV_ROWS.splitlines()))
    pd.testing.assert_frame_equal(logs.load_log(padded), logs.load_log(plain))


def test_a_t0_that_swamps_the_logs_times_is_named(tmp_path: Path) -> None:
    """``--log-t0 1e20`` on a log stamped from 0: the converted times, 1e20 apart from their 1 ms steps, are all
    -1e20 in double precision, and the refusal read "time is not strictly increasing at data row 2", of a file whose
    times increase. It names the t0 now; a t0 near the log's times (epoch seconds) is read as before."""
    log = tmp_path / "log.csv"
    log.write_text("t,q1,q2,q3\n" + CSV_ROWS)
    with pytest.raises(LegbenchError, match=r"^--log-t0 1e\+20: .*log.csv's times, strictly increasing as written, "
                                            r"are no longer distinct once converted"):  # fmt: skip
        logs.load_log(log, t0=1e20)
    epoch = tmp_path / "epoch.csv"
    epoch.write_text("t,q1,q2,q3\n" + "".join(f"{1.7e9 + float(r.split(',')[0])!r},{r.split(',', 1)[1]}\n"
                                              for r in CSV_ROWS.splitlines()))  # fmt: skip
    np.testing.assert_allclose(logs.load_log(epoch, t0=1.7e9)["t"], [0.0, 0.001, 0.002], atol=1e-6)


def test_a_column_mapped_away_from_its_own_name_is_said_to_leave_that_name_empty(tmp_path: Path) -> None:
    """``--log-columns q1=q2`` on a header t,q1,q2,q3: q1 goes to q2 and nothing gives q1, which read "no column
    matches ['q1'] in the header ['t', 'q1', ...]", a contradiction. It says where q1 went."""
    log = tmp_path / "log.csv"
    log.write_text("t,q1,q2,q3\n" + CSV_ROWS)
    with pytest.raises(ResultsError, match=r"column 'q1' is mapped to q2 \(.*\), so no column gives q1; map one to "
                                           r"it too$"):  # fmt: skip
        logs.load_log(log, {"q1": "q2"})


def test_a_trailing_comma_on_every_data_row_shifts_no_column(tmp_path: Path) -> None:
    """A writer that ends every data row with a comma (the header without one): pandas took the first column as
    the index and shifted every column left, so q1 was read as time (a review: 'time is not strictly increasing
    at data row 2 (t = -0.0025 s)', q1's values). Now the rows read as the plain file's."""
    plain, trailing = tmp_path / "plain.csv", tmp_path / "trailing.csv"
    plain.write_text("t,q1,q2,q3\n" + CSV_ROWS)
    trailing.write_text("t,q1,q2,q3\n" + "".join(line + ",\n" for line in CSV_ROWS.splitlines()))
    pd.testing.assert_frame_equal(logs.load_log(trailing), logs.load_log(plain))
    # a value there (a column without a name) was dropped with only a pandas warning: refused, saying so
    extra = tmp_path / "extra.csv"
    extra.write_text("t,q1,q2,q3\n" + "".join(line + ",9\n" for line in CSV_ROWS.splitlines()))
    with pytest.raises(ResultsError, match=r"data rows hold more values than the header names"):
        logs.load_log(extra)


@pytest.mark.parametrize("cell", ["", "NaN", "n/a"])
def test_a_missing_value_in_a_csv_log_is_a_missing_sample_not_an_error(tmp_path: Path, cell: str) -> None:
    """Deliberate (docs/metrics.md: a NaN sample is an imported log's missing value, left out of the metrics that
    need it; tests/test_compare.py measures such a log): what pandas reads as missing in some rows is NaN there,
    every other value as logged; inf stays refused."""
    log = tmp_path / "gap.csv"
    lines = CSV_ROWS.splitlines()
    lines[1] = f"0.001,0.11,{cell},0.31"
    log.write_text("t,q1,q2,q3\n" + "\n".join(lines) + "\n")
    df = logs.load_log(log)
    np.testing.assert_array_equal(df["q2"], [0.2, np.nan, 0.22])
    np.testing.assert_array_equal(df["q1"], [0.1, 0.11, 0.12])
    log.write_text(log.read_text().replace(f",{cell},", ",inf,"))
    with pytest.raises(ResultsError, match=r"column 'q2' holds inf at data row 2 \(t = 0\.001 s\)"):
        logs.load_log(log)


@pytest.mark.skipif(not hasattr(__import__("os"), "mkfifo"), reason="no FIFOs here")
def test_a_log_path_that_is_no_regular_file_says_what_it_is(tmp_path: Path) -> None:
    """A FIFO given as the log was reported 'no such log file'; now what it is, without opening it (no writer comes:
    opening would block). A directory that is no ROS 2 bag says what a bag directory holds."""
    fifo = tmp_path / "live.csv"
    __import__("os").mkfifo(fifo)
    with pytest.raises(ResultsError) as err:
        logs.load_log(fifo)
    assert str(err.value) == f"{fifo}: is a FIFO, not a regular file (a CSV log is read only from one)"
    with pytest.raises(ResultsError) as err:
        logs.load_log(tmp_path)
    assert str(err.value) == (
        f"{tmp_path}: is a directory, not a log file (a ROS 2 bag directory holds metadata.yaml; this one has none)"
    )
    with pytest.raises(ResultsError) as err:
        logs.load_log(tmp_path / "nope.csv")
    assert str(err.value) == f"{tmp_path / 'nope.csv'}: no such log file"


def test_a_bag_path_that_is_a_fifo_is_refused_unopened(tmp_path: Path) -> None:
    """A FIFO named like a bag (``x.bag``) went to rosbags, whose open blocks until a writer comes: refused, saying
    what it is, without opening it."""
    fifo = tmp_path / "x.bag"
    os.mkfifo(fifo)
    with pytest.raises(ResultsError) as exc:
        logs.load_log(fifo)
    assert str(exc.value) == f"{fifo}: is a FIFO, not a regular file (a bag is read only from one)"


def test_a_unit_in_a_csv_header_is_read_or_refused_never_ignored(tmp_path: Path) -> None:
    """A review's log with 'q1 [deg]' was read as radians (5634 % errors, exit 0), 't [ms]' as seconds, 'qd1 [deg/s]'
    without a warning: the header's unit was stripped and dropped. A unit legbench knows for the column is
    converted to its unit (deg -> rad, ms -> s, mm -> m); another is refused naming the column and what it reads;
    a header time unit together with a time scale is refused (it would scale twice)."""
    plain = tmp_path / "plain.csv"
    plain.write_text("t,q1,q2,q3,qd1,ee_x\n0,0.1,0.2,0.3,1.0,0.1\n0.001,0.11,0.21,0.31,1.5,0.2\n")
    deg = tmp_path / "deg.csv"
    k = 180.0 / np.pi
    deg.write_text(f"t [ms],q1 [deg],q2 (deg),q3 [rad],qd1 [deg/s],ee_x [mm]\n0,{0.1 * k!r},{0.2 * k!r},0.3,{k!r},"
                   f"100\n1,{0.11 * k!r},{0.21 * k!r},0.31,{1.5 * k!r},200\n")  # fmt: skip
    pd.testing.assert_frame_equal(logs.load_log(deg), logs.load_log(plain), rtol=1e-14, atol=0)
    with pytest.raises(LegbenchError, match="header gives the time's unit already .'t \\[ms\\]'.; give one or"):
        logs.load_log(deg, time_scale=1e-3)
    odd = tmp_path / "odd.csv"
    odd.write_text("t,q1 [grad],q2,q3\n0,0,0,0\n0.001,0,0,0\n")
    with pytest.raises(ResultsError, match=r"column 'q1 \[grad\]': unit \[grad\] is not one legbench reads for q1 "
                                           r"\(rad, radians, deg, degrees\)"):  # fmt: skip
        logs.load_log(odd)


def test_a_logs_time_errors_read_in_seconds_and_a_semicolon_file_is_named_as_such(tmp_path: Path) -> None:
    """A ms log with a repeated time said 't = 2000 s after 2002 s' (checked before the scale); it reads in
    seconds now. A semicolon-separated file was told to map its columns (one column, 't;q1;q2;q3'): it is told
    what it looks like."""
    ms = tmp_path / "ms.csv"
    ms.write_text("t,q1,q2,q3\n0,0,0,0\n2002,0,0,0\n2000,0,0,0\n")
    with pytest.raises(ResultsError, match=r"not strictly increasing at data row 3 \(t = 2 s after 2.002 s\)"):
        logs.load_log(ms, time_scale=1e-3)
    semi = tmp_path / "semi.csv"
    semi.write_text("t;q1;q2;q3\n0;0;0;0\n0.001;0;0;0\n")
    with pytest.raises(ResultsError, match="one column, its header 't;q1;q2;q3': separated by ';' or tabs"):
        logs.load_log(semi)


def test_a_time_scale_given_with_a_bag_is_refused_not_ignored(tmp_path: Path) -> None:
    """--log-time-scale with a bag was silently ignored (its stamps are ns): refused, naming the option."""
    from legbench.compare import log_settings_problem

    bag = tmp_path / "run.bag"
    words = {"log": "--reference-log", "log_time_scale": "--log-time-scale"}
    said = log_settings_problem(bag, None, False, 1e-3, False, words)
    assert said is not None and said.startswith("--log-time-scale: a ROS bag's times are its stamps (ns)")
    assert log_settings_problem(bag, None, False, 1.0, False, words) is None
    assert log_settings_problem(tmp_path / "log.csv", None, False, 1e-3, False, words) is None


def test_any_unit_in_square_brackets_that_legbench_does_not_read_is_refused(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A review: 'q1 [furlong]' was read as radians with exit 0, 'q1 [arcmin]' gave 3934 % errors and a warning
    only. Text in square brackets is a unit unless it is an integer index (pos[2], pos[-1]), and one legbench does
    not read is refused ('[²]' too: no digit); brackets that do not pair ('[deg)') are refused; the last bracket
    pair is the unit ('pos[0] [deg]' converted, 0.5 deg = 8.7266e-3 rad to 1e-15). Text in parentheses that is no
    unit legbench knows ('q1 (measured)', 'q1 (arcmin)') is read in legbench's unit, with a warning naming it."""

    def load(header: str, row: str = "0,0.5,0.25,0.125", cmap: dict[str, str] | None = None) -> pd.DataFrame:
        log = tmp_path / "u.csv"
        log.write_text(f"t,{header}\n{row}\n0.001,{row.split(',', 1)[1]}\n")
        return logs.load_log(log, cmap)

    for unit in ("furlong", "arcmin", "Rad/min", "²"):
        with pytest.raises(ResultsError, match=rf"column 'q1 \[{unit}\]': unit \[{unit}\] is not one legbench reads"):
            load(f"q1 [{unit}],q2,q3")
    with pytest.raises(ResultsError, match=r"column 'q1 \[deg\)': its brackets do not pair"):
        load("q1 [deg),q2,q3")
    df = load("pos[0] [deg],q2 [],pos[-1],q3 [radians]", "0,0.5,0.25,7,0.125", {"pos[0] [deg]": "q1"})
    assert df["q1"].tolist() == pytest.approx([math.radians(0.5)] * 2, abs=1e-15)
    assert df["q2"].tolist() == [0.25, 0.25] and df["q3"].tolist() == [0.125, 0.125]
    with caplog.at_level("WARNING", logger="legbench.logs"):
        df = load("q1 (measured),q2 (arcmin),q3")
    assert (df["q1"].tolist(), df["q2"].tolist()) == ([0.5, 0.5], [0.25, 0.25])
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 2 and "column 'q2 (arcmin)': (arcmin) is not a unit legbench reads; the column is read in " \
                              "rad" in said[1]  # fmt: skip


def test_a_log_error_names_the_column_as_the_files_header_does(tmp_path: Path) -> None:
    """A review's log with a 'knee' column mapped to q3 was told "column 'q3' holds inf": the file has no q3. The
    error names the header and legbench's column: "column 'knee' (q3)"."""
    log = tmp_path / "hw.csv"
    log.write_text("time,hip_aa,hip_fe,knee\n0,0,0,0\n0.001,0,0,inf\n")
    with pytest.raises(ResultsError, match=r"column 'knee' \(q3\) holds inf at data row 2 \(t = 0.001 s\)"):
        logs.load_log(log, {"hip_aa": "q1", "hip_fe": "q2", "knee": "q3"})


def test_bracketed_text_that_is_no_unit_stays_part_of_the_name(tmp_path: Path) -> None:
    """A review: headers pos[0], pos[1], pos[2] given in the column map, and 'q1 (measured)', loaded before header
    units were read, then were refused as units [0] and [measured]. Bracketed text that is no unit is part of
    the name again; common spellings (rad/sec, N-m, seconds) are read; a 't [s]' header with a time scale is
    refused as a 't [ms]' one is (the two disagree about the unit)."""
    idx = tmp_path / "idx.csv"
    idx.write_text(
        "t,pos[0],pos[1],pos[2],qd1 (measured),tau1 [N-m]\n0,0.1,0.2,0.3,1.0,2.0\n0.001,0.1,0.2,0.3,1.0,2.0\n"
    )
    df = logs.load_log(idx, {"pos[0]": "q1", "pos[1]": "q2", "pos[2]": "q3"})
    assert df["q1"].tolist() == [0.1, 0.1] and df["qd1"].tolist() == [1.0, 1.0] and df["tau1"].tolist() == [2.0, 2.0]
    sec = tmp_path / "sec.csv"
    sec.write_text("t [seconds],q1,q2,q3,qd1 [rad/sec]\n0,0,0,0,1\n0.001,0,0,0,1\n")
    assert logs.load_log(sec)["t"].tolist() == [0.0, 0.001]
    with pytest.raises(LegbenchError, match="header gives the time's unit already"):
        logs.load_log(sec, time_scale=1e-3)
    rpm = tmp_path / "rpm.csv"
    rpm.write_text("t,q1,q2,q3,qd1 [rpm]\n0,0,0,0,1\n0.001,0,0,0,1\n")
    with pytest.raises(ResultsError, match=r"column 'qd1 \[rpm\]': unit \[rpm\] is not one legbench reads for qd1"):
        logs.load_log(rpm)


def test_digest_is_a_files_sha256_and_tells_a_bag_directory_s_recordings_apart(tmp_path: Path) -> None:
    """A log's digest (metrics.json's sha256 of an imported log): a file's SHA-256 as hashlib computes it; for a
    ROS 2 bag directory, one that changes when any of its files' bytes or names change and not otherwise."""
    f = tmp_path / "hw.csv"
    f.write_text("t,q1\n0,0\n")
    assert logs.digest(f) == hashlib.sha256(f.read_bytes()).hexdigest()
    bag = tmp_path / "bag"
    (bag / "sub").mkdir(parents=True)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (bag / "sub" / "bag_0.db3").write_bytes(b"\x00" * 10)
    first = logs.digest(bag)
    assert logs.digest(bag) == first and re.fullmatch(r"[0-9a-f]{64}", first)
    (bag / "sub" / "bag_0.db3").write_bytes(b"\x00" * 9 + b"\x01")
    second = logs.digest(bag)
    (bag / "sub" / "bag_0.db3").rename(bag / "sub" / "bag_1.db3")
    assert len({first, second, logs.digest(bag)}) == 3
