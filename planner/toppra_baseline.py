"""TOPP-RA on a fixed geometric path in minimal coordinates: baseline and certificate.

The path is x(s), s in [0, 1] (a cubic spline through samples).  One second-order
constraint carries the actuator torques, the actuated accelerations and the squared
actuated velocities, all of the form a(s) s_ddot + b(s) s_dot^2 + c(s) along a path:

    inv_dyn(x, xd, xdd) = [tau(x, xd, xdd); theta_ddot(x, xd, xdd); theta_dot(x, xd)^2]

with tau from the same CasADi model as the planner (which agrees with Pinocchio).
Parametrisation: ParametrizeConstAccel (docs/libraries.md: the spline parametriser violated
limits by ~14%); callers re-check the result.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import toppra as ta
import toppra.algorithm as algo
import toppra.constraint as constraint
from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate

from sixplus3.errors import InfeasibleTaskError, InputError
from sixplus3.planner.solution import actuated_profile
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

if TYPE_CHECKING:
    from sixplus3.planner.solution import Solution

PATH_SCALE = 0.1


@dataclass(frozen=True)
class ToppraResult:
    duration: float  # [s]
    gridpoints: int
    t: np.ndarray  # (m,) sample times [s]
    x: np.ndarray  # (m, 9) path samples at those times


def arc_length_parameter(xs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ss, xs) with ss in [0, 1] proportional to the path length in x (samples that do
    not move are dropped): a regular path, as TOPP-RA needs (a path sampled from a motion
    that starts at rest has zero speed in normalised time)."""
    step = np.linalg.norm(np.diff(xs, axis=0), axis=1)
    keep = np.r_[True, step > 1e-9]
    xs = xs[keep]
    ss = np.r_[0.0, np.cumsum(step[step > 1e-9])]
    return ss / ss[-1], xs


def toppra_time(robot: Robot, xs: np.ndarray, limits: Limits, gridpoints: int = 400,
                samples: int = 400) -> ToppraResult:
    """Time-optimal parametrisation for ``robot`` of the path through the samples xs
    (m, 9), at rest at both ends, re-parametrised by arc length."""
    traj = toppra_trajectory(robot, xs, limits, gridpoints)
    t = np.linspace(0.0, traj.duration, samples)
    return ToppraResult(float(traj.duration), gridpoints, t, traj(t))


def toppra_trajectory(robot: Robot, xs: np.ndarray, limits: Limits,
                      gridpoints: int = 400) -> Any:
    """TOPP-RA's trajectory object (``traj(t, order)``) for the path through the samples
    xs (m, 9), at rest at both ends; raises InfeasibleTaskError (limit "toppra") if it
    finds none."""
    ss, xs = arc_length_parameter(np.asarray(xs, dtype=float))
    # Path parameter in [0, PATH_SCALE] rather than [0, 1]: on a unit path the platform's
    # tiny inertia makes the admissible path accelerations ~1e4 and TOPP-RA's Seidel LP
    # returned NaN controllable sets (measured); a time-like scale keeps them O(1..100).
    ss = ss * PATH_SCALE
    path = ta.SplineInterpolator(ss, xs)

    eye = np.eye(9)
    zero = np.zeros((9, 9))
    F = np.block([[eye, zero, zero], [-eye, zero, zero], [zero, eye, zero],
                  [zero, -eye, zero], [zero, zero, eye]])
    g = np.r_[np.full(18, limits.torque), np.full(18, limits.acceleration),
              np.full(9, limits.velocity**2)]
    pc = _GridSecondOrderConstraint(grid_inv_dyn(robot), F, g, dof=9)
    grid = np.linspace(ss[0], ss[-1], gridpoints)
    inst = algo.TOPPRA([pc], path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    traj = inst.compute_trajectory(0.0, 0.0)
    if traj is None:
        raise InfeasibleTaskError("TOPP-RA found no feasible parametrisation of the path",
                                  None, "toppra", value=None,
                                  valid="a path with a time parametrisation within the limits")
    return traj


def grid_inv_dyn(robot: Robot) -> Any:
    """TOPP-RA's inverse dynamics over a grid: (q, qd, qdd), (m, 9) each, to the (m, 27)
    rows [tau; theta_ddot; theta_dot^2], in one mapped call of the planner's compiled
    profile function (:func:`planner.solution.actuated_profile`)."""

    def inv_dyn(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        thd, thdd, tau, _ = actuated_profile(robot, q, qd, qdd)
        return np.vstack([tau, thdd, thd**2]).T

    return inv_dyn


class _GridSecondOrderConstraint(constraint.SecondOrderConstraint):
    """TOPP-RA's second-order constraint (interpolation discretisation, constant F and
    g) with the inverse dynamics evaluated over the whole grid at once.

    ``SecondOrderConstraint.compute_constraint_params`` calls ``inv_dyn`` three times
    per grid point from Python (900 CasADi calls for a 300-point segment, about half of
    the baseline's time, BENCHMARKS.md); this override computes the same a, b, c, F, g
    arrays with one call per term on (gridpoints, dof) arrays, and hands them to the same
    conversion (``canlinear_colloc_to_interpolate``).  ``grid_inv_dyn(q, qd, qdd)`` maps
    (m, dof) arrays to (m, k).
    """

    def __init__(self, grid_inv_dyn: Any, F: np.ndarray, g: np.ndarray, dof: int) -> None:
        super().__init__(lambda q, qd, qdd: grid_inv_dyn(q[None], qd[None], qdd[None])[0],
                         lambda q: F, lambda q: g, dof,
                         discretization_scheme=constraint.DiscretizationType.Interpolation)
        self._grid_inv_dyn, self._F, self._g = grid_inv_dyn, F, g

    def compute_constraint_params(self, path: Any, gridpoints: np.ndarray) -> Any:
        if path.dof != self.dof:
            raise InputError(f"constraint dof {self.dof} != path dof {path.dof}",
                             value=path.dof, valid=str(self.dof))
        p, ps, pss = path(gridpoints), path(gridpoints, 1), path(gridpoints, 2)
        zero = np.zeros_like(p)
        c = self._grid_inv_dyn(p, zero, zero)
        a = self._grid_inv_dyn(p, zero, ps) - c
        b = self._grid_inv_dyn(p, ps, pss) - c
        m = len(gridpoints)
        F = np.repeat(self._F[None], m, axis=0)
        g = np.repeat(self._g[None], m, axis=0)
        return canlinear_colloc_to_interpolate(a, b, c, F, g, None, None, gridpoints)


def rest_splits(sol: Solution, rel: float = 1e-3) -> np.ndarray:
    """Times [s] where a planned motion comes to rest: its ends and every interior node
    with |x_dot| <= rel * max |x_dot|.  A path that stops and reverses there (a tilt and
    back) has a cusp, where no spline through its samples is the same path; TOPP-RA is
    run on each rest-to-rest piece instead."""
    speed = np.linalg.norm(sol.xd, axis=1)
    stops = np.flatnonzero(speed <= rel * speed.max())
    return np.unique(np.r_[0.0, sol.t[stops], sol.t[-1]])


def toppra_along(sol: Solution, limits: Limits | None = None, gridpoints: int = 800,
                 samples: int = 201,
                 cranks: float | np.ndarray | None = None) -> float:
    """TOPP-RA duration [s] along the geometric path of a planned motion (``sol``: a
    :class:`planner.solution.Solution`), summed over its rest-to-rest pieces.

    With ``cranks`` (a scalar or (3,), [rad]) the crank angles are replaced by these constants: the
    redundancy-less baseline on the same platform path.  ``limits`` default to the plan's.
    """
    limits = limits or sol.limits
    total = 0.0
    splits = rest_splits(sol)
    for t0, t1 in zip(splits[:-1], splits[1:], strict=True):
        x, _, _ = sol.sample(np.linspace(t0, t1, samples))
        if cranks is not None:
            x = x.copy()
            x[:, 6:9] = cranks
        total += toppra_time(sol.robot, x, limits, gridpoints=gridpoints).duration
    return total
