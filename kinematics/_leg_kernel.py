"""Compiled per-point kernels of the RU/2-RUS leg (paper §III-IV).

Everything here is scalar code compiled with numba; batch entry points loop over a
leading axis of points with ``prange``.  One point's results are written into a row of
``NF`` float64 fields whose layout is given by the index constants below; the public API
in :mod:`kinematics.leg` slices those rows into dataclasses.

Conventions (docs/conventions.md): leg frame with origin A, x = actuated axis, y to the centre,
z up.  theta_j = 0 points the proximal link along +y, 90 deg along +z.  Actuated angles are
returned in [-90 deg, 270 deg): the base-collision quadrant (270, 360) of the paper shows
up as (-90, 0).  Passive angles are returned in (-180, 180].

The packed geometry vector ``geo`` is (l1, l2, l3, l4, l5, l6, l7, dp, ex, ey, ez, fx,
fy, fz) -- see :meth:`robot_description.LegGeometry.packed`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

# ---------------------------------------------------------------- row layout
ST = 0  # status bitmask (see STATUS_* below), stored as float
TH = 1  # theta1, theta2, theta3 [rad]
TS = 4  # theta_s2, theta_s3 [rad]
QM = 6  # Q, row-major 3x3
PD = 15  # d
PE = 18  # e
PF = 21  # f
PG = 24  # g
PH = 27  # h
PP = 30  # p
JR = 33  # J' = diag(1, det Jp, det Jp) J, row-major (finite through type I)
KM = 42  # K, row-major
JT = 51  # J tilde of Proposition 1, row-major
MM = 60  # M = K^T J^-T  (tau = M f), row-major
DET_J = 69
DET_K = 70
DET_JT = 71
MARGIN_I = 72
MARGIN_II = 73
TAU_EXT = 74
DET_JP = 75
NF = 76

# Status bits.  0 means the point was solved.
STATUS_OK = 0
STATUS_RU = 1  # the RU chain cannot reach p (outside the torus, or on the actuated axis)
STATUS_RUS_B = 2  # the RUS chain at B cannot close
STATUS_RUS_C = 4  # the RUS chain at C cannot close
STATUS_INPUT = 8  # non-finite input
STATUS_FK_NOCONV = 16  # forward kinematics: Newton did not converge from any seed
STATUS_FK_MODE = 32  # forward kinematics: converged, but not in the requested mode

# |cos| slightly above 1 from rounding at the workspace boundary is clamped, not rejected.
_ACOS_SLACK = 1e-12
_TWO_PI = 2.0 * math.pi
# Safe fast-math subset: contraction (FMA), reciprocal and sign-of-zero freedom.  Never
# 'nnan'/'ninf' (the kernels test for non-finite values) nor 'afn' (approximate libm).
_FM = {"contract", "arcp", "nsz"}


@njit(cache=True, inline="always", fastmath=_FM, error_model="numpy")
def _wrap_actuated(t: float) -> float:
    """Wrap an actuated angle into [-pi/2, 3pi/2) (any finite input)."""
    if -0.5 * math.pi <= t < 1.5 * math.pi:  # always true for atan2 output >= -pi/2
        return t
    return (t + 0.5 * math.pi) % _TWO_PI - 0.5 * math.pi


@njit(cache=True, inline="always", fastmath=_FM, error_model="numpy")
def _wrap_pi(t: float) -> float:
    return math.atan2(math.sin(t), math.cos(t))


@njit(cache=True, fastmath=_FM, error_model="numpy")
def _solve_rus(rx, ry, rz, crank, link, sign):
    """Crank of a RUS (or RU) chain with R axis x_f: |rel - crank [0, c, s]| = link.

    ``rel`` is the spherical-joint centre relative to the crank's base point.  Expanding
    gives ry c + rz s = k (paper eq. 3 and 5).  The two roots th = atan2(rz, ry) +/- acos(k/r)
    are returned algebraically, without trigonometric calls:

        c = (ry k - sign rz q) / r^2,   s = (rz k + sign ry q) / r^2,   q = sqrt(r^2 - k^2).

    Returns (ok, c, s).  |k| slightly above r from rounding at the boundary is clamped.
    """
    r2 = ry * ry + rz * rz
    k = (rx * rx + r2 + crank * crank - link * link) / (2.0 * crank)
    if r2 <= 0.0:
        return False, 1.0, 0.0
    q2 = r2 - k * k
    if q2 < 0.0:
        if q2 < -_ACOS_SLACK * r2:
            return False, 1.0, 0.0
        q2 = 0.0
    q = sign * math.sqrt(q2)
    return True, (ry * k - rz * q) / r2, (rz * k + ry * q) / r2


@njit(cache=True, fastmath=_FM, error_model="numpy")
def _write_q(cp, sp, c3, s3, out):
    """Q = R(x, phi) R(z, th_s3 - pi/2), phi = th1 + th_s2 (paper eq. 2), row-major."""
    out[QM + 0] = s3
    out[QM + 1] = c3
    out[QM + 2] = 0.0
    out[QM + 3] = -cp * c3
    out[QM + 4] = cp * s3
    out[QM + 5] = -sp
    out[QM + 6] = -sp * c3
    out[QM + 7] = sp * s3
    out[QM + 8] = cp


@njit(cache=True, fastmath=_FM, error_model="numpy")
def _body_frame(t1, ts2, ts3, out):
    """Q = R(x, th1) R(x, th_s2) R(z, th_s3 - pi/2)  (paper eq. 1-2) from angles."""
    phi = t1 + ts2
    _write_q(math.cos(phi), math.sin(phi), math.cos(ts3), math.sin(ts3), out)


@njit(cache=True, fastmath=_FM, error_model="numpy")
def _body_points(geo, out):
    """e = d + Q e_b, f = d + Q f_b, p = d + Q p_b from d and Q already in ``out``."""
    dp, ex, ey, ez, fx, fy, fz = geo[7], geo[8], geo[9], geo[10], geo[11], geo[12], geo[13]
    for i in range(3):
        q0 = out[QM + 3 * i]
        q1 = out[QM + 3 * i + 1]
        q2 = out[QM + 3 * i + 2]
        d = out[PD + i]
        out[PE + i] = d + q0 * ex + q1 * ey + q2 * ez
        out[PF + i] = d + q0 * fx + q1 * fy + q2 * fz
        out[PP + i] = d + q0 * dp


@njit(cache=True, fastmath=_FM, error_model="numpy")
def _failed(out, status):
    """A failed point carries zeros, margins 0 and tau_ext = inf: every limit check fails."""
    for i in range(NF):
        out[i] = 0.0
    out[ST] = status
    out[TAU_EXT] = math.inf
    return status


@njit(cache=True, fastmath=_FM, error_model="numpy")
def ik_point(x, y, z, geo, mode, out, passive=True):
    """Closed-form inverse kinematics of one point p = (x, y, z) [m] in the leg frame.

    ``mode`` holds four signs (+1/-1) choosing the branch of theta1, theta_s3 (sign of
    cos theta_s3), theta2 and theta3.  Fills ST, TH, TS, QM, PD..PP of ``out`` and returns
    the status bitmask.  ``passive=False`` skips the passive angles (TS stays as it was):
    the design search does not need them and they cost two atan2 per point.
    """
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        return _failed(out, STATUS_INPUT)
    l1, l2, l3, l4, l5, l6, l7, dp = (geo[0], geo[1], geo[2], geo[3], geo[4], geo[5],
                                      geo[6], geo[7])
    # RU chain: |p - d|^2 = dp^2 with d = l1 [0, c1, s1]  =>  y c1 + z s1 = k.
    ok, c1, s1 = _solve_rus(x, y, z, l1, dp, mode[0])
    if not ok:
        return _failed(out, STATUS_RU)
    out[PD + 0] = 0.0
    out[PD + 1] = l1 * c1
    out[PD + 2] = l1 * s1
    # Q p_b = p - d:  (p - d)/dp = [s_s3, -c_phi c_s3, -s_phi c_s3],  phi = th1 + th_s2.
    vx = x
    vy = y - l1 * c1
    vz = z - l1 * s1
    n = math.sqrt(vx * vx + vy * vy + vz * vz)
    vx /= n
    vy /= n
    vz /= n
    m1 = mode[1]
    rho = math.sqrt(vy * vy + vz * vz)
    cs3 = m1 * rho
    if rho > 0.0:
        cp = -m1 * vy / rho
        sp = -m1 * vz / rho
    else:
        # Type I: p - d along x_f, phi is undefined; any value keeps Q a rotation.
        cp = 1.0
        sp = 0.0
    _write_q(cp, sp, cs3, vx, out)
    _body_points(geo, out)
    # Keep the caller's p exactly (the recomputed one differs by rounding only).
    out[PP + 0] = x
    out[PP + 1] = y
    out[PP + 2] = z
    out[TH + 0] = _wrap_actuated(math.atan2(s1, c1))
    if passive:
        out[TS + 0] = math.atan2(sp * c1 - cp * s1, cp * c1 + sp * s1)  # phi - th1
        out[TS + 1] = math.atan2(vx, cs3)
    status = STATUS_OK
    # RUS chain at B = (l6, 0, 0) closing at E.
    ok, c2, s2 = _solve_rus(out[PE] - l6, out[PE + 1], out[PE + 2], l2, l4, mode[2])
    if ok:
        out[TH + 1] = _wrap_actuated(math.atan2(s2, c2))
        out[PG + 0] = l6
        out[PG + 1] = l2 * c2
        out[PG + 2] = l2 * s2
    else:
        status |= STATUS_RUS_B
    # RUS chain at C = (-l7, 0, 0) closing at F.
    ok, c3, s3 = _solve_rus(out[PF] + l7, out[PF + 1], out[PF + 2], l3, l5, mode[3])
    if ok:
        out[TH + 2] = _wrap_actuated(math.atan2(s3, c3))
        out[PH + 0] = -l7
        out[PH + 1] = l3 * c3
        out[PH + 2] = l3 * s3
    else:
        status |= STATUS_RUS_C
    if status != STATUS_OK:
        return _failed(out, status)
    out[ST] = status
    return status


@njit(cache=True, inline="always", fastmath=_FM, error_model="numpy")
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True, fastmath=_FM, error_model="numpy")
def _sigma_min_unit_rows(a0, a1, a2, b0, b1, b2, c0, c1, c2):
    """Smallest singular value of the 3x3 matrix with the given rows, each normalised.

    sigma_min^2 = lambda_min(G) with G the Gram matrix of the unit rows: unit diagonal,
    off-diagonal cosines (u, v, w).  G - I has the characteristic polynomial
    t^3 - (u^2+v^2+w^2) t - 2uvw, solved in closed (trigonometric) form.  The value is
    the spectral distance to the nearest singular matrix: 0 singular, 1 orthonormal rows.
    """
    na = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    nb = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
    nc = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if na == 0.0 or nb == 0.0 or nc == 0.0:
        return 0.0
    u = (a0 * b0 + a1 * b1 + a2 * b2) / (na * nb)
    v = (a0 * c0 + a1 * c1 + a2 * c2) / (na * nc)
    w = (b0 * c0 + b1 * c1 + b2 * c2) / (nb * nc)
    p = u * u + v * v + w * w
    if p < 1e-300:
        return 1.0
    q = 2.0 * u * v * w
    arg = 1.5 * q / p * math.sqrt(3.0 / p)
    arg = min(1.0, max(-1.0, arg))
    t_min = 2.0 * math.sqrt(p / 3.0) * math.cos((math.acos(arg) - 4.0 * math.pi) / 3.0)
    lam = 1.0 + t_min
    return math.sqrt(lam) if lam > 0.0 else 0.0


@njit(cache=True, inline="always", fastmath=_FM, error_model="numpy")
def _torque_map(out, det_jp, det_jr, cof, kk, mass_g, accel_g):
    """M = K^T J^-T (rows of ``out[MM:]``) from J's cofactor rows ``cof`` (c0x, c0y,
    c0z, c1x, ..., c2z) and K's entries ``kk`` (k11, k21, k22, k31, k33), and the
    largest static torque ``out[TAU_EXT]`` of :func:`jacobian_point`."""
    c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z = cof
    k11, k21, k22, k31, k33 = kk
    # N = S J'^-T: rows c0/det, dJp c1/det, dJp c2/det.
    inv = 1.0 / det_jr
    s = det_jp * inv
    n0x, n0y, n0z = c0x * inv, c0y * inv, c0z * inv
    n1x, n1y, n1z = c1x * s, c1y * s, c1z * s
    n2x, n2y, n2z = c2x * s, c2y * s, c2z * s
    # M = K^T N.
    m0x = k11 * n0x + k21 * n1x + k31 * n2x
    m0y = k11 * n0y + k21 * n1y + k31 * n2y
    m0z = k11 * n0z + k21 * n1z + k31 * n2z
    m1x, m1y, m1z = k22 * n1x, k22 * n1y, k22 * n1z
    m2x, m2y, m2z = k33 * n2x, k33 * n2y, k33 * n2z
    out[MM + 0], out[MM + 1], out[MM + 2] = m0x, m0y, m0z
    out[MM + 3], out[MM + 4], out[MM + 5] = m1x, m1y, m1z
    out[MM + 6], out[MM + 7], out[MM + 8] = m2x, m2y, m2z
    # tau_ext = max_j max_{f in F} |m_j . f|,  F = {mg[0, cos a, sin a]} + a_g m g B^3:
    # the ball adds a_g m g |m_j| and the gravity circle m g sqrt(m_jy^2 + m_jz^2).
    t0 = mass_g * (math.sqrt(m0y * m0y + m0z * m0z)
                   + accel_g * math.sqrt(m0x * m0x + m0y * m0y + m0z * m0z))
    t1 = mass_g * (math.sqrt(m1y * m1y + m1z * m1z)
                   + accel_g * math.sqrt(m1x * m1x + m1y * m1y + m1z * m1z))
    t2 = mass_g * (math.sqrt(m2y * m2y + m2z * m2z)
                   + accel_g * math.sqrt(m2x * m2x + m2y * m2y + m2z * m2z))
    out[TAU_EXT] = max(t0, max(t1, t2))


@njit(cache=True, fastmath=_FM, error_model="numpy")
def jacobian_point(geo, mass_g, accel_g, out, margin_ii=True):
    """J, K (paper §III-C), J tilde (Prop. 1), M = K^T J^-T, determinants, margins, tau_ext.

    Reads the IK fields of ``out``; ``mass_g`` = m g [N], ``accel_g`` the required
    acceleration in g.  ``margin_ii=False`` skips the sigma_min type II margin (left 0).
    J is stored row-scaled as J' = diag(1, det Jp, det Jp) J, which stays finite at type I
    configurations where J_p (and so J) blows up; det J = det J' / det(Jp)^2 and
    tau = K^T J^-T f = K^T S J'^-T f with S = diag(1, det Jp, det Jp).
    """
    l1, l2, l3, l4, l5, dp = geo[0], geo[1], geo[2], geo[3], geo[4], geo[7]
    dy, dz = out[PD + 1], out[PD + 2]
    px, py, pz = out[PP], out[PP + 1], out[PP + 2]
    # Relative vectors.
    pdx, pdy, pdz = px, py - dy, pz - dz  # p - d (d_x = 0)
    egx, egy, egz = out[PE] - out[PG], out[PE + 1] - out[PG + 1], out[PE + 2] - out[PG + 2]
    fhx, fhy, fhz = out[PF] - out[PH], out[PF + 1] - out[PH + 1], out[PF + 2] - out[PH + 2]
    # u_j = x_f x (crank tip - crank base); all cranks lie in planes normal to x_f.
    u1y, u1z = -dz, dy
    u2y, u2z = -out[PG + 2], out[PG + 1]
    u3y, u3z = -out[PH + 2], out[PH + 1]
    k11 = pdy * u1y + pdz * u1z  # = (p-d)^T u1 (the paper has a sign typo, docs/conventions.md)
    k21 = -(egy * u1y + egz * u1z)
    k22 = egy * u2y + egz * u2z
    k31 = -(fhy * u1y + fhz * u1z)
    k33 = fhy * u3y + fhz * u3z
    # w = Q z_f (U-joint axis at D), third column of Q.
    wx, wy, wz = out[QM + 2], out[QM + 5], out[QM + 8]
    # J_p columns: x_f x (p - a), x_f x (p - d), w x (p - d).
    a0x, a0y, a0z = 0.0, -pz, py
    a1x, a1y, a1z = 0.0, -pdz, pdy
    a2x, a2y, a2z = _cross(wx, wy, wz, pdx, pdy, pdz)
    # Rows of det(Jp) Jp^-1:  a1 x a2, a2 x a0, a0 x a1.
    r0x, r0y, r0z = _cross(a1x, a1y, a1z, a2x, a2y, a2z)
    r1x, r1y, r1z = _cross(a2x, a2y, a2z, a0x, a0y, a0z)
    r2x, r2y, r2z = _cross(a0x, a0y, a0z, a1x, a1y, a1z)
    det_jp = a0x * r0x + a0y * r0y + a0z * r0z
    # n_e = Q e_b x (e - g) = (e - d) x (e - g);  n_f likewise.
    nex, ney, nez = _cross(out[PE], out[PE + 1] - dy, out[PE + 2] - dz, egx, egy, egz)
    nfx, nfy, nfz = _cross(out[PF], out[PF + 1] - dy, out[PF + 2] - dz, fhx, fhy, fhz)
    # J_omega^T n = (n.x, n.x, n.w);  row' = (J_omega^T n)^T adj(Jp).
    be0, be2 = nex, nex * wx + ney * wy + nez * wz
    bf0, bf2 = nfx, nfx * wx + nfy * wy + nfz * wz
    j1x = be0 * (r0x + r1x) + be2 * r2x
    j1y = be0 * (r0y + r1y) + be2 * r2y
    j1z = be0 * (r0z + r1z) + be2 * r2z
    j2x = bf0 * (r0x + r1x) + bf2 * r2x
    j2y = bf0 * (r0y + r1y) + bf2 * r2y
    j2z = bf0 * (r0z + r1z) + bf2 * r2z
    out[JR + 0], out[JR + 1], out[JR + 2] = pdx, pdy, pdz
    out[JR + 3], out[JR + 4], out[JR + 5] = j1x, j1y, j1z
    out[JR + 6], out[JR + 7], out[JR + 8] = j2x, j2y, j2z
    out[KM + 0], out[KM + 1], out[KM + 2] = k11, 0.0, 0.0
    out[KM + 3], out[KM + 4], out[KM + 5] = k21, k22, 0.0
    out[KM + 6], out[KM + 7], out[KM + 8] = k31, 0.0, k33
    # J tilde rows: x_f x w, n_e, n_f.
    t0x, t0y, t0z = 0.0, -wz, wy
    out[JT + 0], out[JT + 1], out[JT + 2] = t0x, t0y, t0z
    out[JT + 3], out[JT + 4], out[JT + 5] = nex, ney, nez
    out[JT + 6], out[JT + 7], out[JT + 8] = nfx, nfy, nfz
    cx, cy, cz = _cross(nex, ney, nez, nfx, nfy, nfz)
    out[DET_JT] = t0x * cx + t0y * cy + t0z * cz
    # Cofactor rows of J' (rows a = p-d, b = j1, c = j2): b x c, c x a, a x b.
    c0x, c0y, c0z = _cross(j1x, j1y, j1z, j2x, j2y, j2z)
    c1x, c1y, c1z = _cross(j2x, j2y, j2z, pdx, pdy, pdz)
    c2x, c2y, c2z = _cross(pdx, pdy, pdz, j1x, j1y, j1z)
    det_jr = pdx * c0x + pdy * c0y + pdz * c0z
    out[DET_JP] = det_jp
    out[DET_K] = k11 * k22 * k33
    if det_jp != 0.0:
        out[DET_J] = det_jr / (det_jp * det_jp)
    else:
        out[DET_J] = math.copysign(math.inf, det_jr) if det_jr != 0.0 else 0.0
    # Scale-free margins.  Type I: cosine between each distal link and its crank velocity
    # (|K_jj| normalised by the constant link and crank lengths).  Type II: sigma_min of
    # the row-normalised J' (same rows as J up to positive/negative scaling).
    m_i = min(abs(k11) / (dp * l1), abs(k22) / (l4 * l2), abs(k33) / (l5 * l3))
    out[MARGIN_I] = m_i
    if margin_ii:
        out[MARGIN_II] = _sigma_min_unit_rows(pdx, pdy, pdz, j1x, j1y, j1z, j2x, j2y, j2z)
    else:
        out[MARGIN_II] = 0.0
    if det_jr == 0.0:
        for i in range(9):
            out[MM + i] = math.inf
        out[TAU_EXT] = math.inf
        return
    _torque_map(out, det_jp, det_jr, (c0x, c0y, c0z, c1x, c1y, c1z, c2x, c2y, c2z),
                (k11, k21, k22, k31, k33), mass_g, accel_g)


def _full_batch(points, geo, mode, mass_g, accel_g):
    """IK + Jacobians + statics for (n, 3) points; returns the (n, NF) field array."""
    n = points.shape[0]
    out = np.zeros((n, NF))
    for i in prange(n):
        row = out[i]
        st = ik_point(points[i, 0], points[i, 1], points[i, 2], geo, mode, row)
        if st == STATUS_OK:
            jacobian_point(geo, mass_g, accel_g, row)
    return out


#: Threaded for large batches; a small one (a few samples per call, e.g. forward
#: kinematics following a log) runs serial: waking the thread pool costs ~1 ms per call
#: on a loaded machine, a thousand times the work (``leg_ik`` picks, SERIAL_BELOW).
full_batch = njit(cache=True, parallel=True, fastmath=_FM, error_model="numpy")(_full_batch)
full_batch_serial = njit(cache=True, fastmath=_FM, error_model="numpy")(_full_batch)
SERIAL_BELOW = 512


# Compact output of the throughput kernel.
E_ST, E_TH, E_DET_J, E_DET_K, E_MARGIN_I, E_MARGIN_II, E_TAU_EXT = 0, 1, 4, 5, 6, 7, 8
E_NF = 9
_CHUNK = 2048


@njit(cache=True, parallel=True, fastmath=_FM, error_model="numpy")
def eval_into(points, geo, mode, mass_g, accel_g, margin_ii, res):
    """IK + J + K + tau_ext for (n, 3) points into a caller-owned (n, E_NF) buffer.

    The compact output of the design search: status, theta, det J, det K, margins and
    tau_ext.  Reusing ``res`` across calls avoids first-touch page faults of a fresh
    allocation, which cost ~20% at 10^6 points.
    """
    n = points.shape[0]
    nchunks = (n + _CHUNK - 1) // _CHUNK
    for c in prange(nchunks):
        row = np.empty(NF)
        for i in range(c * _CHUNK, min(n, (c + 1) * _CHUNK)):
            st = ik_point(points[i, 0], points[i, 1], points[i, 2], geo, mode, row, False)
            if st == STATUS_OK:
                jacobian_point(geo, mass_g, accel_g, row, margin_ii)
            res[i, E_ST] = st
            res[i, E_TH] = row[TH]
            res[i, E_TH + 1] = row[TH + 1]
            res[i, E_TH + 2] = row[TH + 2]
            res[i, E_DET_J] = row[DET_J]
            res[i, E_DET_K] = row[DET_K]
            res[i, E_MARGIN_I] = row[MARGIN_I]
            res[i, E_MARGIN_II] = row[MARGIN_II]
            res[i, E_TAU_EXT] = row[TAU_EXT]
