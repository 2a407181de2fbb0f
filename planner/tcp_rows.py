"""The tool centre point's speed and acceleration as rows of the NLP.

The tool centre point is p_tcp(x) = p + R(r) t (``robot.tool.xyz`` = t in the platform
frame, R(r) the rotation vector's matrix), so along the NLP's cubic states

    v = (d p_tcp / d x) xd,      a = (d v / d x) xd + (d p_tcp / d x) u

exactly (CasADi's derivatives of that expression).  :func:`tcp_function` gives
(|v|^2, |a|^2); the NLP bounds them, divided by the limits squared (parameters of the
NLP), at every node and every interval's midpoint, like the joint limits.  A task
without platform-space limits gets no such rows (the NLP is the same as before).

:func:`sixplus3.kinematics.tcp.tcp_velocity` is the independent derivation the tests
compare with: the actuated rates through the inverse of the IK Jacobian and the
platform's twist.
"""

from __future__ import annotations

import functools
from typing import Any

import casadi as ca
import numpy as np

from sixplus3.dynamics.symbolic_ik import ik_expressions, rotvec_matrix
from sixplus3.robot_description.assembly import AssemblyMode
from sixplus3.robot_description.robot_geometry import RobotGeometry


@functools.lru_cache(maxsize=8)
def _tcp_function(tool: tuple[float, float, float]) -> ca.Function:
    x, xd, u = ca.SX.sym("x", 9), ca.SX.sym("xd", 9), ca.SX.sym("u", 9)
    p_tcp = x[0:3] + rotvec_matrix(x[3:6]) @ ca.DM(tool)
    J = ca.jacobian(p_tcp, x)
    v = J @ xd
    a = ca.jtimes(v, x, xd) + J @ u
    return ca.Function("tcp_rates", [x, xd, u], [ca.vertcat(ca.dot(v, v), ca.dot(a, a))],
                       ["x", "xd", "u"], ["v2_a2"])


def tcp_function(tool: Any) -> ca.Function:
    """CasADi function (x, xd, u) (9 each) -> (|v|^2 [m^2/s^2], |a|^2 [m^2/s^4]) of the
    tool centre point at ``tool`` (3,) [m] in the platform frame."""
    t = tuple(float(c) for c in np.asarray(tool, dtype=float).ravel())
    if len(t) != 3:
        raise ValueError(f"the tool centre point has 3 coordinates, not {len(t)}")
    return _tcp_function(t)  # type: ignore[arg-type]


def tcp_rows(fn: ca.Function, points: tuple[Any, Any, Any], inv_v2: Any,
             inv_a2: Any) -> Any:
    """The rows (|v|^2 / v_max^2, |a|^2 / a_max^2) at every point of ``points`` (x, xd,
    u; 9 x n each), as one column 2 n (the speeds, then the accelerations)."""
    n = points[0].shape[1]
    G = fn.map(n)(*points)
    return ca.vertcat(ca.vec(G[0, :]) * inv_v2, ca.vec(G[1, :]) * inv_a2)


@functools.lru_cache(maxsize=8)
def _pfl_function(tool: tuple[float, float, float]) -> ca.Function:
    x, xd, c = ca.SX.sym("x", 9), ca.SX.sym("xd", 9), ca.SX.sym("c", 9)
    p_tcp = x[0:3] + rotvec_matrix(x[3:6]) @ ca.DM(tool)
    v = ca.jacobian(p_tcp, x) @ xd
    C = ca.reshape(c, 3, 3)
    return ca.Function("pfl_energy", [x, xd, c], [ca.dot(v, C @ v)], ["x", "xd", "c"],
                       ["ratio"])


def pfl_function(tool: Any) -> ca.Function:
    """CasADi function (x, xd, c) -> v^T C v: the tool centre point's velocity v at the
    state (x, xd) in the quadratic form C (``c``: its 9 entries, column-major) of
    :func:`sixplus3.planner.pfl.pfl_matrices`, the worst contact energy over every
    direction and region against its limit (power and force limiting)."""
    t = tuple(float(c) for c in np.asarray(tool, dtype=float).ravel())
    if len(t) != 3:
        raise ValueError(f"the tool centre point has 3 coordinates, not {len(t)}")
    return _pfl_function(t)  # type: ignore[arg-type]


#: Each leg vertex's place among the links of ``ik_expressions`` (per leg: AD, DP, BG,
#: GE, CH, HF): (link, end).
_VERTEX_IN_LINKS = {"D": (0, 1), "P": (1, 1), "G": (2, 1), "E": (3, 1), "H": (4, 1),
                    "F": (5, 1)}


@functools.lru_cache(maxsize=64)
def vertex_pfl_function(geom: RobotGeometry, mode: AssemblyMode, leg: int,
                        vertex: str) -> ca.Function:
    """CasADi function (x, xd, c) -> v^T C v for the leg vertex ``vertex`` (D, E, F, G,
    H or P of :mod:`sixplus3.dynamics.leg_points`) of leg ``leg``: its position from
    the closed-form IK (:func:`sixplus3.dynamics.symbolic_ik.ik_expressions`), its
    velocity that position's derivative along xd, independently of the gate's
    Pinocchio frame Jacobians through the closures."""
    x, xd, c = ca.SX.sym("x", 9), ca.SX.sym("xd", 9), ca.SX.sym("c", 9)
    link, end = _VERTEX_IN_LINKS[vertex]
    p = ik_expressions(geom, mode, x)["links"][6 * leg + link][end]
    v = ca.jacobian(p, x) @ xd
    C = ca.reshape(c, 3, 3)
    return ca.Function(f"pfl_leg{leg}_{vertex}", [x, xd, c], [ca.dot(v, C @ v)],
                       ["x", "xd", "c"], ["ratio"])


def pfl_rows(fn: ca.Function, points: tuple[Any, Any], C: Any) -> Any:
    """The rows v^T C_k v at every point of ``points`` (x, xd; 9 x n each), C (9 x n)
    each point's matrix (a parameter of the NLP), as one column n."""
    n = points[0].shape[1]
    return ca.vec(fn.map(n)(points[0], points[1], C))


def pfl_ratios_at(fn: ca.Function, x: np.ndarray, xd: np.ndarray, C: np.ndarray
                  ) -> np.ndarray:
    """(n,) v^T C v of ``fn`` (:func:`pfl_function`, :func:`vertex_pfl_function`) at the
    states (n, 9) with C (n, 3, 3)."""
    c = np.asarray(C, dtype=float).transpose(0, 2, 1).reshape(len(C), 9)  # column-major
    return np.array(fn.map(len(x))(np.asarray(x).T, np.asarray(xd).T, c.T)).ravel()


def tcp_rates_at(tool: Any, x: np.ndarray, xd: np.ndarray, u: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(speed (n,) [m/s], |acceleration| (n,) [m/s^2]) of the tool centre point at the
    states (n, 9) each."""
    G = np.array(tcp_function(tool).map(len(x))(np.asarray(x).T, np.asarray(xd).T,
                                               np.asarray(u).T))
    return np.sqrt(np.maximum(G[0], 0.0)), np.sqrt(np.maximum(G[1], 0.0))


__all__ = ["pfl_function", "pfl_ratios_at", "pfl_rows", "tcp_function", "tcp_rates_at",
           "tcp_rows", "vertex_pfl_function"]
