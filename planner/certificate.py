"""Time-optimality certificate: the fastest re-timing of a plan's own path under all of
its limits, jerk and torque rate included.

TOPP-RA (:func:`planner.toppra_baseline.toppra_along`) re-times a path under torque,
velocity and acceleration limits only.  The planner also bounds the actuated jerk and
the torque rate, so TOPP-RA along its path solves an easier problem and comes out
faster by the cost of those limits (BENCHMARKS.md).  No TOPP library handles
third-order limits, so this module states the like-for-like problem directly, as a
small NLP in the path parameter, and solves it with IPOPT and CasADi's exact Hessian.

**The path** is the plan's own motion x(s), with s the plan's time: x, x' and x'' at
any s are exact (:meth:`planner.solution.Solution.sample`).  A re-timing is s(t) with
v = ds/dt > 0 and a = d2s/dt2; the plan itself is v = 1, a = 0.  At rest (the ends, a
stop) x' = x'' = 0, so every re-timing starts and ends at rest with zero acceleration,
as the plan does; no end condition is needed.

**Along the path everything is exact in (v, a)** (:func:`path_coefficients`):

    theta_dot   = theta'(s) v
    theta_ddot  = theta'(s) a + theta''(s) v^2
    tau         = A(s) a + B(s) v^2 + C(s) + b_v theta'(s) v + tau_c tanh(theta'(s) v / w_c)

A, B, C (links, payload and rotor inertia) from three evaluations of the planner's
torque model; the viscous and Coulomb friction of the motors (``Robot.motors``) are not
of TOPP-RA's a s'' + b s'^2 + c form and are kept as they are.

**The discretisation.** A grid s_0 < ... < s_M refines every node interval of the plan
(so that the jumps of x''' fall on grid points).  Variables v_i, a_i; rows:

a linear in s between grid points, so d(v^2)/ds = 2 a gives
v_{i+1}^2 - v_i^2 = (a_i + a_{i+1}) (s_{i+1} - s_i), and (v^2, a) at every midpoint
follow from its two neighbours; rows at every grid point and midpoint:

- |tau| <= torque, |theta_ddot| <= acceleration, |theta_dot| <= velocity;
- |difference of theta_ddot| / dt <= jerk and the same for the torque rate between
  consecutive points (half an interval apart), dt = 2 (half interval) / (v + v+);
- duration sum dt, minimised, from the plan (v = 1, a = 0).

The limits hold at these points, as the planner's hold at its nodes and midpoints;
with a grid ~8x as fine as the planner's points, the certificate's duration is a slight
under-estimate of the true optimum on this path, i.e. the certificate is on the strict
side for the plan.  :func:`retime_path` is checked against TOPP-RA with the jerk and
torque-rate limits lifted (tests/test_certificate.py).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from sixplus3.errors import InputError
from sixplus3.planner.solution import actuated_profile
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

if TYPE_CHECKING:
    from sixplus3.planner.solution import Solution

#: default number of grid intervals of a certificate (at least 4 per node interval)
GRID = 600
#: the re-timing's path speed v = ds/dt is kept in [V_MIN, V_MAX]; the plan is v = 1.
#: At a rest point (x' = 0) nothing else bounds v, which then runs to the bound with
#: no effect on the duration (1e-8 s between 1e3 and 10, 38 instead of 412 IPOPT
#: iterations at 10: measured on tilt60_x)
V_MIN, V_MAX = 1e-2, 10.0


@dataclass(frozen=True)
class PathCoefficients:
    """Per grid point (n, 9): theta', theta'', and tau = A a + B v^2 + C + friction."""

    theta_p: np.ndarray
    theta_pp: np.ndarray
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    viscous: np.ndarray  # (n, 9): each joint's, at every point
    coulomb: np.ndarray  # (n, 9)
    coulomb_velocity: float

    def rates(self, v: Any, v2: Any, a: Any, col: Any = lambda m: m,
              tanh: Any = np.tanh) -> tuple[Any, Any]:
        """(theta_ddot, tau) of the re-timing (v, v^2, a): numeric with (n, 1) arrays, or
        CasADi expressions of one joint with ``col`` picking its column as a DM and
        ``tanh`` = ``ca.tanh`` (the one formula of both, :func:`retime_path`)."""
        thp = col(self.theta_p)
        thdd = thp * a + col(self.theta_pp) * v2
        tau = (col(self.A) * a + col(self.B) * v2 + col(self.C)
               + col(self.viscous) * thp * v
               + col(self.coulomb) * tanh(thp * v / self.coulomb_velocity))
        return thdd, tau

    def torque(self, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """(n, 9) actuator torques [N m] of the re-timing (v, a), each (n,)."""
        v, a = np.asarray(v, float)[:, None], np.asarray(a, float)[:, None]
        return self.rates(v, v**2, a)[1]

    def theta_ddot(self, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        v, a = np.asarray(v, float)[:, None], np.asarray(a, float)[:, None]
        return self.rates(v, v**2, a)[0]


def path_coefficients(robot: Robot, x: np.ndarray, xp: np.ndarray,
                      xpp: np.ndarray) -> PathCoefficients:
    """The exact dependence of the actuated rates and torques on (v, a) along the path
    with samples x(s), x'(s), x''(s), each (n, 9), from the planner's compiled model
    (:func:`planner.solution.actuated_profile`, which agrees with Pinocchio)."""

    m = robot.motors
    zero = np.zeros_like(x)
    thp, thpp, tau1, grav = (v.T for v in actuated_profile(robot, x, xp, xpp))
    _, _, tau_a, _ = (v.T for v in actuated_profile(robot, x, zero, xp))
    visc = np.broadcast_to(m.viscous_per_joint, thp.shape).copy()
    coul = np.broadcast_to(m.coulomb_per_joint, thp.shape).copy()
    wc = float(m.coulomb_velocity)
    # tau1 is the torque at v = 1, a = 0: B + C + friction(theta')
    B = tau1 - grav - visc * thp - coul * np.tanh(thp / wc)
    return PathCoefficients(theta_p=thp, theta_pp=thpp, A=tau_a - grav, B=B, C=grav,
                            viscous=visc, coulomb=coul, coulomb_velocity=wc)


@dataclass(frozen=True)
class Retiming:
    """The fastest re-timing s(t) of a path found by :func:`retime_path`."""

    duration: float  # [s]
    reference: float  # [s] the duration of the path's own timing (v = 1)
    status: str  # IPOPT's return status
    success: bool
    iterations: int
    solve_time: float  # [s]
    # at the grid points and the midpoints between them (2M+1,), in order:
    s: np.ndarray  # the path parameter (the plan's time) [s]
    t: np.ndarray  # the re-timed times [s]
    v: np.ndarray  # ds/dt
    a: np.ndarray  # d2s/dt2 [1/s]
    jerk_limited: bool

    def motion(self, xp: np.ndarray, xpp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x_dot, x_ddot) (2M+1, 9) of the re-timed motion at ``s``, from the path's x'
        and x'' there: x_dot = x' v, x_ddot = x' a + x'' v^2."""
        v, a = self.v[:, None], self.a[:, None]
        return xp * v, xp * a + xpp * v**2

    @property
    def ratio(self) -> float:
        """reference / duration: how much longer the path's own timing is (1.02: 2 %)."""
        return self.reference / self.duration


def retime_path(robot: Robot, limits: Limits, s: np.ndarray, path: Callable[..., Any],
                jerk: bool = True, at_rest: bool = False, max_iter: int = 500) -> Retiming:
    """Minimum-time re-timing of the path x(s) on the grid ``s`` (M+1,), under
    ``limits``' torque, velocity and acceleration limits and, with ``jerk``, its jerk and
    torque-rate limits.  ``path(s)`` returns x, x', x'' (n, 9) at the parameters s (n,).
    Started from v = 1, a = 0.

    a = d2s/dt2 is linear in s between grid points, so v^2 is quadratic; the rows hold
    at the grid points and at the midpoints between them, where (v^2, a) follow exactly
    from the two neighbours.  (Rows at the grid points only let a zig-zag from point to
    point: without the jerk rows the re-timed torques overshot by 4-25 % between the
    points on the example plans, measured.)

    ``at_rest`` fixes v = 0 at both ends, for a regular path (x' != 0 there, e.g. a
    straight line), and with ``jerk`` also a = 0 (the acceleration before and after the
    motion is zero; a jump there is an infinite jerk).  A plan's own path is at rest
    with zero acceleration at its ends by itself (x' = x'' = 0).  The path parameter
    should be time-like (v = ds/dt within [V_MIN, V_MAX])."""
    t_start = time.perf_counter()
    s = np.asarray(s, dtype=float)
    ds = np.diff(s)
    if s.ndim != 1 or len(s) < 3 or not (ds > 0).all():
        raise InputError("the grid s must be increasing with at least 3 points",
                         value=s.shape, valid="an increasing 1-D grid of >= 3 points")
    n = len(s)
    s_all = np.empty(2 * n - 1)  # grid points (even) and midpoints (odd)
    s_all[0::2], s_all[1::2] = s, (s[:-1] + s[1:]) / 2
    pc = path_coefficients(robot, *path(s_all))
    V, Acc = ca.SX.sym("v", n), ca.SX.sym("a", n)
    dsm = ca.DM(ds)
    v2 = V**2
    # the midpoints: a linear in s, v^2 = v_i^2 + 2 int a ds
    a_mid = (Acc[:-1] + Acc[1:]) / 2
    v2_mid = v2[:-1] + dsm * (3 * Acc[:-1] + Acc[1:]) / 4
    v_mid = ca.sqrt(v2_mid)

    def interleave(nodes: Any, mids: Any) -> Any:
        out = ca.SX.zeros(2 * n - 1, 1)
        out[0::2], out[1::2] = nodes, mids
        return out

    Va, Aa, V2a = interleave(V, v_mid), interleave(Acc, a_mid), interleave(v2, v2_mid)
    half = ca.DM(np.repeat(ds / 2, 2))
    dt = 2 * half / (Va[:-1] + Va[1:])  # (2M,) the half intervals' durations
    rows, lo, hi = [], [], []

    def add(expr: Any, bound_lo: Any, bound_hi: Any) -> None:
        rows.append(expr)
        lo.append(np.full(expr.numel(), bound_lo))
        hi.append(np.full(expr.numel(), bound_hi))

    add((v2[1:] - v2[:-1]) / dsm - (Acc[:-1] + Acc[1:]), 0.0, 0.0)
    add(v2_mid, 1e-12, np.inf)
    for j in range(9):
        thdd, tau = pc.rates(Va, V2a, Aa, col=lambda m, j=j: ca.DM(m[:, j]), tanh=ca.tanh)
        add(tau / limits.torque, -1.0, 1.0)
        add(thdd / limits.acceleration, -1.0, 1.0)
        add(ca.DM(pc.theta_p[:, j]) * Va / limits.velocity, -1.0, 1.0)
        if jerk:  # rate = difference / dt over each half interval
            add((thdd[1:] - thdd[:-1]) / (dt * limits.jerk), -1.0, 1.0)
            add((tau[1:] - tau[:-1]) / (dt * limits.torque_rate), -1.0, 1.0)
    duration = ca.sum1(dt)
    nlp = {"x": ca.vertcat(V, Acc), "f": duration, "g": ca.vertcat(*rows)}
    solver = ca.nlpsol("retime", "ipopt", nlp, {
        "print_time": False,
        "ipopt": {"print_level": 0, "sb": "yes", "max_iter": max_iter, "tol": 1e-8,
                  "constr_viol_tol": 1e-8, "mumps_pivot_order": 2}})
    v_lo, v_hi = np.full(n, V_MIN), np.full(n, V_MAX)
    a_lo, a_hi = np.full(n, -np.inf), np.full(n, np.inf)
    if at_rest:
        v_lo[[0, -1]] = v_hi[[0, -1]] = 0.0
        if jerk:
            a_lo[[0, -1]] = a_hi[[0, -1]] = 0.0
    v0, a0 = np.clip(np.ones(n), v_lo, v_hi), np.zeros(n)
    if at_rest:  # start and stop over the first and last interval (v^2 > 0 between)
        a0[[0, 1]], a0[[-2, -1]] = 0.5 / ds[0], -0.5 / ds[-1]
        a0 = np.clip(a0, a_lo, a_hi)
    res = solver(x0=np.r_[v0, a0], lbx=np.r_[v_lo, a_lo],
                 ubx=np.r_[v_hi, a_hi], lbg=np.concatenate(lo),
                 ubg=np.concatenate(hi))
    stats = solver.stats()
    w = np.array(res["x"]).ravel()
    points = ca.Function("points", [V, Acc], [dt, Va, Aa])
    dt_v, v_all, a_all = (np.array(m).ravel() for m in points(w[:n], w[n:]))
    t_all = np.r_[0.0, np.cumsum(dt_v)]
    return Retiming(duration=float(t_all[-1]), reference=float(s[-1] - s[0]),
                    status=str(stats["return_status"]), success=bool(stats["success"]),
                    iterations=int(stats["iter_count"]),
                    solve_time=time.perf_counter() - t_start, s=s_all,
                    t=t_all, v=v_all, a=a_all, jerk_limited=jerk)


def plan_grid(sol: Solution, points: int = GRID) -> np.ndarray:
    """A grid of about ``points`` intervals over the plan's time that refines every node
    interval uniformly (at least 4 parts each)."""
    per = max(4, math.ceil(points / (len(sol.t) - 1)))
    parts = [np.linspace(t0, t1, per + 1)[:-1] for t0, t1 in zip(sol.t[:-1], sol.t[1:],
                                                                  strict=True)]
    return np.r_[np.concatenate(parts), sol.t[-1]]


def certify(sol: Solution, limits: Limits | None = None, points: int = GRID,
            jerk: bool = True) -> Retiming:
    """The fastest re-timing of the plan ``sol`` (a :class:`planner.solution.Solution`)
    along its own path, under ``limits`` (default: the limits it was planned to).
    ``result.ratio`` = plan duration / re-timed duration; the issue's target is
    ratio <= 1.02."""
    return retime_path(sol.robot, limits or sol.limits, plan_grid(sol, points), sol.sample,
                       jerk=jerk)
