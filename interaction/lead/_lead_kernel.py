"""The lead-through's per-tick arithmetic, compiled (numba): the wrench's deadband, the
admittance with its caps and tank, the walls' least change, and the command
(:class:`~sixplus3.interaction.lead.leadthrough.LeadThrough`, whose module doc states each
step; it keeps the state and the mode logic, these kernels the arithmetic, on its
preallocated arrays).

``sc``, the scalar state: [the tank's initial energy, the energy the person put in, the
tank, the tank's least value]."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sixplus3.interaction.lead._walls_kernel import moved
from sixplus3.interaction.observer._tick_kernel import (
    friction,
    lu_factor,
    lu_solve,
    matvec,
    skew_squared,
)

E0, PORT, TANK, MIN_TANK = 0, 1, 2, 3


@njit(cache=True, error_model="numpy")
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, error_model="numpy")
def _exp3(r):
    """exp([r]x) of a small rotation vector (one tick's turn)."""
    t2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    K = np.zeros((3, 3))
    K[0, 1], K[0, 2], K[1, 2] = -r[2], r[1], -r[0]
    K[1, 0], K[2, 0], K[2, 1] = r[2], -r[1], r[0]
    if t2 < 1e-8:
        return np.eye(3) + K + 0.5 * skew_squared(r)
    t = math.sqrt(t2)
    return np.eye(3) + (math.sin(t) / t) * K + ((1.0 - math.cos(t)) / t2) * skew_squared(r)


@njit(cache=True, error_model="numpy")
def lead_input(w, std, band, J, thd, off, n_sigma, w_t, w_in, lu, piv):
    """The wrench moved to the tool point ``w_t`` (m_tcp = m_c - off x f), and the input
    beyond the deadband ``w_in`` (n_sigma std + band; the moments' band grows by |off|
    times the largest force band); returns (whether any component is beyond, the power
    w_t . v_meas of the measured twist J^-1 thd at the tool point, info: nonzero when J
    is singular)."""
    tmp = np.empty(3)
    _cross(off, w[:3], tmp)
    for k in range(3):
        w_t[k] = w[k]
        w_t[3 + k] = w[3 + k] - tmp[k]
    thr = np.empty(6)
    for k in range(6):
        thr[k] = n_sigma * std[k] + band[k]
    top = max(thr[0], max(thr[1], thr[2]))
    lo = math.sqrt(off[0] * off[0] + off[1] * off[1] + off[2] * off[2])
    for k in range(3, 6):
        thr[k] += lo * top
    beyond = False
    for k in range(6):
        ex = abs(w_t[k]) - thr[k]
        if ex > 0.0:
            beyond = True
            w_in[k] = ex if w_t[k] > 0.0 else -ex
        else:
            w_in[k] = 0.0
    info = lu_factor(J, lu, piv)
    if info != 0:
        return beyond, 0.0, info
    xi = np.empty(9)
    lu_solve(lu, piv, thd, xi)
    _cross(xi[3:6], off, tmp)
    power = 0.0
    for k in range(3):
        power += w_t[k] * (xi[k] + tmp[k]) + w_t[3 + k] * xi[3 + k]
    return beyond, power, 0


@njit(cache=True, error_model="numpy")
def admittance(w_in, v, psi_dot, wish, mass, damping, dt, accel, speed, crank_step, sc):
    """One semi-implicit step of M_v dv/dt + D_v v = w_in (in place on v), the energy
    tank first (at T <= 0 only the input that slows the platform), then each block's
    acceleration and speed caps, and the crank rates toward ``wish`` within
    ``crank_step``."""
    kinetic = 0.0
    for k in range(6):
        kinetic += 0.5 * mass[k] * v[k] * v[k]
    sc[TANK] = sc[E0] + sc[PORT] - kinetic
    if sc[TANK] > 4.0 * sc[E0]:  # capped: the surplus is not kept
        sc[PORT] -= sc[TANK] - 4.0 * sc[E0]
        sc[TANK] = 4.0 * sc[E0]
    sc[MIN_TANK] = min(sc[MIN_TANK], sc[TANK])
    empty = sc[TANK] <= 0.0
    v_prev = v.copy()
    for k in range(6):
        f = 0.0 if (empty and w_in[k] * v[k] > 0.0) else w_in[k]
        v[k] = (v[k] + dt / mass[k] * f) / (1.0 + dt * damping[k] / mass[k])
    for b in range(2):
        s = 3 * b
        dv0, dv1, dv2 = v[s] - v_prev[s], v[s + 1] - v_prev[s + 1], v[s + 2] - v_prev[s + 2]
        n = math.sqrt(dv0 * dv0 + dv1 * dv1 + dv2 * dv2)
        if n > accel[b] * dt:
            k = accel[b] * dt / n
            v[s], v[s + 1], v[s + 2] = (v_prev[s] + dv0 * k, v_prev[s + 1] + dv1 * k,
                                        v_prev[s + 2] + dv2 * k)
        sp = math.sqrt(v[s] * v[s] + v[s + 1] * v[s + 1] + v[s + 2] * v[s + 2])
        if sp > speed[b]:
            for i in range(s, s + 3):
                v[i] *= speed[b] / sp
    for i in range(3):
        d = wish[i] - psi_dot[i]
        psi_dot[i] += min(max(d, -crank_step), crank_step)


@njit(cache=True, error_model="numpy")
def keep_out(v, psi_dot, G, b, n, cranks, scale):
    """The least change of (v, omega L, psi_dot L) (the walls' metric, L = ``scale``)
    that keeps g . x >= b for the ``n`` walls (rows of G, b), by cyclic projections (5
    sweeps); without ``cranks`` the walls' crank columns are ignored.  In place."""
    if n == 0:
        return
    x = np.empty(9)
    for i in range(3):
        x[i], x[3 + i], x[6 + i] = v[i], v[3 + i] * scale, psi_dot[i] * scale
    m = 9 if cranks else 6
    for _ in range(5):
        for k in range(n):
            gg = 0.0
            into = 0.0
            for i in range(m):
                gg += G[k, i] * G[k, i]
                into += G[k, i] * x[i]
            if gg == 0.0 or into >= b[k]:
                continue
            f = (b[k] - into) / gg
            for i in range(m):
                x[i] += f * G[k, i]
    for i in range(3):
        v[i], v[3 + i], psi_dot[i] = x[i], x[3 + i] / scale, x[6 + i] / scale


@njit(cache=True, error_model="numpy")
def command(model, motion, ref, anchor, has_anchor, settings, ff):
    """The reference: the joint rates J (v_centre, omega, psi_dot) (the whole twist
    scaled within ``rate_cap``, v and psi_dot too), integrated into the pose, the cranks
    and the angles (from ``anchor`` when the slow update solved the pose); ``tdr`` (the
    rate reference) updated in place; tau_ff = h - friction(thd) + friction(rates) +
    M (the reference's acceleration), within +-cap, into ``ff``.  ``model``: (J, M, h,
    thd) this tick; ``motion``: (v, psi_dot, lead); ``ref``: (tdr, p_ref, R_ref,
    psi_ref, theta_ref), in place; ``settings``: (tool, rate_cap, dt, viscous, coulomb,
    speed, cap)."""
    J, M, h, thd = model
    v, psi_dot, lead = motion
    tdr, p_ref, R_ref, psi_ref, theta_ref = ref
    tool, rate_cap, dt, viscous, coulomb, speed, cap = settings
    off = np.empty(3)
    matvec(R_ref, tool, off)
    xi = np.empty(9)
    tmp = np.empty(3)
    _cross(v[3:6], off, tmp)
    for i in range(3):
        xi[i] = v[i] - tmp[i]
        xi[3 + i] = v[3 + i]
        xi[6 + i] = psi_dot[i] if lead else 0.0
    rates = np.empty(9)
    matvec(J, xi, rates)
    top = 0.0
    for i in range(9):
        top = max(top, abs(rates[i]))
    if top > rate_cap:  # within the joints' rate share: the whole twist scaled
        k = rate_cap / top
        for i in range(9):
            rates[i] *= k
            xi[i] *= k
        for i in range(6):
            v[i] *= k
        for i in range(3):
            psi_dot[i] *= k
    acc = (rates - tdr) / dt
    tdr[:] = rates
    for i in range(3):
        p_ref[i] += xi[i] * dt
        psi_ref[i] += xi[6 + i] * dt
    E = _exp3(xi[3:6] * dt)
    Rn = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            Rn[i, j] = E[i, 0] * R_ref[0, j] + E[i, 1] * R_ref[1, j] + E[i, 2] * R_ref[2, j]
    R_ref[:, :] = Rn
    for i in range(9):
        base = anchor[i] if has_anchor else theta_ref[i]
        theta_ref[i] = base + rates[i] * dt
    f0 = np.empty(9)
    f1 = np.empty(9)
    friction(thd, viscous, coulomb, speed, f0)
    friction(rates, viscous, coulomb, speed, f1)
    Ma = np.empty(9)
    matvec(M, acc, Ma)
    for i in range(9):
        ff[i] = min(max(h[i] - f0[i] + f1[i] + Ma[i], -cap), cap)


@njit(cache=True, error_model="numpy")
def slow_scalars(sl, solved, n_probe, crank_step, band, prev_now, dt_prev, horizon, grad,
                 active, inside):
    """The slow update's arithmetic on its poses' slacks sl (interaction.lead.leadthrough,
    _slow_update: row 0 the reference, 1-6 the cranks turned by +- crank_step, 7.. the
    probes): ``inside`` (n_probe,) whether each probe has an assembly and every slack
    above min(the reference's, 0); ``grad`` (3,) the crank score's central gradient
    (walls.crank_score: the singularity slack less how deep the spherical and range
    slacks are inside ``band``); ``active`` (4,) the walls near: a slack inside ``band``
    now or within ``horizon`` at the rate it fell since ``prev_now`` (``dt_prev`` ago; 0:
    none).  Returns |grad| and the number of walls near."""
    floor = 0.0
    for c in range(4):
        floor = min(floor, sl[0, c])
    for m in range(n_probe):
        ok = solved[7 + m]
        for c in range(4):
            ok = ok and sl[7 + m, c] >= floor
        inside[m] = ok
    gn = 0.0
    for i in range(3):
        up = sl[1 + i, 0] + min(sl[1 + i, 1] - band, 0.0) + min(sl[1 + i, 2] - band, 0.0)
        down = sl[4 + i, 0] + min(sl[4 + i, 1] - band, 0.0) + min(sl[4 + i, 2] - band, 0.0)
        grad[i] = (up - down) / (2.0 * crank_step)
        gn += grad[i] * grad[i]
    n_active = 0
    for c in range(4):
        ahead = sl[0, c]
        if dt_prev > 0.0:
            rate = (sl[0, c] - prev_now[c]) / dt_prev
            if math.isfinite(rate) and rate < 0.0:
                ahead = sl[0, c] + rate * horizon
        active[c] = min(sl[0, c], ahead) < band
        n_active += active[c]
    return math.sqrt(gn), n_active


@njit(cache=True, error_model="numpy")
def update_poses(pose, motion, off, settings, tw, out, u):
    """The lead-through's slow update's poses (interaction.lead.leadthrough, 5) from the
    reference ``pose`` (p, R, psi_ref) into ``out`` (pos, rot, psi): row 0 the
    reference, rows 1-3 and 4-6 each crank turned by +- ``crank_step``, rows 7.. the
    probes ahead (``probes`` [m] along the direction u (9,) of the ``motion`` (v,
    psi_dot), metric: rotations and cranks times ``scale``; ``settings``: (scale,
    crank_step, probes)) of the tool point ``off`` (R tool); tw (n, 6) work.  Returns
    |(v, omega scale, psi_dot scale)| (0: u = 0)."""
    p, R, psi_ref = pose
    v, psi_dot = motion
    scale, crank_step, probes = settings
    pos, rot, psi = out
    n_probe = probes.shape[0]
    nx = 0.0
    for i in range(9):
        x = v[i] if i < 3 else (v[i] * scale if i < 6 else psi_dot[i - 6] * scale)
        u[i] = x
        nx += x * x
    nx = math.sqrt(nx)
    for i in range(9):
        u[i] = u[i] / nx if nx > 0.0 else 0.0
    tw[:, :] = 0.0
    for r in range(7 + n_probe):
        for i in range(3):
            psi[r, i] = psi_ref[i]
    for i in range(3):
        psi[1 + i, i] += crank_step
        psi[4 + i, i] -= crank_step
    for m in range(n_probe):
        r = 7 + m
        d = probes[m]
        # the tool point moves by u[:3] d: the centre by that less omega x off
        w0, w1, w2 = u[3] * d / scale, u[4] * d / scale, u[5] * d / scale
        tw[r, 0] = u[0] * d - (w1 * off[2] - w2 * off[1])
        tw[r, 1] = u[1] * d - (w2 * off[0] - w0 * off[2])
        tw[r, 2] = u[2] * d - (w0 * off[1] - w1 * off[0])
        tw[r, 3], tw[r, 4], tw[r, 5] = w0, w1, w2
        for i in range(3):
            psi[r, i] += u[6 + i] * d / scale
    moved(p, R, tw, pos, rot)
    return nx
