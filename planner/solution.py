"""A solved plan (:class:`Solution`, frozen) and its independent dense re-check.

The motion is piecewise cubic: node times ``t``, node states (x, xd) and accelerations
``xdd`` linear between the nodes (:func:`sample_cubic`).  :func:`dense_check` re-evaluates
it at 10x the node density with the numeric model (Pinocchio's constrained inverse
dynamics, the numeric kinematics and the capsule clearance), by the same rule as the
file gate (:func:`sixplus3.kinematics.checks.measure_limits`), independently of the
CasADi expressions used inside the optimisation.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.codegen import build_kind, compiled_profile
from sixplus3.kinematics.checks import measure_limits
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.task import Task
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot


@dataclass(frozen=True)
class DenseCheck:
    """Independent re-check of a plan with the numeric model at a given density."""

    ok: bool
    samples: int
    max_torque_ratio: float  # max |tau| / limit (Pinocchio constrained inverse dynamics)
    max_velocity_ratio: float
    max_acceleration_ratio: float
    min_margin: float  # smallest official margin (leg type I/II, platform)
    min_margin_leg_type1: float
    min_margin_leg_type2: float
    min_margin_platform: float
    theta_range_ok: bool
    max_spherical_tilt: float  # [rad]
    min_clearance: float  # [m] of the collision model (kinematics.collision)
    violations: list[str]
    max_tcp_speed: float = float("nan")  # [m/s] tool centre point
    max_tcp_acceleration: float = float("nan")  # [m/s^2]


#: no NLP work: (seconds, IPOPT iterations, seconds of function evaluations)
NO_WORK: tuple[float, int, float] = (0.0, 0, 0.0)


@dataclass(frozen=True)
class Solution:
    """A solved plan: node trajectory, timings, statistics and its own dense re-check.

    Frozen: every step of the planner that changes a plan (a re-time, a stretch, the
    baseline's statistics) makes a new one (:meth:`replace`)."""

    status: str
    final_time: float  # [s]
    solve_time: float  # [s] wall clock of the NLP solves
    iterations: int
    segment_times: np.ndarray  # (S,) [s]
    t: np.ndarray  # (N+1,) node times [s]
    x: np.ndarray  # (N+1, 9) minimal coordinates
    xd: np.ndarray  # (N+1, 9)
    xdd: np.ndarray  # (N+1, 9)
    tau: np.ndarray  # (N+1, 9) actuator torques [N m]
    theta: np.ndarray  # (N+1, 9) actuated angles [rad]
    residuals: dict[str, float]  # max violations of the NLP's equality constraints
    active_limits: tuple[str, ...]
    robot: Robot  # the robot planned for
    limits: Limits  # the limits planned to (the robot's, tightened by the task)
    check: DenseCheck | None = None
    options: PlannerOptions = field(default_factory=PlannerOptions)
    task: Task | None = None
    #: NLP solves behind this plan (1 + re-solves after the dense check)
    solves: int = 1
    #: final uniform time scale applied after the NLP (1: the NLP's own timing)
    time_scale: float = 1.0
    #: the NLP's primal-dual point (x, lam_x, lam_g, D), to warm-start a re-solve
    nlp_point: tuple[Any, ...] | None = field(default=None, repr=False)
    #: "ocp" (the time-optimal NLP) or "baseline" (planner.baseline: stop at every
    #: waypoint, straight lines, TOPP-RA per segment; returned when the NLP failed or
    #: was slower)
    source: str = "ocp"
    #: duration [s] of the baseline plan of the same task (None: no admissible baseline)
    baseline_time: float | None = None
    #: wall clock [s] of the whole solve (static choices, baseline, NLPs, checks)
    wall_time: float = 0.0
    #: IPOPT iterations of every NLP solve behind this plan (``solve_time``'s solves:
    #: failed starts, the homotopy's steps and the re-solves included)
    total_iterations: int = 0
    #: [s] of ``solve_time`` spent evaluating the NLP's functions and derivatives
    #: (CasADi's ``t_wall_nlp_*``); the rest is the solver's own work (IPOPT's linear
    #: algebra, line search and bookkeeping)
    function_time: float = 0.0

    def replace(self, **changes: Any) -> Solution:
        """A copy with ``changes`` (``dataclasses.replace``)."""
        return replace(self, **changes)

    def work(self) -> tuple[float, int, float]:
        """(``solve_time``, ``total_iterations``, ``function_time``): the NLP work behind
        this plan, for :meth:`plus_work`."""
        return self.solve_time, self.total_iterations, self.function_time

    def header(self) -> dict[str, Any]:
        """The trajectory file's ``planner`` header field: how this plan was found (status,
        source, build, timings, iterations, solves, time scale, segment times, residuals,
        active limits, the dense check, the options).  Built here, once."""


        return {"status": self.status, "source": self.source,
                "compiled": build_kind(self.robot),
                "baseline_time_s": self.baseline_time, "wall_time_s": self.wall_time,
                "final_time_s": self.final_time,
                "solve_time_s": self.solve_time, "iterations": self.iterations,
                "total_iterations": self.total_iterations,
                "function_time_s": self.function_time,
                "solves": self.solves, "time_scale": self.time_scale,
                "segment_times_s": self.segment_times, "residuals": self.residuals,
                "active_limits": self.active_limits,
                "dense_check": self.check.__dict__ if self.check else None,
                "options": asdict(self.options)}

    def plus_work(self, seconds: float, iterations: int, function_time: float) -> Solution:
        """A copy that also counts the NLP work of other solves (a failed start, an
        earlier step) in its solve time, iterations and function time."""
        return replace(self, solve_time=self.solve_time + seconds,
                       total_iterations=self.total_iterations + iterations,
                       function_time=self.function_time + function_time)

    def checked(self, factor: int = 10) -> Solution:
        """A copy with its :func:`dense_check` at ``factor`` x the node density."""
        return replace(self, check=dense_check(self, factor))

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, xd, xdd) at arbitrary times [s] from the exact piecewise-cubic motion."""
        return sample_cubic(self.t, self.x, self.xd, self.xdd, times)

    def is_feasible(self) -> bool:
        return bool(self.check is not None and self.check.ok)


def sample_cubic(t: np.ndarray, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray,
                 times: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, xd, xdd) at ``times`` of the piecewise-cubic motion with node times ``t`` and
    node values (x, xd, xdd), the acceleration linear between the nodes."""
    times = np.clip(np.asarray(times, dtype=float), 0.0, t[-1])
    k = np.clip(np.searchsorted(t, times, side="right") - 1, 0, len(t) - 2)
    h = (t[k + 1] - t[k])[:, None]
    s = (times - t[k])[:, None]
    u0, u1 = xdd[k], xdd[k + 1]
    jerk = (u1 - u0) / h
    return (x[k] + s * xd[k] + s**2 / 2 * u0 + s**3 / 6 * jerk,
            xd[k] + s * u0 + s**2 / 2 * jerk, u0 + s * jerk)


def actuated_profile(robot: Robot, x: np.ndarray, xd: np.ndarray,
                     xdd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(theta_dot, theta_ddot, tau, tau_gravity), each (9, n), of the samples (n, 9) of a
    motion, with ``robot``'s CasADi model (:func:`dynamics.symbolic.profile_function`,
    compiled: ~20x faster than the interpreted functions on 400 samples, the same
    numbers, BENCHMARKS.md)."""

    f, p = compiled_profile(robot)
    out = f.map(len(x))(x.T, xd.T, xdd.T, p)
    return tuple(np.array(v) for v in out)  # type: ignore[return-value]


def stretch_factors(thd: np.ndarray, thdd: np.ndarray, tau: np.ndarray, grav: np.ndarray,
                    lim: Limits, fraction: float) -> np.ndarray:
    """(n,) smallest uniform time stretch a > 0 per sample bringing the
    :func:`actuated_profile` within ``fraction`` of the velocity, acceleration and torque
    limits (theta_dot scales 1/a, theta_ddot and tau - tau_gravity 1/a^2).  Where gravity
    alone exceeds the fraction the headroom is floored at 1e-3 of the limit."""
    dyn = tau - grav
    room_hi = fraction * lim.torque - grav  # d / a^2 <= room_hi
    room_lo = fraction * lim.torque + grav  # -d / a^2 <= room_lo
    need = np.where(dyn > 0, dyn / np.maximum(room_hi, 1e-3 * lim.torque),
                    -dyn / np.maximum(room_lo, 1e-3 * lim.torque))
    a2 = np.maximum.reduce([
        (np.abs(thd) / (fraction * lim.velocity)) ** 2,
        np.abs(thdd) / (fraction * lim.acceleration), need]).max(axis=0)
    return np.sqrt(np.maximum(a2, 1e-12))  # type: ignore[no-any-return]


def dense_check(sol: Solution, factor: int = 10) -> DenseCheck:
    """Re-evaluate a plan with the numeric model at ``factor`` x the node density.

    Torques come from Pinocchio's constrained inverse dynamics (dynamics.closed_loop),
    margins and the exact capsule clearance between the legs from the numeric
    kinematics (kinematics.robot), independently of the CasADi expressions used inside
    the optimisation; the same rule as the file validation
    (:func:`sixplus3.kinematics.checks.measure_limits`), against ``sol.limits``.
    """

    n = (len(sol.t) - 1) * factor + 1
    times = np.linspace(0.0, sol.t[-1], n)
    x, xd, xdd = sol.sample(times)
    R = Rotation.from_rotvec(x[:, 3:6]).as_matrix()
    cfg = robot_ik(x[:, 0:3], R, x[:, 6:9], sol.robot)
    violations = []
    if not cfg.ok.all():
        violations.append(f"unreachable at {int((~cfg.ok).sum())} samples")
    thd, thdd, _, _ = (v.T for v in actuated_profile(sol.robot, x, xd, xdd))
    # Pinocchio's constrained inverse dynamics of all samples at once (the validator's,
    # tests/test_dynamics.py checks it against the per-state one); NaN at a parallel
    # singularity, where no torque is defined
    tau, _ = ClosedLoopDynamics(sol.robot).actuated_inverse_dynamics_batch(cfg.q, thd, thdd)
    if not np.isfinite(tau).all():
        violations.append(f"no torque defined (singular) at "
                          f"{int((~np.isfinite(tau).all(axis=1)).sum())} samples")
    lm = measure_limits(cfg, tau, cfg.theta, thd, thdd, sol.limits, times)
    violations += lm.violations
    return DenseCheck(ok=not violations, samples=n, max_torque_ratio=lm.max_torque_ratio,
                      max_velocity_ratio=lm.max_velocity_ratio,
                      max_acceleration_ratio=lm.max_acceleration_ratio,
                      min_margin=min(lm.min_margin_leg_type1, lm.min_margin_leg_type2,
                                     lm.min_margin_platform),
                      min_margin_leg_type1=lm.min_margin_leg_type1,
                      min_margin_leg_type2=lm.min_margin_leg_type2,
                      min_margin_platform=lm.min_margin_platform,
                      theta_range_ok=lm.theta_range_ok,
                      max_spherical_tilt=lm.max_spherical_tilt,
                      min_clearance=lm.min_clearance, violations=violations,
                      max_tcp_speed=lm.max_tcp_speed,
                      max_tcp_acceleration=lm.max_tcp_acceleration)


__all__ = ["NO_WORK", "DenseCheck", "Solution", "actuated_profile", "dense_check", "sample_cubic",
           "stretch_factors"]
