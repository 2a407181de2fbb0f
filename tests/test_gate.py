"""The gate to the hardware, attacked: forged, corrupted, interrupted, hostile input.

Every forgery is *consistent*: the attacker knows the format and recomputes the integrity
digest (:func:`trajectory_file.encode`), so only the physics can catch it.  Refusals must
come with the right exit code: 2 for a file that is not a consistent motion of this
robot, 1 for a motion that violates a limit; genuinely valid motions are accepted.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from forgeries import zigzag
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sixplus3.cli import main as cli
from sixplus3.control.drive.feed import prepare_feed
from sixplus3.control.file import trajectory_file as tf
from sixplus3.control.file.file_format import COLUMNS, JOINTS, columns, motion_of
from sixplus3.control.file.trajectory_file import encode
from sixplus3.control.file.trajectory_parse import parse
from sixplus3.control.gate import interval
from sixplus3.control.gate.validation import validate_bytes, validate_file, validate_motion
from sixplus3.control.pipeline import run_plan
from sixplus3.dynamics.symbolic import symbolic_robot
from sixplus3.errors import InputError, TrajectoryFileError, ValidationFailed
from sixplus3.motion import RATE_RANGE, Motion
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()
SMALL = {"name": "gate", "waypoints": [{"position": [0, 0, 0.58]},
                                       {"position": [0.03, 0.0, 0.61], "rpy": [10, 0, 0]}],
         "nodes_per_segment": 6}
IDX = {k: [COLUMNS.index(f"{j}_{k}") for j in JOINTS] for k in ("pos", "vel", "acc", "tau")}
SETTINGS = settings(max_examples=12, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def valid(tmp_path_factory):
    out = tmp_path_factory.mktemp("gate")
    res = run_plan(task_from_dict(SMALL), out, ROBOT, html=False, plots=False)
    raw = res.csv.read_bytes()
    header, data = parse(raw)
    return res.csv, raw, header, data


def forged(header: dict, data: np.ndarray, **changes) -> bytes:
    """A consistent forgery: new samples and header fields, digest recomputed."""
    h = {**header, **changes, "samples": len(data), "duration_s": float(data[-1, 0])}
    return encode(h, data)


def verdict(raw: bytes) -> int:
    try:
        return validate_bytes(raw, ROBOT).exit_code
    except TrajectoryFileError:
        return 2


def cli_validate(path: Path):
    r = CliRunner().invoke(cli, ["validate", str(path)])
    assert "Traceback" not in r.output
    return r


# ------------------------------------------------------------------ the valid file
_WORKER_SCRIPT = """
import json, os, sys
import sixplus3.control.gate.offload as O
import sixplus3.control.gate.validation as V
from sixplus3.robot_description.robot import Robot

O.OFFLOAD_MIN_POINTS = 10  # this short motion gets a worker too
parent, forks = os.getpid(), []
fork, compute = O.Offload._fork, O.Offload.compute


def record(self):
    fork(self)
    forks.append(self.pid)


def dying(self, start, stop):
    if os.getpid() != parent:  # the worker dies at its first range
        os._exit(7)
    compute(self, start, stop)


O.Offload._fork = record
if sys.argv[2] == "die":
    O.Offload.compute = dying
rep = V.validate_file(sys.argv[1], Robot.default())
print(json.dumps({"forks": forks, "tau": rep.tau.tolist(), "summary": rep.summary()}))
"""


def test_the_dynamics_worker_changes_nothing(valid, monkeypatch) -> None:
    """The validator shares the dynamics with a forked worker process when it may
    (control/gate/offload.py, Offload): in a fresh process, where numba has not started
    its threads.  The report is the one computed in a single process, exactly, and
    when the worker dies the parent computes its ranges itself."""
    import sixplus3.control.gate.offload as O

    path = valid[0]
    monkeypatch.setattr(O, "OFFLOAD_MIN_POINTS", 10**9)  # here: one process
    one = validate_file(path, ROBOT)
    for mode in ("work", "die"):
        out = subprocess.run([sys.executable, "-c", _WORKER_SCRIPT, str(path), mode],
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr[-2000:]
        got = json.loads(out.stdout)
        assert len(got["forks"]) == 1 and got["forks"][0] > 0, "no worker was forked"
        np.testing.assert_array_equal(np.array(got["tau"]), one.tau)
        assert got["summary"] == json.loads(json.dumps(one.summary())), mode


def test_the_valid_file_passes_and_the_command_agrees(valid, tmp_path) -> None:
    path, raw, _, data = valid
    rep = validate_bytes(raw, ROBOT)
    assert rep.ok and rep.exit_code == 0 and rep.checked_points == 2 * len(data) - 1
    assert cli_validate(path).exit_code == 0


# ------------------------------------------------------------------ motion forgeries
@SETTINGS
@given(st.data())
def test_swapped_rows_are_refused(valid, d) -> None:
    _, _, header, data = valid
    n = len(data)
    i = d.draw(st.integers(1, n - 3))
    j = d.draw(st.integers(i + 1, n - 2))
    bad = data.copy()
    bad[[i, j], 1:] = bad[[j, i], 1:]  # keep the time column: a jump in the motion
    assert verdict(forged(header, bad)) == 2


@SETTINGS
@given(st.data())
def test_a_reversed_middle_is_refused(valid, d) -> None:
    _, _, header, data = valid
    n = len(data)
    i = d.draw(st.integers(2, n // 2))
    j = d.draw(st.integers(i + 3, n - 2))
    bad = data.copy()
    bad[i:j, 1:] = bad[i:j, 1:][::-1]
    assert verdict(forged(header, bad)) == 2


@SETTINGS
@given(st.sampled_from([0.0, 10.0, 99.0, 1e5, math.inf, -1000.0]),
       st.sampled_from([1.0, 100.0, 0.5]))
def test_scaled_timestamps_or_an_absurd_rate_are_refused(valid, rate, factor) -> None:
    _, _, header, data = valid
    bad = data.copy()
    bad[:, 0] *= factor
    raw = encode({**header, "rate_hz": rate if math.isfinite(rate) else None,
                  "duration_s": float(bad[-1, 0])}, bad)
    assert verdict(raw) == 2


@SETTINGS
@given(st.data())
def test_a_motion_cut_off_or_started_mid_way_is_refused(valid, d) -> None:
    _, _, header, data = valid
    n = len(data)
    k = d.draw(st.integers(5, n - 5))
    head = data[:k].copy()
    tail = data[k:].copy()
    tail[:, 0] = np.arange(len(tail)) / 1000.0
    assert verdict(forged(header, head)) == 2
    assert verdict(forged(header, tail)) == 2


def test_zeroed_accelerations_with_recomputed_torques_are_refused(valid) -> None:
    _, _, header, data = valid
    bad = data.copy()
    bad[:, IDX["acc"]] = 0.0
    x = np.c_[data[:, 37:40], np.zeros((len(data), 3)), data[:, 44:47]]
    from scipy.spatial.transform import Rotation

    x[:, 3:6] = Rotation.from_quat(data[:, 40:44]).as_rotvec()
    rep = validate_motion(motion_of(bad, 1000.0), ROBOT, x)
    bad[:, IDX["tau"]] = rep.tau  # the forger recomputes the torques for zero acceleration
    out = validate_bytes(forged(header, bad), ROBOT)
    assert out.exit_code == 2
    assert any("velocity/acceleration consistency" in m for m in out.messages())


def test_a_gap_before_the_last_sample_is_refused(valid) -> None:
    _, _, header, data = valid
    bad = data.copy()
    bad[-1, 0] += 10.0
    assert verdict(forged(header, bad)) == 2


def test_low_rates_are_refused_by_the_planner_and_the_validator(tmp_path) -> None:
    r = CliRunner().invoke(cli, ["plan", "examples/tilt30_x.yaml", "-o", str(tmp_path),
                                 "--rate", "10"])
    assert r.exit_code == 2 and "rate" in r.output and not list(tmp_path.iterdir())


@SETTINGS
@given(st.sampled_from([0.8, 0.7, 0.5]), st.sampled_from([None, 20.0, 1e9]))
def test_a_faster_consistent_forgery_violates_a_limit_whatever_the_header_says(
        valid, scale, header_torque) -> None:
    """Time compressed (t x s, rates / s, accelerations / s^2), torques recomputed: a
    consistent motion, beyond the limits.  The header's limits can only tighten the
    robot's: looser ones are a forged file (refused, exit 2), never a looser gate."""
    _, _, header, data = valid
    fast = data.copy()
    fast[:, IDX["vel"]] /= scale
    fast[:, IDX["acc"]] /= scale**2
    rate = 1000.0 / scale
    fast[:, 0] = np.arange(len(fast)) / rate
    lim = dict(header["limits"])
    if header_torque is not None:
        lim.update(torque=header_torque, acceleration=1e6, jerk=1e12)
        with pytest.raises(TrajectoryFileError, match="header limits"):
            validate_bytes(forged(header, fast, rate_hz=rate, limits=lim), ROBOT)
        return
    rep = validate_bytes(forged(header, fast, rate_hz=rate, limits=lim), ROBOT)
    limit_msgs = [f.check for f in rep.findings if f.kind == "limit"]
    assert rep.exit_code in (1, 2) and limit_msgs, rep.messages()
    assert set(limit_msgs) & {"torque", "acceleration", "jerk (between samples)"}


def test_the_limit_exit_code_is_1_for_a_clean_violation(valid, tmp_path) -> None:
    """A robot with a tighter torque limit is another robot (other hash): the file is
    refused as a mismatch (2); validated for a robot whose limit it meets, it passes.
    A real violation with everything else consistent: exit 1."""
    _, _, header, data = valid
    fast = data.copy()
    s = 0.85
    fast[:, IDX["vel"]] /= s
    fast[:, IDX["acc"]] /= s**2
    fast[:, 0] = np.arange(len(fast)) / (1000.0 / s)
    from scipy.spatial.transform import Rotation

    x = np.c_[data[:, 37:40], Rotation.from_quat(data[:, 40:44]).as_rotvec(), data[:, 44:47]]
    rep = validate_motion(Motion(fast[:, 0], columns(fast, "pos"), columns(fast, "vel"),
                                 columns(fast, "acc"), 1000.0 / s), ROBOT, x)
    fast[:, IDX["tau"]] = rep.tau  # consistent feed-forward
    path = tmp_path / "fast.csv"
    path.write_bytes(forged(header, fast, rate_hz=1000.0 / s))
    r = cli_validate(path)
    assert r.exit_code == 1, r.output
    assert "violation: " in r.output and "first at t =" in r.output and "worst at" in r.output
    # the program itself (its entry point ends validate with os._exit after flushing):
    # the same exit codes and the whole report through a pipe
    for file, code, words in ((path, 1, ("LIMIT VIOLATED", "violation: ", "worst at")),
                              (valid[0], 0, ("OK",))):
        out = subprocess.run([sys.executable, "-m", "sixplus3.cli", "validate", str(file)],
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == code, out.stdout + out.stderr
        assert all(w in out.stdout for w in words) and "Traceback" not in out.stderr


@pytest.mark.parametrize("what", ["platform", "feedforward", "quaternion"])
def test_columns_that_disagree_with_the_joints_are_refused(valid, what) -> None:
    _, _, header, data = valid
    bad = data.copy()
    if what == "platform":
        bad[10:, 37] += 1e-3
    elif what == "feedforward":
        bad[:, IDX["tau"]] *= 0.9
    else:
        bad[5, 40:44] *= 1.01
    assert verdict(forged(header, bad)) == 2


@SETTINGS
@given(st.sampled_from(["header", "sample", "truncate", "append", "bom", "nan-header"]))
def test_edits_without_a_new_digest_or_with_nan_are_refused(valid, how) -> None:
    _, raw, header, _ = valid
    if how == "header":
        bad = raw.replace(b'"torque":10.0', b'"torque":20.0', 1)
        assert bad != raw
    elif how == "sample":
        lines = raw.split(b"\n")
        lines[10] = lines[10].replace(b"1", b"2", 1)
        bad = b"\n".join(lines)
    elif how == "truncate":
        bad = raw[: len(raw) // 2]
    elif how == "append":
        bad = raw + raw.split(b"\n")[-2] + b"\n"
    elif how == "bom":
        bad = b"\xef\xbb\xbf" + raw
    else:
        first, rest = raw.split(b"\n", 1)
        bad = first.replace(b'"torque":10.0', b'"torque":NaN', 1) + b"\n" + rest
    with pytest.raises(TrajectoryFileError):
        validate_bytes(bad, ROBOT)


def test_a_file_for_another_robot_or_with_a_forged_robot_is_refused(valid) -> None:
    _, _, header, data = valid
    other = ROBOT.replace(limits=ROBOT.limits.tightened(torque=20.0 - 10.5))
    rec = {"hash": other.hash, "parameters": other.as_dict(), "summary": ""}
    with pytest.raises(TrajectoryFileError, match="robot mismatch"):
        validate_bytes(forged(header, data, robot=rec), ROBOT)
    loose = {**ROBOT.as_dict(), "limits": {**ROBOT.as_dict()["limits"], "torque": 20.0}}
    rec = {"hash": ROBOT.hash, "parameters": loose, "summary": ""}
    with pytest.raises(TrajectoryFileError,
                       match="do not match the recorded robot hash|recorded robot is invalid"):
        validate_bytes(forged(header, data, robot=rec), ROBOT)


# ------------------------------------------------------------------ genuinely valid motions
@settings(max_examples=6, deadline=None, derandomize=True)
@given(st.floats(-0.03, 0.03), st.floats(-0.03, 0.03), st.floats(-0.2, 0.2),
       st.floats(0.3, 0.8), st.sampled_from([1000.0, 2000.0]))
def test_valid_motions_are_accepted(dx, dz, droll, duration, rate) -> None:
    """Rest-to-rest quintic blends in minimal coordinates, sampled at the rate: written
    by write_trajectory and accepted by the file validator (exit 0)."""
    sr = symbolic_robot(ROBOT)
    t = np.arange(0, math.ceil(duration * rate) + 1) / rate
    T = t[-1]
    s = t / T
    b = 10 * s**3 - 15 * s**4 + 6 * s**5
    db = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    ddb = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    x0 = np.r_[ROBOT.home_position, 0, 0, 0, ROBOT.home_psi]
    step = np.r_[dx, 0.0, dz, droll, 0.0, 0.0, 0.0, 0.0, 0.0]
    x, xd, xdd = x0 + b[:, None] * step, db[:, None] * step, ddb[:, None] * step
    n = len(t)
    th = np.array(sr.theta.map(n)(x.T)).T
    thd = np.array(sr.theta_dot.map(n)(x.T, xd.T)).T
    thdd = np.array(sr.theta_ddot.map(n)(x.T, xd.T, xdd.T)).T
    thd[[0, -1]] = 0.0
    thdd[[0, -1]] = 0.0
    rep = validate_motion(Motion(t, th, thd, thdd, rate), ROBOT, x)
    assert rep.ok, rep.messages()
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = tf.write_trajectory(Path(tmp) / "ok.csv", Motion(t, th, thd, thdd, rep.rate_hz),
                                   rep, ROBOT, ROBOT.limits, {"rate_hz": rate})
        again = validate_file(path, ROBOT)
        assert again.ok and again.exit_code == 0, again.messages()


# ------------------------------------------------------------------ names
@pytest.mark.parametrize("name,expect", [
    ("../../x", "x"), ("/abs/path", "abs_path"), ("a b", "a_b"), ("ok-1.2", "ok-1.2"),
    ("", None), (".", None), ("..", None), ("a\x00b", None), ("x" * 101, None),
    ("....", None), (".hidden", "hidden")])
def test_output_names_cannot_escape(tmp_path, name, expect) -> None:
    if expect is None:
        with pytest.raises(TrajectoryFileError):
            tf.output_path(tmp_path, name)
    else:
        p = tf.output_path(tmp_path, name)
        assert p.name == expect + ".csv" and p.parent == tmp_path


def test_a_hostile_task_name_is_refused_before_the_solve(tmp_path, monkeypatch) -> None:
    import sixplus3.control.pipeline as pl

    def boom(*a, **k):
        raise AssertionError("the planner must not run")

    monkeypatch.setattr(pl, "plan_problem", boom)
    for name in ("..", "", "/"):
        doc = {**SMALL, "name": name}
        with pytest.raises(TrajectoryFileError):
            run_plan(task_from_dict(doc), tmp_path / "out", ROBOT)
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ atomic writes
WRITER = r"""
import sys, time
from pathlib import Path
from sixplus3.control.file import trajectory_file as tf
path, a, b = Path(sys.argv[1]), Path(sys.argv[2]).read_bytes(), Path(sys.argv[3]).read_bytes()
print("ready", flush=True)
k = 0
while True:
    with tf._exclusive(path):
        tf.write_atomically(path, a if k % 2 else b)
    k += 1
"""


def test_kill_9_at_random_moments_leaves_a_complete_file(valid, tmp_path) -> None:
    _, raw, header, data = valid
    other = forged(header, data, task={"name": "another version"})
    a, b = tmp_path / "a.bin", tmp_path / "b.bin"
    a.write_bytes(raw)
    b.write_bytes(other)
    target = tmp_path / "out" / "traj.csv"
    target.parent.mkdir()
    target.write_bytes(raw)
    rng = np.random.default_rng(7)
    for _ in range(12):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(target), str(a), str(b)],
                                stdout=subprocess.PIPE, text=True)
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        threading.Event().wait(float(rng.uniform(0.0, 0.05)))
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        content = target.read_bytes()
        assert content in (raw, other)  # the old or the new file, whole
        parse(content)


def test_a_full_disk_keeps_the_old_file(valid, tmp_path, monkeypatch) -> None:
    import errno

    _, raw, header, data = valid
    target = tmp_path / "traj.csv"
    target.write_bytes(raw)
    real_open = open

    class Full:
        def __init__(self, fh):
            self.fh = fh

        def __enter__(self):
            return self

        def __exit__(self, *a):
            self.fh.close()

        def write(self, _data):
            raise OSError(errno.ENOSPC, "No space left on device")

    def fake_open(p, mode="r", *a, **k):
        fh = real_open(p, mode, *a, **k)
        return Full(fh) if "w" in mode and str(p).endswith(".tmp") else fh

    monkeypatch.setattr("builtins.open", fake_open)
    with pytest.raises(TrajectoryFileError, match="disk is full"):
        tf.write_atomically(target, forged(header, data, task={"v": 2}))
    monkeypatch.undo()
    assert target.read_bytes() == raw and sorted(p.name for p in tmp_path.iterdir()) == [
        "traj.csv"]


def test_a_concurrent_writer_loses_cleanly(valid, tmp_path) -> None:
    _, raw, header, data = valid
    target = tmp_path / "traj.csv"
    target.write_bytes(raw)
    with tf._exclusive(target):  # another writer holds the name
        r = subprocess.run([sys.executable, "-c",
                            "import sys; from pathlib import Path; "
                            "from sixplus3.control.file import trajectory_file as tf; "
                            "p = Path(sys.argv[1])\n"
                            "try:\n    with tf._exclusive(p): tf.write_atomically(p, b'x')\n"
                            "except tf.TrajectoryFileError as e:\n    print('lost', e)",
                            str(target)], capture_output=True, text=True, timeout=120)
    assert r.stdout.startswith("lost") and "another process is writing" in r.stdout
    assert target.read_bytes() == raw


# ------------------------------------------------------------------ the feed
def test_the_feed_sends_exactly_the_bytes_it_validated(valid, tmp_path) -> None:
    path, raw, header, data = valid
    copy = tmp_path / "traj.csv"
    copy.write_bytes(raw)
    plan = prepare_feed(copy, ROBOT, 1.0)
    # swapped for a forgery after the check: nothing read again, the validated samples
    # are what goes out
    fast = data.copy()
    fast[:, IDX["tau"]] *= 2.0
    copy.write_bytes(forged(header, fast))
    np.testing.assert_array_equal(plan.theta, columns(data, "pos"))
    # the validated torques, held as the feed says (default: the interval's mean)
    assert plan.torque_hold == "mean"
    np.testing.assert_array_equal(plan.tau, interval.held_torque(plan.report.tau, "mean"))
    sent = [json.loads(m) for m in plan.messages()]
    assert len(sent) == len(data) and sent[5]["tau_ff"] == plan.tau[5].tolist()


def test_a_slower_replay_is_a_real_retiming(valid, tmp_path) -> None:
    path, raw, header, data = valid
    half = prepare_feed(path, ROBOT, 0.5)
    assert half.report.ok and half.rate == 1000.0
    assert abs(half.t[-1] - 2 * data[-1, 0]) <= 1e-3
    assert np.abs(half.theta_dot).max() == pytest.approx(
        0.5 * np.abs(columns(data, "vel")).max(), rel=0.02)
    # torques recomputed: the inertial part shrinks, so the peak is lower
    assert np.abs(half.tau).max() < np.abs(columns(data, "tau")).max()
    for speed in (0.0, -1.0, math.nan, math.inf, 2.0):
        with pytest.raises(InputError):
            prepare_feed(path, ROBOT, speed)


def test_the_feed_refuses_an_invalid_file(valid, tmp_path) -> None:
    _, _, header, data = valid
    bad = data.copy()
    bad[[10, 11], 1:] = bad[[11, 10], 1:]
    p = tmp_path / "bad.csv"
    p.write_bytes(forged(header, bad))
    with pytest.raises(ValidationFailed) as err:
        prepare_feed(p, ROBOT)
    assert err.value.exit_code == 2


# ------------------------------------------------------------------ bad input, every command
def _run(args, tmp_path):
    r = CliRunner().invoke(cli, [str(a) for a in args])
    text = r.output
    assert "Traceback" not in text and r.exit_code in (1, 2), (r.exit_code, text)
    lines = [ln for ln in text.splitlines() if ln.strip()]
    return r.exit_code, lines


@pytest.mark.parametrize("content,needle", [
    ("name: t\nwaypoints:\n  - position: [0, 0, .nan]\n  - position: [0, 0, 0.58]\n", "NaN"),
    ("name: t\nwaypoints:\n  - position: [0, 0, .inf]\n  - position: [0, 0, 0.58]\n", "NaN"),
    ("a: &a [1,1,1,1,1,1,1,1,1]\nb: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]\nc: &c [*b,*b,*b,*b,*b,*b,"
     "*b,*b,*b]\nd: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]\ne: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]\n"
     "f: [*e,*e,*e,*e,*e,*e,*e,*e,*e]\n", "aliases"),
    ("waypoints: []\nwaypoints: []\n", "duplicate key"),
    (b"name: caf\xe9\nwaypoints: []\n", "UTF-8"),
    ("waypoints:\n  - position: [0, 0, 0.58]\n  - position: [0, 0, 0.58]\nlimits:\n"
     "  torque: 12\n", "torque"),
])
def test_bad_task_files_exit_2_with_one_line(tmp_path, content, needle) -> None:
    task = tmp_path / "task.yaml"
    if isinstance(content, bytes):
        task.write_bytes(content)
    else:
        task.write_text(content)
    code, lines = _run(["plan", task, "-o", tmp_path / "out"], tmp_path)
    assert code == 2 and len(lines) == 1 and needle in lines[0], lines
    assert len(lines[0]) < 2500
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args", [
    ["plan", "examples/tilt30_x.yaml", "--rate", "0"],
    ["plan", "examples/tilt30_x.yaml", "--rate", "nan"],
    ["design", "figures", "--ws-step", "0"],
    ["report", "--ws-step", "0"],
    ["feed", "missing.csv", "--speed", "-1"],
    ["feed", "missing.csv", "--speed", "nan"],
    ["feed", "missing.csv", "--speed", "inf"],
    ["feed", "missing.csv", "--udp", "not-an-address"],
    ["validate", "missing.csv"],
    ["robot", "ik", "0", "0", "nan", "0", "0", "0"],
    ["leg", "nan", "0.4", "0.2"],
])
def test_bad_arguments_exit_2_with_one_line(tmp_path, args) -> None:
    code, lines = _run([*args[:1], *args[1:]], tmp_path)
    assert code == 2 and len(lines) == 1, lines


def test_errors_carry_the_value_and_the_valid_range(valid, tmp_path) -> None:
    """Every error raised on purpose says what was wrong and what is allowed, as
    attributes (the CLI prints the message; a program reads these)."""
    from sixplus3.errors import Sixplus3Error
    from sixplus3.kinematics.robot import robot_ik_pose
    from sixplus3.kinematics.robot_fk import robot_fk

    _, raw, header, data = valid
    bad_file = tmp_path / "x.csv"
    bad_file.write_bytes(raw[:-50])
    cases = [
        lambda: robot_ik_pose((0.0, 0.0, 1.2), robot=ROBOT),
        lambda: robot_ik_pose((0.0, math.nan, 0.3), robot=ROBOT),
        lambda: robot_fk(np.zeros(8), robot=ROBOT),
        lambda: ROBOT.limits.tightened(torque=11.0),
        lambda: Robot.from_dict({"geometry": {"leg": {"l2": -1}}}),
        lambda: task_from_dict({"waypoints": [{"position": [0, 0, 0.58]}]}),
        lambda: validate_file(bad_file, ROBOT),
        lambda: validate_file(tmp_path / "missing.csv", ROBOT),
        lambda: tf.output_path(tmp_path, ".."),
        lambda: prepare_feed(bad_file, ROBOT, 5.0),
    ]
    for make in cases:
        with pytest.raises(Sixplus3Error) as err:
            make()
        assert err.value.valid is not None, (str(err.value), err.value.value)
        assert str(err.value)


@pytest.mark.parametrize("rate,eps,joints,want", [
    (100.0, 0.0037, range(9), 2),   # the audit's 100 Hz file: below the minimum rate
    (500.0, 2e-5, range(9), 2),     # 500 Hz: below the minimum rate too
    (1000.0, 1e-5, range(9), 2),    # the audit's +-10 microrad at 1 kHz
    (1000.0, 3e-5, [4], 2),         # one joint
    (1000.0, 2e-5, range(9), 2),    # within the old J dt^3/6 bound; 231 rad/s^2 between
    (2000.0, 1e-6, range(9), 2),    # within J dt^3/6 at 2 kHz; no jerk-J motion
])
def test_zigzag_forgeries_are_refused(rate, eps, joints, want, tmp_path) -> None:
    raw = zigzag(rate, eps, joints)
    assert verdict(raw) == want
    path = tmp_path / "zig.csv"
    path.write_bytes(raw)
    for args in (["validate", str(path)], ["export", str(path), "--format", "ros2-json"],
                 ["feed", str(path), "--dry-run"], ["simulate", str(path)]):
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == want, (args, r.output)
        assert "Traceback" not in r.output


@settings(max_examples=25, deadline=None, derandomize=True)
@given(st.floats(RATE_RANGE[0], RATE_RANGE[1]), st.floats(1e-8, 1e-2))
def test_a_zigzag_passes_only_if_its_motion_between_samples_is_within_limits(rate,
                                                                           eps) -> None:
    """At any accepted rate and amplitude: accepted only when the interpolant (whose
    acceleration peaks at 5.77 x the step / dt^2, jerk 60 x the step / dt^3) is within
    the acceleration limit and what a jerk-limited motion allows."""
    dt = 1.0 / rate
    step = 2 * eps
    acc = step * 10 / math.sqrt(3) / dt**2  # max |h5''| = 10 / sqrt(3) = 5.7735
    jerk = 60 * step / dt**3
    lim = ROBOT.limits
    c = verdict(zigzag(rate, eps, n=8))
    if acc > lim.acceleration * 1.001 or jerk > interval.C_JERK * lim.jerk * 1.001:
        assert c != 0
    if c == 0:
        assert acc <= lim.acceleration * (1 + 1e-6)
        assert jerk <= interval.C_JERK * lim.jerk * (1 + 1e-6)


