"""The stop table a trajectory file carries (docs/safety.md, "Stopping along the path"):
for every sample k, the deceleration of the motion along the path that the torque
limits allow from there, so that a controller's stop is a table look-up, not an
optimisation.

Along the file's path theta(s) (s the file's time), a motion with path speed sd = ds/dt
has the joint rates theta' sd and the joint speed sigma = |theta'| sd.  A stop slows the
joint speed at sigma_dot = -beta |theta'_k| (beta [1/s]: the plan's speed at k lost in
1/beta seconds), which needs the joint accelerations -beta theta'_k + sd^2 theta''_perp,
theta''_perp the part of the path's second derivative across its tangent (the part along
it only changes how fast s runs, not the joints: a stop early in a plan that is still
speeding up must not inherit that speeding up).  So the torques are

    tau = -beta a_k + sd^2 b_k + g_k,   a_k = M_k theta'_k,
    b_k = tau_k - g_k - M_k t_k (t_k . theta''_k),  t_k = theta'_k / |theta'_k|

(M_k the reduced inertia, rotors included, g_k gravity, tau_k the file's torques: the
velocity torques and friction scale with sd^2 with them).  beta_k must keep every
joint's torque within ``torque_share`` of the limit both at full path speed (sd = 1) and
at rest (sd = 0), and the joint accelerations within their limit; where no deceleration
is within the share (the plan itself uses more), the one that needs the least torque.
A stop looks up each sample's beta as it passes it (the torque is affine in beta and in
sd^2, so the two ends of sd hold every path speed between).

The writer (:func:`sixplus3.control.gate.validation.validate_and_write`) computes it from
the gate's own configurations and torques and puts it in the header (``stop``); the gate
recomputes it from the file's samples and refuses (a defect: exit 2) a table that is
not the one the limits it is judged by give, within the writer's rounding:

- above it anywhere (a stop faster than the torque limits allow);
- below its floor anywhere: ``(1 - FLOOR_SLACK)`` times the recomputed entry.  A table
  that stops more slowly is not the file's choice: a zero entry never stops, a negative
  one turns a stop into a push, and a tiny one is a stop that takes the whole path
  (session 34's forged tables).  Every entry the writer puts there is the recomputed one
  rounded down to 6 significant digits (at most 1e-5 below it), so an honest file always
  passes;
- any entry that is not a finite number > 0, a table not of the file's length, or of
  another form or torque share (nothing reads one: a header entry nobody checks is not
  let through either).

The guard (interaction/contact/tables.py) never stops more slowly than its own
recomputation, whatever the file says.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sixplus3.control.gate.findings import finding
from sixplus3.control.report import Finding, ValidationReport
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.motion import Motion
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

#: The share of the torque limit a stop's feed-forward may use (the rest: the drive's
#: feedback).
TORQUE_SHARE = 0.95
#: The header's key.
HEADER_KEY = "stop"
#: The table's definition (the module doc's): the joint speed's deceleration along the
#: path.  A table of another form or torque share is refused (nothing reads one).
FORM = "joint-speed/1"
#: Relative slack of the gate's comparison (the file's samples are text; the writer's
#: table was computed from the same motion before it was written).
SLACK = 1e-6
#: The floor's relative slack below the recomputed table: the writer's rounding down to
#: 6 significant digits (1e-5 at most) and the samples' text, with margin.
FLOOR_SLACK = 5e-5
#: The table's range [1/s]: a stop within a second of plan time at the slowest; where
#: the plan barely moves the joints, the acceleration limit decides below the top.
BETA_RANGE = (1.0, 1e6)
#: Samples of the reduced inertia computed at a time (81 floats each).
CHUNK = 4096


def path_tables(robot: Robot, rep: ValidationReport
                ) -> tuple[np.ndarray, np.ndarray, Any]:
    """(M (n, 9, 9), g (n, 9), the configurations) at the report's samples: the reduced
    inertia and the gravity torques from Pinocchio at the gate's own poses."""
    assert rep.position is not None and rep.quaternion is not None and rep.psi is not None
    cfg = robot_ik(rep.position, rot.matrix_from_quat(rep.quaternion), rep.psi, robot,
                   platform_margins=False)
    n = len(rep.position)
    dyn = ClosedLoopDynamics(robot)
    M = np.empty((n, 9, 9))
    g = np.empty((n, 9))
    for i in range(0, n, CHUNK):
        sl = slice(i, min(n, i + CHUNK))
        m = len(range(*sl.indices(n)))
        Mi = np.empty((m, 9, 9))
        g[sl], _ = dyn.actuated_inverse_dynamics_batch(cfg.q[sl], np.zeros((m, 9)),
                                                       np.zeros((m, 9)), inertia=Mi)
        M[sl] = Mi
    return M, g, cfg


def beta_interval(a: np.ndarray, c: np.ndarray, cap: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (n,): the decelerations beta with |c - beta a| <= cap on every joint of
    each row (a joint with a = 0 bounds nothing: c alone decides there)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        e1, e2 = (c - cap) / a, (c + cap) / a
    lo_j = np.where(a > 0, e1, np.where(a < 0, e2, -np.inf))
    hi_j = np.where(a > 0, e2, np.where(a < 0, e1, np.inf))
    return (np.nan_to_num(lo_j, nan=-np.inf).max(axis=1),
            np.nan_to_num(hi_j, nan=np.inf).min(axis=1))


def path_deceleration(a: np.ndarray, b: np.ndarray, g: np.ndarray, theta_dot: np.ndarray,
                      torque: float, acceleration: float,
                      share: float = TORQUE_SHARE) -> np.ndarray:
    """beta (n,) [1/s]: the module doc's deceleration at every sample, from a = M theta'
    (n, 9), b (n, 9: across the path, :func:`across_path`) and g (n, 9), the planned
    rates (n, 9) and the torque and acceleration limits."""
    cap = share * torque
    n = len(a)
    lo = np.zeros(n)
    hi = np.full(n, np.inf)
    for c in (b + g, g):  # at full path speed, at rest
        lo_c, hi_c = beta_interval(a, c, cap)
        lo, hi = np.maximum(lo, lo_c), np.minimum(hi, hi_c)
    beta = hi.copy()
    none = hi < lo  # no deceleration within the share: the least torque one
    if none.any():
        beta[none] = least_torque_beta(a[none], (b[none] + g[none], g[none]))
    vmax = np.abs(theta_dot).max(axis=1)
    with np.errstate(divide="ignore"):
        beta = np.minimum(beta, acceleration / np.maximum(vmax, 1e-9))
    # at least 1/s (a stop within a second of plan time); at most 1e6/s (where the plan
    # barely moves the joints, the acceleration limit above decides)
    return np.clip(beta, *BETA_RANGE)


def least_torque_beta(a: np.ndarray, cs: tuple[np.ndarray, ...],
                      lo: float = BETA_RANGE[0], hi: float = BETA_RANGE[1],
                      steps: int = 200) -> np.ndarray:
    """beta (n,) in [lo, hi] minimising max over the joints and over ``cs`` of
    |c - beta a| (rows (n, 9) each): a maximum of absolute values of affine functions,
    convex in beta, so unimodal in log beta too; found by a ternary search in log beta
    (``steps`` rounds: the bracket shrinks by (2/3)^steps)."""
    def worst(beta: np.ndarray) -> np.ndarray:
        return np.max([np.abs(c - beta[:, None] * a).max(axis=1) for c in cs], axis=0)

    x0 = np.full(len(a), np.log(lo))
    x1 = np.full(len(a), np.log(hi))
    for _ in range(steps):
        m0, m1 = x0 + (x1 - x0) / 3.0, x1 - (x1 - x0) / 3.0
        left = worst(np.exp(m0)) <= worst(np.exp(m1))
        x1 = np.where(left, m1, x1)
        x0 = np.where(left, x0, m0)
    return np.exp(0.5 * (x0 + x1))  # type: ignore[no-any-return]


def across_path(a: np.ndarray, b: np.ndarray, theta_dot: np.ndarray,
                theta_ddot: np.ndarray) -> np.ndarray:
    """b_k (n, 9) of the module doc: the torques tau_k - g_k (``b``) without the inertial
    torque of the path's acceleration along its tangent, M t (t . theta''), from
    a = M theta' (a / |theta'| = M t)."""
    v2 = np.einsum("ni,ni->n", theta_dot, theta_dot)
    along = np.where(v2 > 1e-12, np.einsum("ni,ni->n", theta_dot, theta_ddot)
                     / np.maximum(v2, 1e-12), 0.0)
    return b - a * along[:, None]


def stop_table(robot: Robot, rep: ValidationReport, motion: Motion,
               limits: Limits) -> np.ndarray:
    """beta (n,) of a validated motion (its report's poses and Pinocchio torques)."""
    assert rep.tau is not None
    theta_dot, theta_ddot = motion.theta_dot, motion.theta_ddot
    M, g, _ = path_tables(robot, rep)
    a = np.einsum("nij,nj->ni", M, theta_dot)
    b = across_path(a, rep.tau - g, theta_dot, theta_ddot)
    return path_deceleration(a, b, g, theta_dot, limits.torque, limits.acceleration)


def stop_runs(beta: np.ndarray, vnorm: np.ndarray, rate: float,
              max_time: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """(stop time (n,) [s], path position at rest (n,) [samples]) of a stop begun at
    each sample at the plan's speed, by the table ``beta`` alone, as the guard runs it
    (interaction/contact/guard.py): each tick the joint speed sigma = sd |theta'(s)| loses
    beta(s) |theta'(s)| / rate, the path advances by sd, and sd follows from sigma at the
    new place (``vnorm`` (n,) = |theta'| per sample).  The guard may stop faster (it
    also takes what the torque allows at the stop's own speed), never slower.  A stop
    that reaches the end of the path ends there (the motion is at rest there)."""
    n = len(beta)
    s = np.arange(n, dtype=float)
    sd = np.where(vnorm > 1e-9, 1.0, 0.0)
    time_ = np.zeros(n)
    dt = 1.0 / rate
    grid = np.arange(n, dtype=float)
    for _ in range(int(max_time * rate)):
        moving = sd > 0.0
        if not moving.any():
            break
        k = np.minimum(np.floor(s).astype(int), n - 1)
        v0 = np.interp(s, grid, vnorm)
        sigma = np.maximum(0.0, sd * v0 - beta[k] * v0 * dt)
        s = np.where(moving, np.minimum(n - 1.0, s + rate * dt * sd), s)
        v1 = np.interp(s, grid, vnorm)
        new = np.where((v1 > 1e-9) & (sigma > 0.0), sigma / np.maximum(v1, 1e-300), 0.0)
        new[s >= n - 1.0] = 0.0
        time_ += np.where(moving, dt, 0.0)
        sd = np.where(moving, new, sd)
    return time_, s


def header_entry(beta: np.ndarray) -> dict[str, Any]:
    """The header's ``stop``: the table rounded down to 6 significant digits (a file
    never claims more than was computed)."""
    e = np.floor(np.log10(np.maximum(beta, 1e-300)))
    scale = 10.0 ** (5 - e)
    down = np.floor(beta * scale) / scale
    return {"torque_share": TORQUE_SHARE, "unit": "1/s", "form": FORM,
            "deceleration": [float(f"{x:.6g}") for x in down]}


def stop_check(rep: ValidationReport, robot: Robot, motion: Motion, limits: Limits,
               entry: object) -> tuple[np.ndarray | None, list[Finding]]:
    """(the file's table if it holds, findings): the header's ``stop`` against the table
    recomputed from the samples (module doc: neither above it nor below its floor).  No
    entry: (None, [])."""
    t = motion.t
    if entry is None:
        return None, []

    def defect(what: str) -> list[Finding]:
        f = finding(f"stop table ({what})", "defect", "", 0.0, np.ones(1), np.ones(1),
                    t[:1], ["header"])
        return [f] if f else []

    if not isinstance(entry, dict):
        return None, defect("the header's form: a mapping")
    if entry.get("torque_share") != TORQUE_SHARE or entry.get("form") != FORM:
        return None, defect(f"its definition: form {FORM!r} at torque share "
                            f"{TORQUE_SHARE:g} only")
    table = entry.get("deceleration")
    if (not isinstance(table, list) or len(table) != len(t)
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                       for x in table)):
        return None, defect(f"the header's form: {len(t)} numbers")
    claimed = np.asarray(table, dtype=float)
    good = np.isfinite(claimed) & (claimed > 0.0)
    f = finding("stop table (a deceleration that is not a finite number > 0: a stop that "
                "never stops, or pushes)", "defect", "1/s", 0.0, np.where(good, -1.0, 1.0),
                np.nan_to_num(claimed, nan=0.0), t, ["path"])
    if f:
        return None, [f]
    if rep.tau is None or rep.position is None:
        return None, []
    mine = stop_table(robot, rep, motion, limits)
    over = claimed - mine * (1.0 + SLACK)
    f = finding("stop table (a deceleration the torque limits do not allow)", "defect",
                "1/s", 0.0, over, claimed, t, ["path"])
    if f:
        return None, [f]
    floor = mine * (1.0 - FLOOR_SLACK)
    f = finding(f"stop table (a stop slower than the limits give: below {1 - FLOOR_SLACK:g} "
                "of the recomputed deceleration)", "defect", "1/s", 0.0, floor - claimed,
                claimed, t, ["path"])
    if f:
        return None, [f]
    return claimed, []


__all__ = ["BETA_RANGE", "FLOOR_SLACK", "HEADER_KEY", "TORQUE_SHARE", "across_path",
           "beta_interval", "header_entry", "least_torque_beta", "path_deceleration", "path_tables",
           "stop_check", "stop_runs", "stop_table"]
