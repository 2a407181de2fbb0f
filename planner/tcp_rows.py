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
def leg_pfl_function(geom: RobotGeometry, mode: AssemblyMode, leg: int,
                     vertices: tuple[str, ...]) -> ca.Function:
    """CasADi function (x, xd, c) -> (v_j^T C_j v_j for each of leg ``leg``'s
    ``vertices``, D, E, F, G, H or P of :mod:`sixplus3.dynamics.leg_points`), ``c`` the
    k matrices' 9 entries each, column-major, one after the other.  Each vertex's
    position is the closed-form IK's (:func:`sixplus3.dynamics.symbolic_ik.ik_expressions`,
    computed once for the leg's vertices), its velocity that position's derivative
    along xd: independent of the gate's Pinocchio frame Jacobians through the
    closures."""
    k = len(vertices)
    x, xd, c = ca.SX.sym("x", 9), ca.SX.sym("xd", 9), ca.SX.sym("c", 9 * k)
    links = ik_expressions(geom, mode, x)["links"]
    out = []
    for j, vertex in enumerate(vertices):
        link, end = _VERTEX_IN_LINKS[vertex]
        v = ca.jtimes(links[6 * leg + link][end], x, xd)
        out.append(ca.dot(v, ca.reshape(c[9 * j:9 * j + 9], 3, 3) @ v))
    return ca.Function(f"pfl_leg{leg}", [x, xd, c], [ca.vertcat(*out)], ["x", "xd", "c"],
                       ["ratio"])


def pfl_rows(fn: ca.Function, points: tuple[Any, Any], C: Any) -> Any:
    """The rows v^T C_k v at every point of ``points`` (x, xd; 9 x n each), C (9 k x n)
    each point's k matrices (a parameter of the NLP), as one column k n (the k values of
    the first point, then the next's)."""
    n = points[0].shape[1]
    return ca.vec(fn.map(n)(points[0], points[1], C))


def pfl_ratios_at(fn: ca.Function, x: np.ndarray, xd: np.ndarray, C: np.ndarray
                  ) -> np.ndarray:
    """v^T C v of ``fn`` (:func:`pfl_function`: C (n, 3, 3), gives (n,);
    :func:`leg_pfl_function`: C (n, k, 3, 3), gives (n, k)) at the states (n, 9)."""
    C = np.asarray(C, dtype=float)
    c = np.swapaxes(C, -1, -2).reshape(len(C), -1)  # column-major, one after the other
    out = np.array(fn.map(len(x))(np.asarray(x).T, np.asarray(xd).T, c.T))
    return out.T if C.ndim == 4 else out.ravel()


def tcp_rates_at(tool: Any, x: np.ndarray, xd: np.ndarray, u: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(speed (n,) [m/s], |acceleration| (n,) [m/s^2]) of the tool centre point at the
    states (n, 9) each."""
    G = np.array(tcp_function(tool).map(len(x))(np.asarray(x).T, np.asarray(xd).T,
                                               np.asarray(u).T))
    return np.sqrt(np.maximum(G[0], 0.0)), np.sqrt(np.maximum(G[1], 0.0))


__all__ = ["leg_pfl_function", "pfl_function", "pfl_ratios_at", "pfl_rows", "tcp_function",
           "tcp_rates_at", "tcp_rows"]
