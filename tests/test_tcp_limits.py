"""Platform-space limits: the tool centre point's speed and acceleration, as robot and
task limits (or the named set ``people: collaborative``), met by the planner (rows of
its NLP, planner/tcp_rows.py) and checked by the gate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sixplus3.control.file.trajectory_read import read_trajectory
from sixplus3.control.gate.validation import validate_file, validate_motion
from sixplus3.control.pipeline import run_plan
from sixplus3.errors import LimitError
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.tcp import tcp_rates, tcp_velocity
from sixplus3.planner.ocp import plan
from sixplus3.planner.solution import actuated_profile
from sixplus3.planner.task import task_from_dict
from sixplus3.planner.tcp_rows import tcp_rates_at
from sixplus3.robot_description import Robot
from sixplus3.robot_description.hardware import PEOPLE_LIMITS, hardware_from_dict
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
    rep = validate_motion(traj.motion, ROBOT, x_guess,
                          limits=ROBOT.limits.tightened(tcp_speed=0.1))
    assert rep.exit_code == 1 and any("tcp speed" in m for m in rep.messages())
    assert not any("tcp" in m for m in rep_free.messages())


def test_the_nlp_rows_agree_with_the_gates_derivation() -> None:
    """The rows' speed (derivatives of p + R(r) t along the minimal coordinates) equals
    the gate's (the actuated rates through the inverse IK Jacobian, then the twist), and
    the rows' acceleration equals the finite difference of the gate's velocity."""
    from scipy.spatial.transform import Rotation

    robot = ROBOT.replace(tool=Tool(xyz=(0.02, -0.01, 0.08)))
    t = np.linspace(0.0, 0.2, 2001)
    w = np.pi / 0.2
    s, sd, sdd = 0.5 - 0.5 * np.cos(w * t), 0.5 * w * np.sin(w * t), 0.5 * w**2 * np.cos(w * t)
    amp = np.array([0.04, -0.02, 0.03, 0.3, -0.2, 0.1, 0.2, -0.1, 0.05])
    x0 = np.r_[0.0, 0.0, 0.58, 0.0, 0.0, 0.0, np.asarray(robot.home_psi)]
    x = x0 + np.outer(s, amp)
    xd, xdd = np.outer(sd, amp), np.outer(sdd, amp)
    speed, acc = tcp_rates_at(robot.tool.xyz, x, xd, xdd)
    cfg = robot_ik(x[:, 0:3], Rotation.from_rotvec(x[:, 3:6]).as_matrix(), x[:, 6:9], robot)
    assert cfg.ok.all()
    thd = actuated_profile(robot, x, xd, xdd)[0].T
    v = tcp_velocity(cfg, thd)
    np.testing.assert_allclose(speed, np.linalg.norm(v, axis=1), atol=1e-9)
    a_fd = np.linalg.norm(np.gradient(v, t, axis=0, edge_order=2), axis=1)
    np.testing.assert_allclose(acc[5:-5], a_fd[5:-5], atol=1e-4 * acc.max())
    assert speed.max() > 0.1 and acc.max() > 1.0  # a motion that tests something


def test_a_speed_limit_is_met_by_cruising_at_it_not_by_a_uniform_stretch() -> None:
    """The 10 cm translation under 0.25 m/s: most of its cruise within 2 % of the limit,
    and shorter than today's minimum-time plan stretched uniformly to the limit."""
    doc = {"name": "t10", "waypoints": [{"position": [0.0, 0.0, 0.58]},
                                        {"position": [0.10, 0.0, 0.58]}]}
    free = plan(task_from_dict(doc), ROBOT)
    slow = plan(task_from_dict({**doc, "limits": {"tcp_speed": 0.25}}), ROBOT)
    assert free.is_feasible() and slow.is_feasible() and slow.source == "ocp"
    stretch = free.check.max_tcp_speed / (0.995 * 0.25)
    assert slow.final_time < 0.75 * stretch * free.final_time
    t = np.linspace(0.0, slow.final_time, 2001)
    speed, _ = tcp_rates_at(ROBOT.tool.xyz, *slow.sample(t))
    assert speed.max() <= 0.25
    cruise = speed > 0.5 * 0.25
    assert np.mean(np.abs(speed[cruise] - 0.25) < 0.02 * 0.25) > 0.8
    assert slow.check.ok and slow.check.max_tcp_speed <= 0.25
    # 10 cm at 0.25 m/s takes 0.4 s at least: the plan adds only its ramps
    assert 0.4 < slow.final_time < 0.45


def test_people_collaborative_selects_the_named_set_everywhere() -> None:
    named = {k: v for k, v in PEOPLE_LIMITS["collaborative"].items() if k != "source"}
    assert "ISO 10218-1" in PEOPLE_LIMITS["collaborative"]["source"]
    task = task_from_dict({**MOVE, "people": "collaborative"})
    assert task.limits == named
    lim = task.limits_for(ROBOT)
    assert (lim.tcp_speed, lim.tcp_acceleration) == (0.25, 2.0)
    # the task's own tighter value wins; a looser one is not taken
    tight = task_from_dict({**MOVE, "people": "collaborative", "limits": {"tcp_speed": 0.1}})
    assert tight.limits["tcp_speed"] == 0.1
    loose = task_from_dict({**MOVE, "people": "collaborative", "limits": {"tcp_speed": 1.0}})
    assert loose.limits["tcp_speed"] == 0.25
    robot = Robot.from_dict({"people": "collaborative"})
    assert (robot.limits.tcp_speed, robot.limits.tcp_acceleration) == (0.25, 2.0)
    site = hardware_from_dict({"people": "collaborative"}, "test")
    assert site.limits.tcp_speed == 0.25
    from sixplus3.errors import GeometryError, TaskError

    with pytest.raises(TaskError, match="people"):
        task_from_dict({**MOVE, "people": "gentle"})
    with pytest.raises(GeometryError, match="collaborative"):
        Robot.from_dict({"people": "gentle"})
