"""The walls' slacks of platform poses, compiled (numba): the same numbers as the gate's
own checks composed (:func:`~sixplus3.kinematics.robot.robot_ik`'s margins,
:func:`~sixplus3.kinematics.spherical.spherical_tilts`, the actuated range and
:func:`~sixplus3.kinematics.collision.clearance`), from the legs' compiled kernels
(:mod:`sixplus3.kinematics._leg_kernel`) and the collision model's
(:mod:`sixplus3.kinematics._geometry_kernel`), without their per-call overhead (the
lead-through's slow update evaluates 10-16 poses every 10 ms).

:class:`~sixplus3.interaction.walls.Walls` packs the robot's constants (``k``: see
:func:`~sixplus3.interaction.walls.Walls.__init__`); tests/test_leadthrough.py checks
the kernel against the composition of those functions."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sixplus3.kinematics._geometry_kernel import pose_clearance
from sixplus3.kinematics._leg_kernel import (
    MARGIN_I,
    MARGIN_II,
    NF,
    PD,
    PE,
    PF,
    PG,
    PH,
    PP,
    QM,
    TH,
    ik_point,
    jacobian_point,
)

# the scalar constants k (walls.Walls): the platform's crank and angle scale, the walls'
# floors, the range, the collision model's plate offset and base, the legs' l6, l7
K_CRANK, K_L, K_MARGIN, K_TILT, K_LO, K_HI, K_RANGE, K_PLATE, K_BASE, K_CLEAR = range(10)
K_L6, K_L7 = 10, 11
N_K = 12


@njit(cache=True, inline="always", error_model="numpy")
def _mv(A, x):
    """A x of a 3 x 3 and a 3-vector (numba's @ calls BLAS: a microsecond each)."""
    out = np.empty(3)
    for i in range(3):
        out[i] = A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]
    return out


@njit(cache=True, inline="always", error_model="numpy")
def _mtv(A, x):
    """A^T x of a 3 x 3 and a 3-vector."""
    out = np.empty(3)
    for i in range(3):
        out[i] = A[0, i] * x[0] + A[1, i] * x[1] + A[2, i] * x[2]
    return out


@njit(cache=True, inline="always", error_model="numpy")
def _mm(A, B):
    """A B of two 3 x 3."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]
    return out


@njit(cache=True, error_model="numpy")
def _rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    R = np.zeros((3, 3))
    i, j = (1, 2) if axis == 0 else (0, 1)
    R[axis, axis] = 1.0
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


@njit(cache=True, error_model="numpy")
def _u_joint(theta, ld):
    """(a, b) of the U joint: R_x(theta + a) R_z(b) y = ld (kinematics.robot)."""
    c, s = math.cos(theta), math.sin(theta)
    uy = c * ld[1] + s * ld[2]
    uz = -s * ld[1] + c * ld[2]
    return math.atan2(uz, uy), math.atan2(-ld[0], math.hypot(uy, uz))


@njit(cache=True, error_model="numpy")
def pose_slacks(p, R, psi, with_clearance, k, geo, mode, crank_pos, crank_angle, leg_rot,
                leg_org, sph_ref, hubs, radii, pairs, base, out, theta, caps, mid, half):
    """The four slacks of one pose (interaction.walls) into ``out`` (4,) and its
    actuated angles into ``theta`` (9,); returns whether the pose has an assembly (if
    not: every slack -1, theta 0)."""
    rows = np.zeros((3, NF))
    P = np.empty((3, 3))
    Ri = np.empty((3, 3))
    for i in range(3):
        b = crank_angle[i] + psi[i]
        loc = crank_pos[i] + k[K_CRANK] * np.array([math.cos(b), math.sin(b), 0.0])
        P[i] = p + _mv(R, loc)
        Ri[i] = p + _mv(R, crank_pos[i])
        pl = _mtv(leg_rot[i], P[i] - leg_org[i])
        st = ik_point(pl[0], pl[1], pl[2], geo, mode, rows[i])
        if st != 0:
            out[:] = -1.0
            theta[:] = 0.0
            return False
        jacobian_point(geo, 0.0, 0.0, rows[i])
    # singularity: the seven margins (each leg's type I and II, the platform's)
    m = np.inf
    for i in range(3):
        m = min(m, min(rows[i, MARGIN_I], rows[i, MARGIN_II]))
        for j in range(3):
            theta[3 * i + j] = rows[i, TH + j]
    J = np.zeros((9, 9))
    z = R[:, 2]
    for i in range(3):
        r = P[i] - p
        s = P[i] - Ri[i]
        for a in range(3):
            J[3 * i + a, a] = 1.0
        # omega x r = -[r]x omega, scaled by 1 / L
        J[3 * i + 0, 4], J[3 * i + 0, 5] = r[2] / k[K_L], -r[1] / k[K_L]
        J[3 * i + 1, 3], J[3 * i + 1, 5] = -r[2] / k[K_L], r[0] / k[K_L]
        J[3 * i + 2, 3], J[3 * i + 2, 4] = r[1] / k[K_L], -r[0] / k[K_L]
        J[3 * i + 0, 6 + i] = (z[1] * s[2] - z[2] * s[1]) / k[K_CRANK]
        J[3 * i + 1, 6 + i] = (z[2] * s[0] - z[0] * s[2]) / k[K_CRANK]
        J[3 * i + 2, 6 + i] = (z[0] * s[1] - z[1] * s[0]) / k[K_CRANK]
    # sigma_min / sigma_max from the eigenvalues of J^T J (LAPACK's 9 x 9 SVD costs
    # 25 us in numba, these 7 us; the same ratio to 1e-12 for margins above 1e-3,
    # tests/test_leadthrough.py)
    ev = np.linalg.eigvalsh(J.T @ J)
    m = min(m, math.sqrt(max(ev[0], 0.0) / ev[-1]))
    out[0] = m - k[K_MARGIN]
    # spherical joints: each one's tilt from its axis at home
    tilt = 0.0
    for i in range(3):
        row = rows[i]
        Q = np.empty((3, 3))
        for a in range(3):
            for c in range(3):
                Q[a, c] = row[QM + 3 * a + c]
        body = _mm(leg_rot[i], Q)
        for j in range(3):
            if j < 2:
                th = row[TH + 1 + j]
                tip = PG if j == 0 else PH
                end = PE if j == 0 else PF
                length = geo[3] if j == 0 else geo[4]
                ld = (row[end:end + 3] - row[tip:tip + 3]) / length
                ua, ub = _u_joint(th, ld)
                other = _mm(_mm(leg_rot[i], _rot(0, th + ua)), _rot(2, ub))
            else:
                other = _mm(R, _rot(2, crank_angle[i] + psi[i]))
            u = _mv(body, sph_ref[i, j, 0])
            v = _mv(other, sph_ref[i, j, 1])
            cosv = min(max(u[0] * v[0] + u[1] * v[1] + u[2] * v[2], -1.0), 1.0)
            tilt = max(tilt, math.acos(cosv))
    out[1] = k[K_TILT] - tilt
    # actuated range
    near = np.inf
    for a in range(9):
        near = min(near, min(theta[a] - k[K_LO], k[K_HI] - theta[a]))
    out[2] = near - k[K_RANGE]
    if not with_clearance:
        out[3] = np.inf
        return True
    # legs apart: the collision model's capsules (kinematics.collision.capsules)
    for i in range(3):
        row = rows[i]
        Rl, org = leg_rot[i], leg_org[i]
        pts = np.zeros((9, 3))  # A, D, P, B, G, E, C, H, F in the leg frame
        pts[1], pts[2] = row[PD:PD + 3], row[PP:PP + 3]
        pts[3, 0] = k[K_L6]
        pts[4], pts[5] = row[PG:PG + 3], row[PE:PE + 3]
        pts[6, 0] = -k[K_L7]
        pts[7], pts[8] = row[PH:PH + 3], row[PF:PF + 3]
        for lk, (u, v) in enumerate(((0, 1), (1, 2), (3, 4), (4, 5), (6, 7), (7, 8))):
            caps[6 * i + lk, 0] = _mv(Rl, pts[u]) + org
            caps[6 * i + lk, 1] = _mv(Rl, pts[v]) + org
    for i in range(3):
        caps[18 + i] = hubs[i]
    up = k[K_PLATE] * z
    for i in range(3):
        caps[21 + i, 0] = p + up
        caps[21 + i, 1] = Ri[i] + up
        caps[24 + i, 0] = Ri[i] + up
        caps[24 + i, 1] = Ri[(i + 1) % 3] + up
        caps[27 + i, 0] = Ri[i]
        caps[27 + i, 1] = P[i]
    clear = pose_clearance(caps, radii, pairs, base, k[K_BASE], -np.inf, mid, half)
    out[3] = (clear - k[K_CLEAR]) / 0.01
    return True


@njit(cache=True, error_model="numpy")
def batch_slacks(p, R, psi, with_clearance, k, geo, mode, crank_pos, crank_angle, leg_rot,
                 leg_org, sph_ref, hubs, radii, pairs, base, out, theta, ok):
    """:func:`pose_slacks` of n poses (p (n, 3), R (n, 3, 3), psi (n, 3),
    with_clearance (n,)) into out (n, 4), theta (n, 9), ok (n,)."""
    caps = np.zeros((radii.shape[0], 2, 3))
    mid = np.empty((radii.shape[0], 3))
    half = np.empty(radii.shape[0])
    for n in range(p.shape[0]):
        ok[n] = pose_slacks(p[n], R[n], psi[n], with_clearance[n], k, geo, mode, crank_pos,
                            crank_angle, leg_rot, leg_org, sph_ref, hubs, radii, pairs,
                            base, out[n], theta[n], caps, mid, half)
