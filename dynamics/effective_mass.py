"""The robot's effective (reflected) mass at the platform point, and power and force
limiting by ISO/TS 15066's two-body model (docs/safety.md).

With theta_dot = J (v, omega, psi_dot) (:func:`sixplus3.kinematics.robot.ik_jacobian`)
and M the reduced 9 x 9 inertia in the actuated coordinates (rotors included), the
platform-space inertia is Lambda = J^T M J.  A point at r from the platform centre
(the tool centre point) moves at v_p = P (v, omega, psi_dot), P = [I, -[r]x, 0], so its
inverse mass matrix is A = P Lambda^-1 P^T = P J^-1 M^-1 J^-T P^T (3 x 3) and its
effective mass along a unit direction u is m_u = 1 / (u^T A u), with the motors' torques
held (what a contact within a few milliseconds meets: the drives cannot react sooner).

Power and force limiting.  A contact along n at the point's velocity v transfers
E_n = 1/2 mu_n (v.n)^2, mu_n = (1/m_n + 1/m_H)^-1 (m_H the body region's mass), which
must stay within F_max^2 / (2 k).  Over every direction n (|n| = 1),

    max_n (v.n)^2 / (n^T A n + 1/m_H) = v^T (A + I/m_H)^-1 v

(a generalised Rayleigh quotient, Cauchy-Schwarz), so the worst direction's energy is
E = 1/2 v^T (A + I/m_H)^-1 v: the whole condition in closed form, with no search over
directions and no assumption that the worst one is the direction of motion.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InputError
from sixplus3.kinematics.robot import RobotConfig
from sixplus3.kinematics.robot_fk import ik_jacobian
from sixplus3.robot_description.body_regions import BodyRegion

#: An inverse mass's eigenvalues below this share of its largest are directions the
#: point cannot move in (a crank's tip: only along its circle); the gate's energy and
#: the planner's rows both take them so.
RCOND = 1e-9


def point_map(r: np.ndarray) -> np.ndarray:
    """(n, 3, 9) P: the point's velocity from (v, omega, psi_dot), r (n, 3) [m] the point
    minus the platform centre (base frame)."""
    r = np.atleast_2d(np.asarray(r, dtype=float))
    n = len(r)
    P = np.zeros((n, 3, 9))
    P[:, :, 0:3] = np.eye(3)
    # omega x r = -[r]x omega
    P[:, 0, 4], P[:, 0, 5] = r[:, 2], -r[:, 1]
    P[:, 1, 3], P[:, 1, 5] = -r[:, 2], r[:, 0]
    P[:, 2, 3], P[:, 2, 4] = r[:, 1], -r[:, 0]
    return P


def inverse_mass(J: np.ndarray, M: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(n, 3, 3) A = P J^-1 M^-1 J^-T P^T (module doc): J (n, 9, 9) the IK Jacobian, M
    (n, 9, 9) the reduced inertia in the actuated coordinates, r (n, 3) [m]."""
    Jinv = np.linalg.inv(J)
    PJ = point_map(r) @ Jinv  # (n, 3, 9)
    X = np.linalg.solve(M, np.swapaxes(PJ, 1, 2))  # M^-1 (P J^-1)^T
    A = PJ @ X
    return 0.5 * (A + np.swapaxes(A, 1, 2))


def point_jacobian(dyn: ClosedLoopDynamics, cfg: RobotConfig, point: Any
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(J_p (n, 3, 9) [m/rad], M (n, 9, 9)): the platform point ``point`` ((3,) in the
    platform frame [m]) moves at J_p theta_dot (J_p = P J^-1, module doc); M the reduced
    inertia in the actuated coordinates (rotors included), from Pinocchio."""
    n = len(cfg.q)
    M = np.empty((n, 9, 9))
    dyn.actuated_inverse_dynamics_batch(cfg.q, np.zeros((n, 9)), np.zeros((n, 9)),
                                        inertia=M)
    r = np.einsum("nij,j->ni", cfg.rotation, np.asarray(point, dtype=float))
    return point_map(r) @ np.linalg.inv(ik_jacobian(cfg)), M


def point_inverse_mass(dyn: ClosedLoopDynamics, cfg: RobotConfig,
                       at_tool: bool = True, point: Any = None) -> np.ndarray:
    """(n, 3, 3) the inverse mass matrix of the tool centre point (``at_tool``; the
    platform centre otherwise; or ``point``, (3,) in the platform frame [m]) at the
    configurations ``cfg``, from Pinocchio's reduced inertia (rotors included) and the
    analytic IK Jacobian."""
    tool = np.asarray(point if point is not None else
                      dyn.robot.tool.xyz if (at_tool and dyn.robot is not None)
                      else (0.0, 0.0, 0.0), dtype=float)
    PJ, M = point_jacobian(dyn, cfg, tool)
    X = np.linalg.solve(M, np.swapaxes(PJ, 1, 2))  # M^-1 (P J^-1)^T
    A = PJ @ X
    return 0.5 * (A + np.swapaxes(A, 1, 2))


def link_inverse_mass(dyn: ClosedLoopDynamics, q: np.ndarray, joint: str,
                      point: np.ndarray) -> np.ndarray:
    """(3, 3) the inverse mass matrix, with the motors' torques held, of a point fixed
    to the link that ``joint`` (a joint of the tree, e.g. ``leg0_Ds2``) moves, at the
    tree configuration ``q``; ``point`` (3,) in the base frame [m].  With G = dv/dtheta_dot
    (the closures, :meth:`ClosedLoopDynamics.G`), the point's Jacobian J_p in the tree's
    velocities (Pinocchio's joint Jacobian, shifted to the point) and M the reduced
    inertia (rotors included): A = J_p G M^-1 G^T J_p^T, the leg's counterpart of
    :func:`point_inverse_mass` (issue 70: the legs a person can touch)."""
    import pinocchio as pin  # deferred: only where a leg's mass is asked for

    m, d = dyn.model, dyn.data
    q = np.asarray(q, dtype=float)
    jid = m.getJointId(joint)
    if jid >= m.njoints:
        raise InputError(f"no joint {joint!r} in the robot's tree", value=joint,
                         valid="a joint name, e.g. leg0_Ds2")
    pin.computeJointJacobians(m, d, q)
    J6 = pin.getJointJacobian(m, d, jid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    r = np.asarray(point, dtype=float) - d.oMi[jid].translation
    Jp = J6[0:3] - _skew(r) @ J6[3:6]  # v_p = v_o + omega x r
    M = np.empty((1, 9, 9))
    dyn.actuated_inverse_dynamics_batch(q[None], np.zeros((1, 9)), np.zeros((1, 9)),
                                        inertia=M)
    JG = Jp @ dyn.G(q)  # (3, 9)
    A = JG @ np.linalg.solve(M[0], JG.T)
    return np.asarray(0.5 * (A + A.T))


def _skew(r: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def effective_mass(A: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(n,) the effective mass [kg] along the unit direction(s) u ((3,) or (n, 3))."""
    u = np.asarray(u, dtype=float)
    u = u / np.linalg.norm(u, axis=-1, keepdims=True)
    return 1.0 / np.einsum("...i,...ij,...j->...", u, A, u)


def _worst_y(A: np.ndarray, v: np.ndarray, region: BodyRegion) -> np.ndarray:
    """(n, 3) y = (A + I/m_H)^+ v (a pseudo-inverse, :data:`RCOND`): the worst
    direction's vector (:func:`worst_direction`)."""
    A = np.asarray(A, dtype=float)
    v = np.asarray(v, dtype=float)
    B = A + np.eye(3) / region.mass
    with np.errstate(all="ignore"):
        return np.einsum("nij,nj->ni", np.linalg.pinv(B, rcond=RCOND, hermitian=True), v)


def worst_normal(A: np.ndarray, v: np.ndarray, region: BodyRegion) -> np.ndarray:
    """(n, 3) the unit direction n* of the worst contact with ``region`` of points with
    inverse mass A (n, 3, 3) moving at v (n, 3) (:func:`worst_direction`; NaN at
    rest)."""
    y = _worst_y(A, v, region)
    with np.errstate(all="ignore"):
        return y / np.linalg.norm(y, axis=1, keepdims=True)


def worst_direction(A: np.ndarray, v: np.ndarray, region: BodyRegion
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(energy (n,) [J], effective mass (n,) [kg]) of the worst contact with ``region``
    of points with inverse mass A (n, 3, 3) moving at v (n, 3): E = 1/2 v^T (A +
    I/m_H)^-1 v (module doc), along n* ~ (A + I/m_H)^-1 v, and 1 / n*^T A n* (inf at
    rest).  A pseudo-inverse (:data:`RCOND`): a crank's tip moves along one line only
    (A of rank 1) and a clamped region has 1/m_H = 0; v lies in A's range (v = J
    theta_dot, A = J M^-1 J^T), so the energy is finite."""
    A = np.asarray(A, dtype=float)
    v = np.asarray(v, dtype=float)
    y = _worst_y(A, v, region)
    with np.errstate(all="ignore"):
        u = y / np.linalg.norm(y, axis=1, keepdims=True)
        mass = 1.0 / np.einsum("ni,nij,nj->n", u, A, u)
    return 0.5 * np.einsum("ni,ni->n", v, y), mass


def contact_energy(A: np.ndarray, v: np.ndarray, region: BodyRegion) -> np.ndarray:
    """(n,) the largest energy [J] a contact with ``region`` along any direction could
    take from the point moving at v (n, 3): 1/2 v^T (A + I/m_H)^-1 v (module doc)."""
    return worst_direction(A, v, region)[0]


def pfl_ratio(A: np.ndarray, v: np.ndarray, regions: Sequence[BodyRegion]
              ) -> tuple[np.ndarray, np.ndarray]:
    """(ratio (n,), index of the worst region (n,)): each point's worst contact energy
    over the regions against what that region's spring can hold at its limit,
    F_max^2 / (2 k).  PFL holds where ratio <= 1 (the force then <= F_max: force and
    energy go as the square root of each other)."""
    ratios = np.stack([contact_energy(A, v, r) / r.energy for r in regions])
    return ratios.max(axis=0), ratios.argmax(axis=0)


def worst_speed(A: np.ndarray, region: BodyRegion) -> np.ndarray:
    """(n,) the largest speed [m/s] in any direction that keeps every contact with
    ``region`` within its limit: F_max sqrt(lambda_min(A + I/m_H) / k)."""
    lam = np.linalg.eigvalsh(A + np.eye(3) / region.mass)[:, 0]
    return region.transient_force * np.sqrt(lam / region.stiffness)


__all__ = ["RCOND", "contact_energy", "effective_mass", "inverse_mass", "link_inverse_mass",
           "pfl_ratio", "point_inverse_mass", "point_jacobian", "point_map",
           "worst_direction", "worst_normal", "worst_speed"]
