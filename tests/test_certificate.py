"""The time-optimality certificate (planner.certificate): the exact path model, TOPP-RA
with the third-order limits lifted, and Pinocchio on the re-timed motion."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.symbolic import home_x
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.certificate import certify, path_coefficients, plan_grid, retime_path
from sixplus3.planner.ocp import plan
from sixplus3.planner.solution import actuated_profile
from sixplus3.planner.task import task_from_dict
from sixplus3.planner.toppra_baseline import toppra_time
from sixplus3.robot_description.physical import MotorModel
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()
TASK = {"name": "cert", "nodes_per_segment": 10,
        "waypoints": [{"position": [0, 0, 0.58]},
                      {"position": [0.03, 0.0, 0.61], "rpy": [10, 0, 0]}]}


@pytest.fixture(scope="module")
def planned():
    return plan(task_from_dict(TASK))


def test_the_path_model_is_exact_in_v_and_a_with_friction(planned) -> None:
    """tau(v, a) = A a + B v^2 + C + friction and theta_ddot(v, a) agree with the full
    model evaluated at (x, x' v, x' a + x'' v^2), with the default motors and with strong
    friction (which TOPP-RA's a s'' + b s'^2 + c form cannot carry)."""
    rng = np.random.default_rng(4)
    s = plan_grid(planned, 120)
    x, xp, xpp = planned.sample(s)
    strong = ROBOT.replace(motors=MotorModel(rotor_inertia=8e-3, viscous=0.3, coulomb=0.5))
    for robot in (ROBOT, strong):
        pc = path_coefficients(robot, x, xp, xpp)
        v, a = rng.uniform(0.2, 3.0, len(s)), rng.normal(scale=30.0, size=len(s))
        thd, thdd, tau, _ = (m.T for m in actuated_profile(
            robot, x, xp * v[:, None], xp * a[:, None] + xpp * v[:, None] ** 2))
        np.testing.assert_allclose(pc.torque(v, a), tau, rtol=0, atol=1e-9)
        np.testing.assert_allclose(pc.theta_ddot(v, a), thdd, rtol=0, atol=1e-8)
        np.testing.assert_allclose(pc.theta_p * v[:, None], thd, rtol=0, atol=1e-10)


def test_without_third_order_limits_it_agrees_with_toppra() -> None:
    """Two independent solvers of the same problem: on a straight line at rest at both ends
    (a regular path), torque, velocity and acceleration limits only, with the rotor
    inertia but no friction (TOPP-RA's form), the re-timing and TOPP-RA agree to 1e-4
    (measured: 4e-7 against TOPP-RA with 2000 gridpoints, 9e-6 with 1000); with the
    jerk and torque-rate limits the re-timing is slower (measured: 11.8 %)."""
    robot = ROBOT.replace(motors=MotorModel(rotor_inertia=5.1e-3, viscous=0.0, coulomb=0.0))
    xa = home_x(robot)
    xb = xa + np.r_[0.04, -0.02, 0.03, 0.3, -0.2, 0.1, 0.0, 0.0, 0.0]
    def line(s):  # time-like parameter: the re-timing's v = ds/dt is O(1)
        s = np.asarray(s)[:, None]
        return (xa + s / 0.1 * (xb - xa), np.tile((xb - xa) / 0.1, (len(s), 1)),
                np.zeros((len(s), 9)))

    s = np.linspace(0.0, 0.1, 301)
    lim = robot.limits
    free = retime_path(robot, lim, s, line, jerk=False, at_rest=True)
    topp = toppra_time(robot, line(s[::3])[0], lim, gridpoints=1000).duration
    assert free.success
    assert abs(free.duration / topp - 1.0) < 1e-4
    smooth = retime_path(robot, lim, s, line, jerk=True, at_rest=True)
    assert smooth.success and smooth.duration > 1.05 * free.duration


@pytest.mark.parametrize("jerk", [True, False])
def test_the_retimed_plan_is_feasible_in_pinocchio_and_independent_of_the_plans_timing(
        planned, jerk: bool) -> None:
    """The certificate's re-timing of a plan: no slower than the plan (the plan is a
    feasible point), within every limit with Pinocchio's torques at its grid points and
    midpoints, with and without the third-order limits, and the same optimum from the
    plan slowed down by 10 % (ratio 10 % larger)."""
    sol = planned
    cert = certify(sol, jerk=jerk)
    assert cert.success and cert.jerk_limited == jerk
    assert cert.duration <= sol.final_time * (1 + 1e-6)
    x, xp, xpp = sol.sample(cert.s)
    xd, xdd = cert.motion(xp, xpp)
    thd, thdd, _, _ = (m.T for m in actuated_profile(sol.robot, x, xd, xdd))
    cfg = robot_ik(x[:, 0:3], Rotation.from_rotvec(x[:, 3:6]).as_matrix(), x[:, 6:9],
                   sol.robot)
    assert cfg.ok.all()
    tau, _ = ClosedLoopDynamics(sol.robot).actuated_inverse_dynamics_batch(cfg.q, thd, thdd)
    lim, eps = sol.limits, 1e-6
    assert np.abs(tau).max() <= lim.torque * (1 + eps)
    assert np.abs(thdd).max() <= lim.acceleration * (1 + eps)
    assert np.abs(thd).max() <= lim.velocity * (1 + eps)
    dt = np.diff(cert.t)[:, None]
    if jerk:
        assert (np.abs(np.diff(thdd, axis=0)) / dt).max() <= lim.jerk * (1 + eps)
        assert (np.abs(np.diff(tau, axis=0)) / dt).max() <= lim.torque_rate * (1 + eps)
    np.testing.assert_allclose(cert.t[-1], cert.duration, rtol=1e-12)

    a = 1.1
    slow = dataclasses.replace(sol, t=sol.t * a, final_time=sol.final_time * a,
                               xd=sol.xd / a, xdd=sol.xdd / a**2)
    again = certify(slow, jerk=jerk)
    assert again.success
    assert abs(again.duration / cert.duration - 1.0) < 1e-3
    assert abs(again.ratio / (a * cert.ratio) - 1.0) < 1e-3


def test_the_short_rest_intervals_recover_what_the_certificate_found(monkeypatch,
                                                                      planned) -> None:
    """With every node interval the same length (REST_GRADING (1,)), the acceleration ramps
    from rest over a whole interval and the certificate finds the plan slower than its
    path allows; the short intervals next to rest (the default) give a faster plan, closer
    to its certificate."""
    from sixplus3.planner import options

    assert min(options.REST_GRADING) < 1.0
    monkeypatch.setattr(options, "REST_GRADING", (1.0,))
    uniform = plan(task_from_dict(TASK))
    assert uniform.source == planned.source == "ocp"
    assert np.allclose(np.diff(uniform.t), np.diff(uniform.t)[0])
    assert planned.final_time < uniform.final_time
    assert certify(planned).ratio < certify(uniform).ratio
