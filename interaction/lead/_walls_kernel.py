"""The walls' slacks of platform poses, compiled (numba): the same numbers as the gate's
own checks composed (:func:`~sixplus3.kinematics.robot.robot_ik`'s margins,
:func:`~sixplus3.kinematics.spherical.spherical_tilts`, the actuated range and
:func:`~sixplus3.kinematics.collision.clearance`), from the legs' compiled kernels
(:mod:`sixplus3.kinematics._leg_kernel`) and the collision model's
(:mod:`sixplus3.kinematics._geometry_kernel`), without their per-call overhead (the
lead-through's slow update evaluates 10-16 poses every 10 ms).

:class:`~sixplus3.interaction.lead.walls.Walls` packs the robot's constants (``k``: see
:func:`~sixplus3.interaction.lead.walls.Walls.__init__`); tests/test_leadthrough.py checks
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
def _mv(A, x0, x1, x2):
    """A x of a 3 x 3 and a vector's three scalars (no arrays: numba's @ calls BLAS, a
    microsecond each, and small arrays cost an allocation)."""
    return (A[0, 0] * x0 + A[0, 1] * x1 + A[0, 2] * x2,
            A[1, 0] * x0 + A[1, 1] * x1 + A[1, 2] * x2,
            A[2, 0] * x0 + A[2, 1] * x1 + A[2, 2] * x2)


@njit(cache=True, inline="always", error_model="numpy")
def _rx(a, x0, x1, x2):
    """R_x(a) x."""
    c, s = math.cos(a), math.sin(a)
    return x0, c * x1 - s * x2, s * x1 + c * x2


@njit(cache=True, inline="always", error_model="numpy")
def _rz(a, x0, x1, x2):
    """R_z(a) x."""
    c, s = math.cos(a), math.sin(a)
    return c * x0 - s * x1, s * x0 + c * x1, x2


@njit(cache=True, error_model="numpy")
def _u_joint(theta, ld0, ld1, ld2):
    """(a, b) of the U joint: R_x(theta + a) R_z(b) y = ld (kinematics.robot)."""
    c, s = math.cos(theta), math.sin(theta)
    uy = c * ld1 + s * ld2
    uz = -s * ld1 + c * ld2
    return math.atan2(uz, uy), math.atan2(-ld0, math.hypot(uy, uz))


@njit(cache=True, error_model="numpy")
def _angle(u0, u1, u2, v0, v1, v2):
    return math.acos(min(max(u0 * v0 + u1 * v1 + u2 * v2, -1.0), 1.0))


@njit(cache=True, error_model="numpy")
def _tilt(i, row, R, psi, geo, crank_angle, leg_rot, sph_ref):
    """The largest tilt of leg i's three spherical joints from their axes at home."""
    Rl = leg_rot[i]
    tilt = 0.0
    for j in range(3):
        s0, s1 = sph_ref[i, j, 0], sph_ref[i, j, 1]
        # u = Rl Q s0 (the leg's body), v = the other side's frame times s1
        q0 = row[QM + 0] * s0[0] + row[QM + 1] * s0[1] + row[QM + 2] * s0[2]
        q1 = row[QM + 3] * s0[0] + row[QM + 4] * s0[1] + row[QM + 5] * s0[2]
        q2 = row[QM + 6] * s0[0] + row[QM + 7] * s0[1] + row[QM + 8] * s0[2]
        u0, u1, u2 = _mv(Rl, q0, q1, q2)
        if j < 2:
            th = row[TH + 1 + j]
            tip = PG if j == 0 else PH
            end = PE if j == 0 else PF
            length = geo[3] if j == 0 else geo[4]
            ua, ub = _u_joint(th, (row[end] - row[tip]) / length,
                              (row[end + 1] - row[tip + 1]) / length,
                              (row[end + 2] - row[tip + 2]) / length)
            w0, w1, w2 = _rz(ub, s1[0], s1[1], s1[2])
            w0, w1, w2 = _rx(th + ua, w0, w1, w2)
            v0, v1, v2 = _mv(Rl, w0, w1, w2)
        else:
            w0, w1, w2 = _rz(crank_angle[i] + psi[i], s1[0], s1[1], s1[2])
            v0, v1, v2 = _mv(R, w0, w1, w2)
        tilt = max(tilt, _angle(u0, u1, u2, v0, v1, v2))
    return tilt


_EPS = 2.220446049250313e-16


@njit(cache=True, error_model="numpy")
def sym_extremes(A, d, e, v, p):
    """(the smallest, the largest) eigenvalue of the symmetric n x n ``A`` (overwritten;
    d, e, v, p (n,) work): Householder's tridiagonalisation, then the implicit QL
    iteration with shifts (eigenvalues only; Numerical Recipes' tqli).  Twice as fast
    as numba's ``eigvalsh`` (LAPACK's dsyevd with its copies and workspace) on 9 x 9,
    with its accuracy: each eigenvalue to a few eps times the largest
    (tests/test_tick_kernel.py)."""
    n = A.shape[0]
    for k in range(n - 2):
        nrm = 0.0
        for i in range(k + 1, n):
            nrm += A[i, k] * A[i, k]
        nrm = math.sqrt(nrm)
        d[k] = A[k, k]
        if nrm == 0.0:
            e[k] = 0.0
            continue
        alpha = -nrm if A[k + 1, k] >= 0.0 else nrm
        for i in range(k + 1, n):
            v[i] = A[i, k]
        v[k + 1] -= alpha
        vtv = 0.0
        for i in range(k + 1, n):
            vtv += v[i] * v[i]
        e[k] = alpha
        beta = 2.0 / vtv
        vp = 0.0
        for i in range(k + 1, n):
            s = 0.0
            for j in range(k + 1, n):
                s += A[i, j] * v[j]
            p[i] = beta * s
            vp += v[i] * p[i]
        K = 0.5 * beta * vp
        for i in range(k + 1, n):
            p[i] -= K * v[i]
        for i in range(k + 1, n):
            for j in range(k + 1, n):
                A[i, j] -= v[i] * p[j] + p[i] * v[j]
    d[n - 2] = A[n - 2, n - 2]
    d[n - 1] = A[n - 1, n - 1]
    e[n - 2] = A[n - 1, n - 2]
    e[n - 1] = 0.0
    for l in range(n):
        for _ in range(60):
            m = l
            while m < n - 1:
                dd = abs(d[m]) + abs(d[m + 1])
                if abs(e[m]) <= _EPS * dd:
                    break
                m += 1
            if m == l:
                break
            g = (d[l + 1] - d[l]) / (2.0 * e[l])
            r = math.sqrt(g * g + 1.0)
            g = d[m] - d[l] + e[l] / (g + (r if g >= 0.0 else -r))
            s = c = 1.0
            pp = 0.0
            i = m - 1
            underflow = False
            while i >= l:
                f = s * e[i]
                b = c * e[i]
                r = math.sqrt(f * f + g * g)
                e[i + 1] = r
                if r == 0.0:
                    d[i + 1] -= pp
                    e[m] = 0.0
                    underflow = True
                    break
                s = f / r
                c = g / r
                g = d[i + 1] - pp
                r = (d[i] - g) * s + 2.0 * c * b
                pp = s * r
                d[i + 1] = g + pp
                g = c * r - b
                i -= 1
            if underflow:
                continue
            d[l] -= pp
            e[l] = g
            e[m] = 0.0
    lo, hi = d[0], d[0]
    for i in range(1, n):
        lo = min(lo, d[i])
        hi = max(hi, d[i])
    return lo, hi


@njit(cache=True, error_model="numpy")
def _platform_margin(p, R, P, Ri, k, J, G, vec):
    """sigma_min / sigma_max of the platform's 9 x 9 Jacobian (rotations scaled by 1 / L,
    cranks by 1 / crank), from the eigenvalues of J^T J (LAPACK's 9 x 9 SVD costs 25 us
    in numba, LAPACK's eigvalsh 5 us, :func:`sym_extremes` 3 us).  J, G (9, 9), vec (4, 9):
    work."""
    J[:, :] = 0.0
    L, c = k[K_L], k[K_CRANK]
    z0, z1, z2 = R[0, 2], R[1, 2], R[2, 2]
    for i in range(3):
        r0, r1, r2 = P[i, 0] - p[0], P[i, 1] - p[1], P[i, 2] - p[2]
        s0, s1, s2 = P[i, 0] - Ri[i, 0], P[i, 1] - Ri[i, 1], P[i, 2] - Ri[i, 2]
        for a in range(3):
            J[3 * i + a, a] = 1.0
        # omega x r = -[r]x omega, scaled by 1 / L
        J[3 * i + 0, 4], J[3 * i + 0, 5] = r2 / L, -r1 / L
        J[3 * i + 1, 3], J[3 * i + 1, 5] = -r2 / L, r0 / L
        J[3 * i + 2, 3], J[3 * i + 2, 4] = r1 / L, -r0 / L
        J[3 * i + 0, 6 + i] = (z1 * s2 - z2 * s1) / c
        J[3 * i + 1, 6 + i] = (z2 * s0 - z0 * s2) / c
        J[3 * i + 2, 6 + i] = (z0 * s1 - z1 * s0) / c
    for a in range(9):
        for b in range(a, 9):
            g = 0.0
            for r in range(9):
                g += J[r, a] * J[r, b]
            G[a, b] = g
            G[b, a] = g
    lo, hi = sym_extremes(G, vec[0], vec[1], vec[2], vec[3])
    return math.sqrt(max(lo, 0.0) / hi)


# the leg's capsules' ends (A-D, D-P, B-G, G-E, C-H, H-F): an offset into the leg
# kernel's row, or A, B, C (fixed in the leg frame: -1, -2, -3)
_A, _B, _C = -1, -2, -3
_CAPS = ((_A, PD, _B, PG, _C, PH), (PD, PP, PG, PE, PH, PF))


@njit(cache=True, inline="always", error_model="numpy")
def _leg_point(row, at, k):
    """A capsule's end in the leg frame: A the origin, B = (l6, 0, 0), C = (-l7, 0, 0),
    the others from the leg kernel's row."""
    if at == _A:
        return 0.0, 0.0, 0.0
    if at == _B:
        return k[K_L6], 0.0, 0.0
    if at == _C:
        return -k[K_L7], 0.0, 0.0
    return row[at], row[at + 1], row[at + 2]


@njit(cache=True, error_model="numpy")
def pose_slacks(p, R, psi, with_clearance, robot, out, theta, work):
    """The four slacks of one pose (interaction.lead.walls) into ``out`` (4,) and its
    actuated angles into ``theta`` (9,); returns whether the pose has an assembly (if
    not: every slack -1, theta 0).  ``robot``: the robot's constants (k, geo, mode,
    crank_pos, crank_angle, leg_rot, leg_org, sph_ref, hubs, radii, pairs, base:
    ``Walls._const``); ``work``: (caps, mid, half, rows (3, NF), P, Ri (3, 3), J, G
    (9, 9), vec (4, 9))."""
    (k, geo, mode, crank_pos, crank_angle, leg_rot, leg_org, sph_ref, hubs, radii, pairs,
     base) = robot
    caps, mid, half, rows, P, Ri, J, G, vec = work
    for i in range(3):
        b = crank_angle[i] + psi[i]
        c0 = crank_pos[i, 0] + k[K_CRANK] * math.cos(b)
        c1 = crank_pos[i, 1] + k[K_CRANK] * math.sin(b)
        x0, x1, x2 = _mv(R, c0, c1, crank_pos[i, 2])
        P[i, 0], P[i, 1], P[i, 2] = p[0] + x0, p[1] + x1, p[2] + x2
        x0, x1, x2 = _mv(R, crank_pos[i, 0], crank_pos[i, 1], crank_pos[i, 2])
        Ri[i, 0], Ri[i, 1], Ri[i, 2] = p[0] + x0, p[1] + x1, p[2] + x2
        Rl, o = leg_rot[i], leg_org[i]
        d0, d1, d2 = P[i, 0] - o[0], P[i, 1] - o[1], P[i, 2] - o[2]
        st = ik_point(Rl[0, 0] * d0 + Rl[1, 0] * d1 + Rl[2, 0] * d2,
                      Rl[0, 1] * d0 + Rl[1, 1] * d1 + Rl[2, 1] * d2,
                      Rl[0, 2] * d0 + Rl[1, 2] * d1 + Rl[2, 2] * d2, geo, mode, rows[i])
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
    m = min(m, _platform_margin(p, R, P, Ri, k, J, G, vec))
    out[0] = m - k[K_MARGIN]
    # spherical joints: each one's tilt from its axis at home
    tilt = 0.0
    for i in range(3):
        tilt = max(tilt, _tilt(i, rows[i], R, psi, geo, crank_angle, leg_rot, sph_ref))
    out[1] = k[K_TILT] - tilt
    # actuated range
    near = np.inf
    for a in range(9):
        near = min(near, min(theta[a] - k[K_LO], k[K_HI] - theta[a]))
    out[2] = near - k[K_RANGE]
    if not with_clearance:
        out[3] = np.inf
        return True
    # legs apart: the collision model's capsules (kinematics.collision.capsules): the
    # legs' (_CAPS), the hubs, the plate (raised by the plate offset), the cranks
    for i in range(3):
        row = rows[i]
        Rl, org = leg_rot[i], leg_org[i]
        for lk in range(6):
            for end in range(2):
                y0, y1, y2 = _leg_point(row, _CAPS[end][lk], k)
                x0, x1, x2 = _mv(Rl, y0, y1, y2)
                caps[6 * i + lk, end, 0] = x0 + org[0]
                caps[6 * i + lk, end, 1] = x1 + org[1]
                caps[6 * i + lk, end, 2] = x2 + org[2]
    for i in range(3):
        caps[18 + i] = hubs[i]
    u0, u1, u2 = k[K_PLATE] * R[0, 2], k[K_PLATE] * R[1, 2], k[K_PLATE] * R[2, 2]
    for i in range(3):
        nx = (i + 1) % 3
        caps[21 + i, 0, 0], caps[21 + i, 0, 1], caps[21 + i, 0, 2] = (p[0] + u0, p[1] + u1,
                                                                      p[2] + u2)
        for a in range(3):
            up = (u0, u1, u2)[a]
            caps[21 + i, 1, a] = Ri[i, a] + up
            caps[24 + i, 0, a] = Ri[i, a] + up
            caps[24 + i, 1, a] = Ri[nx, a] + up
            caps[27 + i, 0, a] = Ri[i, a]
            caps[27 + i, 1, a] = P[i, a]
    clear = pose_clearance(caps, radii, pairs, base, k[K_BASE], -np.inf, mid, half)
    out[3] = (clear - k[K_CLEAR]) / 0.01
    return True


@njit(cache=True, error_model="numpy")
def batch_slacks(p, R, psi, with_clearance, robot, out, theta, ok):
    """:func:`pose_slacks` of n poses (p (n, 3), R (n, 3, 3), psi (n, 3),
    with_clearance (n,)) into out (n, 4), theta (n, 9), ok (n,)."""
    radii = robot[9]
    caps = np.zeros((radii.shape[0], 2, 3))
    mid = np.empty((radii.shape[0], 3))
    half = np.empty(radii.shape[0])
    rows = np.zeros((3, NF))
    P, Ri = np.empty((3, 3)), np.empty((3, 3))
    J, G = np.empty((9, 9)), np.empty((9, 9))
    vec = np.empty((4, 9))
    work = (caps, mid, half, rows, P, Ri, J, G, vec)
    for n in range(p.shape[0]):
        ok[n] = pose_slacks(p[n], R[n], psi[n], with_clearance[n], robot, out[n], theta[n],
                            work)


@njit(cache=True, error_model="numpy")
def moved(p, R, tw, pos, rot):
    """The pose (p (3,), R (3, 3)) moved by the twists tw (n, 6) (a translation and a
    rotation vector, base frame) into pos (n, 3), rot (n, 3, 3): rot = exp([w]x) R
    (Rodrigues; below |w|^2 = 1e-8 the coefficients' Taylor series, as
    :func:`~sixplus3.kinematics.rotations.matrix_from_rotvec`)."""
    E = np.empty((3, 3))
    for n in range(tw.shape[0]):
        w0, w1, w2 = tw[n, 3], tw[n, 4], tw[n, 5]
        t2 = w0 * w0 + w1 * w1 + w2 * w2
        if t2 < 1e-8:
            a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
            b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
        else:
            t = math.sqrt(t2)
            a = math.sin(t) / t
            b = (1.0 - math.cos(t)) / t2
        # I + a K + b K^2, K = [w]x, K^2 = w w^T - t2 I
        E[0, 0] = 1.0 + b * (w0 * w0 - t2)
        E[1, 1] = 1.0 + b * (w1 * w1 - t2)
        E[2, 2] = 1.0 + b * (w2 * w2 - t2)
        E[0, 1], E[1, 0] = -a * w2 + b * w0 * w1, a * w2 + b * w0 * w1
        E[0, 2], E[2, 0] = a * w1 + b * w0 * w2, -a * w1 + b * w0 * w2
        E[1, 2], E[2, 1] = -a * w0 + b * w1 * w2, a * w0 + b * w1 * w2
        for i in range(3):
            pos[n, i] = p[i] + tw[n, i]
            for j in range(3):
                rot[n, i, j] = E[i, 0] * R[0, j] + E[i, 1] * R[1, j] + E[i, 2] * R[2, j]
