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

from sixplus3.dynamics.symbolic import rotvec_matrix


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


def tcp_rates_at(tool: Any, x: np.ndarray, xd: np.ndarray, u: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(speed (n,) [m/s], |acceleration| (n,) [m/s^2]) of the tool centre point at the
    states (n, 9) each."""
    G = np.array(tcp_function(tool).map(len(x))(np.asarray(x).T, np.asarray(xd).T,
                                               np.asarray(u).T))
    return np.sqrt(np.maximum(G[0], 0.0)), np.sqrt(np.maximum(G[1], 0.0))


__all__ = ["tcp_function", "tcp_rates_at", "tcp_rows"]
