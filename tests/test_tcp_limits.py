"""Platform-space limits: the tool centre point's speed and acceleration, as robot and
task limits, met by the planner (a uniform time stretch) and checked by the gate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sixplus3.control.pipeline import run_plan
from sixplus3.control.trajectory_file import read_trajectory
from sixplus3.control.validation import validate_file, validate_motion
from sixplus3.errors import LimitError
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.tcp import tcp_rates, tcp_velocity
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description import Robot
from sixplus3.robot_description.physical import Tool

ROBOT = Robot.default()
MOVE = {"name": "move", "nodes_per_segment": 8, "waypoints": [
    {"position": [0.0, 0.0, 0.58]}, {"position": [0.05, 0.02, 0.60], "rpy": [10, 0, 0]}]}


def test_limits_tighten_and_refuse_nonsense() -> None:
    lim = ROBOT.limits
    assert not lim.has_tcp
    t = lim.tightened(tcp_speed=0.25, tcp_acceleration=2 * 9.81)
    assert t.has_tcp and t.tcp_speed == 0.25 and t.without_tcp() == lim
    for bad in (0.0, -1.0, math.nan, 20.0):
        with pytest.raises(LimitError, match="tcp_speed"):
            lim.tightened(tcp_speed=bad)


def test_tcp_velocity_is_the_derivative_of_the_tcp_position() -> None:
    """tcp_velocity (the inverse IK Jacobian applied to the actuated rates) against a
    central difference of the tool centre point's position along a smooth motion, with
    a tool 8 cm off the platform's centre and a rotation."""
    robot = ROBOT.replace(tool=Tool(xyz=(0.02, -0.01, 0.08)))
    t = np.linspace(0.0, 0.2, 401)
    s = 0.5 - 0.5 * np.cos(np.pi * t / 0.2)
    pos = np.c_[0.04 * s, -0.02 * s, 0.58 + 0.03 * s]
    R = np.stack([np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)],
                            [0, math.sin(a), math.cos(a)]]) for a in 0.4 * s])
    psi = np.c_[1.57 + 0.2 * s, 1.57 - 0.1 * s, 1.57 + 0.05 * s]
    cfg = robot_ik(pos, R, psi, robot)
    assert cfg.ok.all()
    thd = np.gradient(cfg.theta, t, axis=0, edge_order=2)
    tcp = pos + np.einsum("nij,j->ni", R, np.array(robot.tool.xyz))
    want = np.gradient(tcp, t, axis=0, edge_order=2)
    got = tcp_velocity(cfg, thd)
    np.testing.assert_allclose(got[5:-5], want[5:-5], atol=2e-4 * np.abs(want).max())
    speed, acc = tcp_rates(cfg, thd, t)
    np.testing.assert_allclose(speed, np.linalg.norm(got, axis=1))
    assert acc.max() > 0.0


def test_a_task_tcp_speed_limit_is_met_and_the_gate_checks_it(tmp_path) -> None:
    free = run_plan(task_from_dict(MOVE), tmp_path / "free", ROBOT, html=False, plots=False)
    slow_doc = {**MOVE, "name": "slow", "limits": {"tcp_speed": 0.25,
                                                  "tcp_acceleration": 2 * 9.81}}
    slow = run_plan(task_from_dict(slow_doc), tmp_path / "slow", ROBOT, html=False,
                    plots=False)
    rep_free, rep_slow = validate_file(free.csv, ROBOT), validate_file(slow.csv, ROBOT)
    assert rep_free.ok and rep_slow.ok
    assert rep_free.max_tcp_speed > 0.25  # the unconstrained plan is faster than that
    assert rep_slow.max_tcp_speed <= 0.25 and rep_slow.max_tcp_acceleration <= 2 * 9.81
    assert rep_slow.limits["tcp_speed"] == 0.25  # the file carries the limit it met
    assert slow.solution.final_time > free.solution.final_time
    assert any(a.startswith("tcp") for a in slow.solution.active_limits)
    # the gate judges the unconstrained motion against a tcp limit: exit 1, named
    traj = read_trajectory(free.csv, ROBOT)
    x_guess = np.c_[traj.platform_position, np.zeros((len(traj.t), 3)), traj.psi]
    rep = validate_motion(traj.t, traj.joints("pos"), traj.joints("vel"),
                          traj.joints("acc"), ROBOT, 1000.0, x_guess,
                          limits=ROBOT.limits.tightened(tcp_speed=0.1))
    assert rep.exit_code == 1 and any("tcp speed" in m for m in rep.messages())
    assert not any("tcp" in m for m in rep_free.messages())
