"""The one sampled motion (issue 54, item 1): :class:`sixplus3.motion.Motion` is frozen,
its arrays read-only copies, checked once where it is built; the gate's report is frozen
and holds what it judged; the writer, the reader, the feed and the exports share it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sixplus3.control.file.file_format import columns, motion_of
from sixplus3.control.file.trajectory_file import write_trajectory
from sixplus3.control.file.trajectory_read import read_trajectory
from sixplus3.control.formats.drive_csv import drive_table
from sixplus3.control.formats.ros2 import ros2_joint_trajectory
from sixplus3.control.gate.validation import validate_and_write, validate_motion
from sixplus3.errors import InputError, TrajectoryFileError
from sixplus3.kinematics.robot import home
from sixplus3.motion import MAX_SAMPLES, Motion, samples_fingerprint
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()


def _quintic(n: int = 301, rate: float = 1000.0):
    """A rest-to-rest quintic of the actuated joints from home, and its seed."""
    t = np.arange(n) / rate
    T = t[-1]
    s = t / T
    p = 10 * s**3 - 15 * s**4 + 6 * s**5
    dp = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    ddp = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    d = 0.04 * np.array([0.2, -0.1, 0.15, 0.1, 0.2, -0.2, -0.15, 0.1, 0.05])
    th = home(ROBOT).theta[0] + p[:, None] * d
    x = np.tile(np.r_[ROBOT.home_position, 0.0, 0.0, 0.0, ROBOT.home_psi], (n, 1))
    return t, th, dp[:, None] * d, ddp[:, None] * d, x


def test_a_motion_is_frozen_and_its_arrays_are_read_only_copies() -> None:
    t, th, v, a, _ = _quintic()
    m = Motion(t, th, v, a, 1000)
    assert m.rate == 1000.0 and isinstance(m.rate, float) and len(m) == len(t)
    for arr in (m.t, m.theta, m.theta_dot, m.theta_ddot):
        assert arr.dtype == np.float64 and not arr.flags.writeable and arr.flags.c_contiguous
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.rate = 500.0  # type: ignore[misc]
    th[0, 0] += 1.0  # the caller's array is theirs: the motion keeps what it was given
    assert m.theta[0, 0] == th[0, 0] - 1.0
    assert m.duration == pytest.approx(0.3)


def test_a_motion_is_checked_once_where_it_is_built() -> None:
    t, th, v, a, _ = _quintic(5)
    with pytest.raises(InputError, match=r"theta_dot must be \(5, 9\)"):
        Motion(t, th, v[:, :8], a, 1000.0)
    with pytest.raises(InputError, match="theta_ddot is missing"):
        Motion(t, th, v, None, 1000.0)
    with pytest.raises(InputError, match="real numbers"):
        Motion(t, th + 0j, v, a, 1000.0)
    with pytest.raises(InputError, match="rate must be a number"):
        Motion(t, th, v, a, True)
    # the cap is checked on the shape: a broadcast view of 10^8 rows is never copied
    huge = np.broadcast_to(np.zeros(9), (10 ** 8, 9))
    with pytest.raises(InputError, match=str(MAX_SAMPLES)):
        Motion(np.broadcast_to(0.0, (10 ** 8,)), huge, huge, huge, 1000.0)
    # a motion with a NaN is a motion (the gate refuses it as a defect, exit 2)
    bad = th.copy()
    bad[2, 3] = np.nan
    x = np.tile(np.r_[ROBOT.home_position, 0.0, 0.0, 0.0, ROBOT.home_psi], (5, 1))
    assert validate_motion(Motion(t, bad, v, a, 1000.0), ROBOT, x).exit_code == 2
    on_grid = Motion.on_grid(th, v, a, 1000.0)
    np.testing.assert_array_equal(on_grid.t, np.arange(5) / 1000.0)


def test_the_fingerprint_is_of_every_sample_and_the_rate() -> None:
    t, th, v, a, _ = _quintic(50)
    m = Motion(t, th, v, a, 1000.0)
    assert m.fingerprint == samples_fingerprint(t, th, v, a, 1000.0)
    assert m.fingerprint is m.fingerprint  # computed once
    other = v.copy()
    other[7, 4] = np.nextafter(other[7, 4], 1.0)
    assert Motion(t, th, other, a, 1000.0).fingerprint != m.fingerprint
    assert Motion(t, th, v, a, 2000.0).fingerprint != m.fingerprint
    assert m.with_theta(th).fingerprint == m.fingerprint


def test_the_report_is_frozen_and_writes_only_its_motion(tmp_path) -> None:
    t, th, v, a, x = _quintic()
    motion = Motion(t, th, v, a, 1000.0)
    rep = validate_motion(motion, ROBOT, x)
    assert rep.ok, rep.messages()
    assert rep.fingerprint == motion.fingerprint and rep.rate_hz == 1000.0
    assert rep.limits == pytest.approx(ROBOT.limits.as_dict(), rel=1e-12)
    with pytest.raises(dataclasses.FrozenInstanceError):
        rep.ok = False  # type: ignore[misc]
    with pytest.raises(InputError, match="takes a sixplus3.motion.Motion"):
        validate_motion((t, th, v, a), ROBOT, x)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="validated Motion"):
        write_trajectory(tmp_path / "a.csv", (t, th, v, a), rep, ROBOT,  # type: ignore[arg-type]
                         ROBOT.limits, {})
    nudged = th.copy()
    nudged[150, 0] += 1e-9
    with pytest.raises(TrajectoryFileError, match="other samples"):
        write_trajectory(tmp_path / "a.csv", motion.with_theta(nudged), rep, ROBOT,
                         ROBOT.limits, {})
    path, written = validate_and_write(tmp_path / "b.csv", motion, ROBOT, x)
    assert written.stop_deceleration is not None and written.fingerprint == rep.fingerprint
    back = read_trajectory(path, ROBOT)
    assert back.motion.fingerprint == motion.fingerprint  # the reader returns the same
    data = back.data
    np.testing.assert_array_equal(motion_of(data, 1000.0).theta, columns(data, "pos"))
    # the exports take the motion
    msg = ros2_joint_trajectory(back.motion, columns(data, "tau"))
    assert msg["points"][10]["positions"] == [float(q) for q in th[10]]
    counts, _, _ = drive_table(ROBOT, back.motion, columns(data, "tau"))
    assert counts.shape == (len(t), 9)


#: What one plan checks, and how often (docs/architecture.md, "What one plan checks"):
#: each input once where it is built, the rate at the two public doors it passes (the
#: pipeline's, before anything is planned, and the smoothing's).
PLAN_CHECKS = {"Motion.__post_init__": 1, "_check_kinds": 1, "samples_fingerprint": 1,
               "judged_limits": 1, "check_plan_arguments": 1, "limits_for": 1,
               "check_rate": 2, "check_samples": 2}


def test_one_plan_checks_each_input_once(tmp_path) -> None:
    """Counts the calls of the checks while ``run_plan`` plans, smooths, validates and
    writes a small task (a profiler hook: every call site counts, whatever imported
    the function)."""
    import collections
    import os
    import sys

    import sixplus3
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.task import task_from_dict

    root = os.path.dirname(os.path.dirname(os.path.realpath(sixplus3.__file__)))
    counts: collections.Counter[str] = collections.Counter()
    wanted = {k.split(".")[-1] for k in PLAN_CHECKS}

    def hook(frame, event, arg):  # sys.setprofile's signature
        code = frame.f_code
        if event == "call" and code.co_name in wanted and code.co_filename.startswith(root):
            name = code.co_name
            if name == "__post_init__":
                name = f"{type(frame.f_locals['self']).__name__}.__post_init__"
            counts[name] += 1

    task = task_from_dict({"name": "counted", "nodes_per_segment": 6, "waypoints": [
        {"position": [0.0, 0.0, 0.58]}, {"position": [0.02, 0.0, 0.58]}]})
    sys.setprofile(hook)
    try:
        out = run_plan(task, tmp_path, ROBOT, html=False, plots=False)
    finally:
        sys.setprofile(None)
    assert out.report.ok
    assert {k: counts[k] for k in PLAN_CHECKS} == PLAN_CHECKS
