"""Compiled forward kinematics of the RU/2-RUS leg: actuated angles -> p, by Newton on
the two passive angles of the body, checked against the inverse kinematics
(:mod:`kinematics._leg_kernel`, whose row layout and status bits it shares)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sixplus3.kinematics._leg_kernel import (
    _FM,
    NF,
    PD,
    PE,
    PF,
    PP,
    QM,
    STATUS_FK_MODE,
    STATUS_FK_NOCONV,
    STATUS_OK,
    TH,
    _body_frame,
    _body_points,
    _cross,
    _failed,
    _wrap_pi,
    ik_point,
    jacobian_point,
)


@njit(cache=True, fastmath=_FM, error_model="numpy")
def _fk_newton(theta, geo, ts2, ts3, out, maxit):
    """Newton on (theta_s2, theta_s3) so that |e-g| = l4 and |f-h| = l5 for given theta.

    The RU constraint |p - d| = dp holds by construction (p = d + Q p_b).  Returns
    (converged, ts2, ts3).
    """
    l1, l2, l3, l4, l5, l6, l7 = geo[0], geo[1], geo[2], geo[3], geo[4], geo[5], geo[6]
    t1 = theta[0]
    out[PD + 0] = 0.0
    out[PD + 1] = l1 * math.cos(t1)
    out[PD + 2] = l1 * math.sin(t1)
    gx, gy, gz = l6, l2 * math.cos(theta[1]), l2 * math.sin(theta[1])
    hx, hy, hz = -l7, l3 * math.cos(theta[2]), l3 * math.sin(theta[2])
    dy, dz = out[PD + 1], out[PD + 2]
    for _ in range(maxit):
        _body_frame(t1, ts2, ts3, out)
        _body_points(geo, out)
        ex, ey, ez = out[PE], out[PE + 1] - dy, out[PE + 2] - dz  # e - d
        fx, fy, fz = out[PF], out[PF + 1] - dy, out[PF + 2] - dz  # f - d
        egx, egy, egz = out[PE] - gx, out[PE + 1] - gy, out[PE + 2] - gz
        fhx, fhy, fhz = out[PF] - hx, out[PF + 1] - hy, out[PF + 2] - hz
        re = 0.5 * (egx * egx + egy * egy + egz * egz - l4 * l4)
        rf = 0.5 * (fhx * fhx + fhy * fhy + fhz * fhz - l5 * l5)
        # Converged when both link-length errors (re / l4, rf / l5 [m]) are at rounding
        # level.  Tested before stepping: near a type II singularity the 2x2 Jacobian is
        # nearly singular and a rounding-level residual would produce a large step.
        if abs(re) < 1e-15 * l4 and abs(rf) < 1e-15 * l5:
            return True, ts2, ts3
        wx, wy, wz = out[QM + 2], out[QM + 5], out[QM + 8]
        # d e / d ts2 = x_f x (e - d);  d e / d ts3 = w x (e - d).
        a11 = egy * (-ez) + egz * ey
        cx, cy, cz = _cross(wx, wy, wz, ex, ey, ez)
        a12 = egx * cx + egy * cy + egz * cz
        a21 = fhy * (-fz) + fhz * fy
        cx, cy, cz = _cross(wx, wy, wz, fx, fy, fz)
        a22 = fhx * cx + fhy * cy + fhz * cz
        det = a11 * a22 - a12 * a21
        if det == 0.0 or not math.isfinite(det):
            return False, ts2, ts3
        d2 = (a22 * re - a12 * rf) / det
        d3 = (-a21 * re + a11 * rf) / det
        step = math.sqrt(d2 * d2 + d3 * d3)
        if step > 0.5:  # damping: Newton steps larger than ~30 deg are not trusted
            d2 *= 0.5 / step
            d3 *= 0.5 / step
        ts2 -= d2
        ts3 -= d3
        if step < 1e-14:
            _body_frame(t1, ts2, ts3, out)
            _body_points(geo, out)
            return True, ts2, ts3
    return False, ts2, ts3


@njit(cache=True, fastmath=_FM, error_model="numpy")
def fk_point(theta, geo, mode, seeds, out, scratch):
    """Forward kinematics theta -> p for one leg, tried from each seed (ts2, ts3) in order.

    The first seed whose Newton run converges and whose IK in ``mode`` reproduces theta
    (to 1e-9 rad) wins; ``out`` then holds the IK fields at that p.  Returns the status.
    """
    status = STATUS_FK_NOCONV
    for s in range(seeds.shape[0]):
        ok, ts2, ts3 = _fk_newton(theta, geo, seeds[s, 0], seeds[s, 1], scratch, 60)
        if not ok:
            continue
        st = ik_point(scratch[PP], scratch[PP + 1], scratch[PP + 2], geo, mode, out)
        if st != STATUS_OK:
            status = STATUS_FK_MODE
            continue
        err = 0.0
        for j in range(3):
            err = max(err, abs(_wrap_pi(out[TH + j] - theta[j])))
        if err < 1e-9:
            return STATUS_OK
        status = STATUS_FK_MODE
    return _failed(out, status)


def _fk_batch(thetas, geo, mode, seeds, mass_g, accel_g):
    """Forward kinematics of (n, 3) actuated angles; ``seeds`` is (n, k, 2)."""
    n = thetas.shape[0]
    out = np.zeros((n, NF))
    for i in prange(n):
        scratch = np.empty(NF)
        st = fk_point(thetas[i], geo, mode, seeds[i], out[i], scratch)
        if st == STATUS_OK:
            jacobian_point(geo, mass_g, accel_g, out[i])
    return out


#: Threaded for large batches, serial for small ones (see _leg_kernel.full_batch).
fk_batch = njit(cache=True, parallel=True, fastmath=_FM, error_model="numpy")(_fk_batch)
fk_batch_serial = njit(cache=True, fastmath=_FM, error_model="numpy")(_fk_batch)
