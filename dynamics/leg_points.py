"""The legs a person can touch, for power and force limiting (issue 70, docs/safety.md).

Every leg link is a rigid body, so its points' velocities are affine in their position
(v = v_o + omega x r) and the fastest point of a link is one of its vertices: a crank's
tip, a rod's two ends, the RU chain's body at D, E, F and P.  The links, by their URDF
names (``robot_description/urdf.py``; their names and vertices as data in
:mod:`sixplus3.robot_description.leg_links`), and the points that bound them:

===========  ===========================  ====================================
link         the issue's joints            its vertices (joint centres)
===========  ===========================  ====================================
``proximal`` crank A                      D (its base end A is fixed)
``body``     the RU chain's Ds2, Ds3       D, E, F, P
``crankB``   crank B                      G
``distalB``  the RUS rod's Ga, Gb          G, E
``crankC``   crank C                      H
``distalC``  the RUS rod's Ha, Hb          H, F
===========  ===========================  ====================================

The universal joints' crosses at D, G and H are points (their spheres of
``JOINT_SPHERE``), covered by those vertices.  A vertex is a joint centre shared by the
links that meet there, so its velocity, and its inverse mass (the same point Jacobian on
either link), does not depend on the link a contact lands on.  That the vertices also
bound the contact *energy* (where the inverse mass varies along the link too) is
checked, not assumed: tests/test_leg_pfl.py samples the links' interiors.

Here the Pinocchio derivation (the gate's): with S = [I; -J_pas^-1 J_act] the tree's
velocities per actuated rate and J_p a vertex's frame Jacobian, J_theta = J_p S, the
vertex moves at J_theta theta_dot and its inverse mass with the motors' torques held is
A = J_theta M^-1 J_theta^T (M the reduced inertia, rotors included).  The planner's
rows derive the velocity independently, from the closed-form IK in CasADi
(:mod:`sixplus3.planner.leg_rows`).
"""

from __future__ import annotations

import numpy as np

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics


def _frame(i: int, vertex: str) -> str:
    """The Pinocchio frame at leg i's vertex (a joint's frame or a closure's)."""
    return {"D": f"leg{i}_Ds2", "G": f"leg{i}_Ga", "H": f"leg{i}_Ha",
            "E": f"closedloop{3 * i}_A", "F": f"closedloop{3 * i + 1}_A",
            "P": f"leg{i}_P"}[vertex]


def vertex_jacobians(dyn: ClosedLoopDynamics, q: np.ndarray,
                     vertices: tuple[tuple[int, str], ...]
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position (n, k, 3) [m], J_theta (n, k, 3, 9) [m/rad], M (n, 9, 9)) of the
    ``vertices`` at the tree configurations q (n, nq): each vertex moves at J_theta
    theta_dot, and M is the reduced inertia (rotors included; module doc).  A state at
    a parallel singularity gets NaN."""
    import pinocchio as pin  # deferred: only where the legs are judged

    m, d = dyn.model, dyn.data
    q = np.asarray(q, dtype=float)
    n, k = len(q), len(vertices)
    zeros = np.zeros((n, 9))
    M = np.empty((n, 9, 9))
    dyn.actuated_inverse_dynamics_batch(q, zeros, zeros, inertia=M)
    _, _, X, _ = dyn.consistent_states_batch(q, zeros, zeros)
    S = np.zeros((n, m.nv, 9))
    act, pas = dyn._act, dyn._pas  # the tree's actuated and passive velocities
    S[:, act, np.arange(9)] = 1.0
    S[:, pas, :] = -X
    fids = [m.getFrameId(_frame(i, v)) for i, v in vertices]
    pos = np.full((n, k, 3), np.nan)
    Jp = np.full((n, 3 * k, m.nv), np.nan)
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    ok = np.isfinite(q).all(axis=1) & np.isfinite(S).all(axis=(1, 2))
    for t in np.flatnonzero(ok):
        pin.computeJointJacobians(m, d, q[t])
        pin.updateFramePlacements(m, d)
        for j, f in enumerate(fids):
            pos[t, j] = d.oMf[f].translation
            Jp[t, 3 * j:3 * j + 3] = pin.getFrameJacobian(m, d, f, world)[0:3]
    return pos, (Jp @ S).reshape(n, k, 3, 9), M


def vertex_rates(dyn: ClosedLoopDynamics, q: np.ndarray, theta_dot: np.ndarray,
                 vertices: tuple[tuple[int, str], ...]
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position (n, k, 3) [m], velocity (n, k, 3) [m/s], inverse mass A (n, k, 3, 3)
    [1/kg]) of the ``vertices`` at the tree configurations q (n, nq) moving at the
    actuated rates theta_dot (n, 9), with the motors' torques held (module doc).  A
    state at a parallel singularity gets NaN (its caller judges it unsafe)."""
    pos, Jth, M = vertex_jacobians(dyn, q, vertices)
    return (pos, *rates_from(Jth, M, theta_dot))


def rates_from(Jth: np.ndarray, M: np.ndarray, theta_dot: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """(velocity (n, k, 3), inverse mass (n, k, 3, 3)) from :func:`vertex_jacobians`'
    J_theta and M at the actuated rates theta_dot (n, 9)."""
    vel = np.einsum("nkij,nj->nki", Jth, np.asarray(theta_dot, dtype=float))
    with np.errstate(all="ignore"):
        Y = np.linalg.solve(M[:, None], np.swapaxes(Jth, 2, 3))  # M^-1 J_theta^T
    A = Jth @ Y
    return vel, 0.5 * (A + np.swapaxes(A, 2, 3))


__all__ = ["rates_from", "vertex_jacobians", "vertex_rates"]
