"""Compiled admissibility checks of the orientation atlas (:mod:`design.atlas`).

Scalar code compiled with numba, the same arithmetic as the numpy path it replaces
(:func:`kinematics.robot.robot_ik`, :func:`~kinematics.spherical.spherical_tilts`,
:func:`~kinematics.collision.clearance`, :func:`~kinematics.robot.platform_margin`;
``tests/test_atlas.py`` checks that they agree).  One pose's legs go through the leg
kernel of :mod:`kinematics._leg_kernel` one at a time, and each check runs only where
the checks before it passed.

Stages (the number of checks passed, in the atlas's order): 0 none, 1 reach,
2 actuated range, 3 spherical joints, 4 leg margins; for a whole pose also 5 clearance
and 6 platform margin.  The holding torque (check 7) is the compiled CasADi statics
(:func:`dynamics.symbolic.holding_function`), called by :mod:`design.atlas`.

Packed inputs (:func:`pack`):

- ``legc`` (3, 16): per leg, R_base_leg row-major (9), A_i (3), R_i in the platform
  frame (3), beta_i (1);
- ``par`` (8,): platform crank c, L = hypot(platform radius, c), theta_min,
  theta_max, cos(spherical limit), margin limit, the base plate's top z, the platform
  plate's offset above the cranks;
- the collision model (:mod:`kinematics.collision`): ``hubs`` (3, 2, 3) the static
  hubs, ``radii`` (30,), ``pairs`` (P, 2), ``base`` (9,) the bodies above the plate.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from sixplus3.kinematics import collision
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
    STATUS_OK,
    TH,
    ik_point,
    jacobian_point,
)
from sixplus3.kinematics.checks import actuated_bounds
from sixplus3.kinematics.spherical import spherical_reference

if TYPE_CHECKING:
    from sixplus3.robot_description.robot import Robot

NL = 3  # legs
_P_C, _P_L, _P_TMIN, _P_TMAX, _P_COS_SPH, _P_MARGIN, _P_BASE, _P_PLATE = range(8)
# the links of a leg in the collision model: AD, DP, BG, GE, CH, HF (kinematics.collision)
_NSEG = 6
_NBODY = 30  # kinematics.collision.N_BODIES: 18 links, 3 hubs, 9 platform bodies


def pack(robot: Robot) -> tuple[np.ndarray, ...]:
    """(legc, par, geo, mode, ref, hubs, radii, pairs, base) of a
    :class:`~robot_description.robot.Robot`."""

    g, lim = robot.geometry, robot.limits
    legc = np.zeros((NL, 16))
    for i in range(NL):
        legc[i, 0:9] = g.leg_rotation(i).ravel()
        legc[i, 9:12] = g.leg_origin(i)
        legc[i, 12:15] = g.crank_axis_position(i)
        legc[i, 15] = g.crank_axis_angle(i)

    par = np.array([g.platform_crank, math.hypot(g.platform_radius, g.platform_crank),
                    *actuated_bounds(lim), math.cos(lim.spherical), lim.margin,
                    robot.collision.base_top, robot.collision.plate_offset])
    assert collision.N_BODIES == _NBODY
    return (legc, par, g.leg.packed(), robot.mode.array(),
            np.ascontiguousarray(spherical_reference(robot)),
            np.ascontiguousarray(collision.hub_segments(robot)), collision.radii(robot),
            collision.PAIRS, collision.BASE_BODIES)


@njit(cache=True, error_model="numpy")
def _distal(row, j, link, u_out):
    """Frame (row-major 3x3, leg frame) of the distal link of crank ``j`` (1: B, 2: C).

    kinematics.robot builds it as R_x(theta + a) R_z(b) with the U-joint angles of
    ``_u_joint_angles`` (branch cos b > 0): its y axis is the link direction u, its z
    axis (0, -u_z, u_y) / |(u_y, u_z)| and x = y cross z.  The same frame, without the
    angles.
    """
    tip, end = (PG, PE) if j == 1 else (PH, PF)
    uy = (row[end + 1] - row[tip + 1]) / link
    uz = (row[end + 2] - row[tip + 2]) / link
    ux = (row[end] - row[tip]) / link
    rho = math.hypot(uy, uz)
    zy, zz = -uz / rho, uy / rho
    # x = y cross z with y = u, z = (0, zy, zz)
    u_out[0], u_out[3], u_out[6] = uy * zz - uz * zy, -ux * zz, ux * zy
    u_out[1], u_out[4], u_out[7] = ux, uy, uz
    u_out[2], u_out[5], u_out[8] = 0.0, zy, zz


@njit(cache=True, error_model="numpy")
def leg_check(pos, R, psi, i, legc, par, geo, mode, ref, row, scratch):
    """Checks 1-4 of leg ``i`` at platform pose (pos, R) with crank angle psi [rad].

    Returns (stage 0..4, min(type I, type II margin) where the IK solved, else 0).
    Leaves the leg's IK (leg frame) in ``row``; ``scratch`` (12,) is work space.
    """
    c = par[_P_C]
    b = legc[i, 15] + psi
    lx = legc[i, 12] + c * math.cos(b)
    ly = legc[i, 13] + c * math.sin(b)
    lz = legc[i, 14]
    # P_i in the robot frame, then in the leg frame: Rl^T (P - A)
    px = pos[0] + R[0, 0] * lx + R[0, 1] * ly + R[0, 2] * lz - legc[i, 9]
    py = pos[1] + R[1, 0] * lx + R[1, 1] * ly + R[1, 2] * lz - legc[i, 10]
    pz = pos[2] + R[2, 0] * lx + R[2, 1] * ly + R[2, 2] * lz - legc[i, 11]
    x = legc[i, 0] * px + legc[i, 3] * py + legc[i, 6] * pz
    y = legc[i, 1] * px + legc[i, 4] * py + legc[i, 7] * pz
    z = legc[i, 2] * px + legc[i, 5] * py + legc[i, 8] * pz
    if ik_point(x, y, z, geo, mode, row, False) != STATUS_OK:  # Q, no passive angles
        return 0, 0.0
    for j in range(3):
        t = row[TH + j]
        if t < par[_P_TMIN] or t > par[_P_TMAX]:
            return 1, 0.0
    # spherical joints E, F (body vs distal link) and P (body vs platform crank): the
    # tilt acos(a . b) exceeds the limit exactly where a . b < cos(limit)
    lim = par[_P_COS_SPH]
    for j in range(2):
        _distal(row, j + 1, geo[3 + j], scratch)
        a = ref[i, j, 0]
        bb = ref[i, j, 1]
        ax = row[QM] * a[0] + row[QM + 1] * a[1] + row[QM + 2] * a[2]
        ay = row[QM + 3] * a[0] + row[QM + 4] * a[1] + row[QM + 5] * a[2]
        az = row[QM + 6] * a[0] + row[QM + 7] * a[1] + row[QM + 8] * a[2]
        bx = scratch[0] * bb[0] + scratch[1] * bb[1] + scratch[2] * bb[2]
        by = scratch[3] * bb[0] + scratch[4] * bb[1] + scratch[5] * bb[2]
        bz = scratch[6] * bb[0] + scratch[7] * bb[1] + scratch[8] * bb[2]
        if ax * bx + ay * by + az * bz < lim:
            return 2, 0.0
    a = ref[i, 2, 0]
    bb = ref[i, 2, 1]
    # body axis in the robot frame: Rl Q a
    qx = row[QM] * a[0] + row[QM + 1] * a[1] + row[QM + 2] * a[2]
    qy = row[QM + 3] * a[0] + row[QM + 4] * a[1] + row[QM + 5] * a[2]
    qz = row[QM + 6] * a[0] + row[QM + 7] * a[1] + row[QM + 8] * a[2]
    ax = legc[i, 0] * qx + legc[i, 1] * qy + legc[i, 2] * qz
    ay = legc[i, 3] * qx + legc[i, 4] * qy + legc[i, 5] * qz
    az = legc[i, 6] * qx + legc[i, 7] * qy + legc[i, 8] * qz
    # crank axis in the robot frame: R Rz(beta_i + psi) b
    cb, sb = math.cos(b), math.sin(b)
    wx = cb * bb[0] - sb * bb[1]
    wy = sb * bb[0] + cb * bb[1]
    wz = bb[2]
    bx = R[0, 0] * wx + R[0, 1] * wy + R[0, 2] * wz
    by = R[1, 0] * wx + R[1, 1] * wy + R[1, 2] * wz
    bz = R[2, 0] * wx + R[2, 1] * wy + R[2, 2] * wz
    if ax * bx + ay * by + az * bz < lim:
        return 2, 0.0
    jacobian_point(geo, 0.0, 0.0, row, True)
    m = min(row[MARGIN_I], row[MARGIN_II])
    if m < par[_P_MARGIN]:
        return 3, m
    return 4, m


@njit(cache=True, parallel=True, error_model="numpy")
def leg_grid(pos, R, grid, legc, par, geo, mode, ref, hubs, radii, pairs, base):
    """Checks 1-4 of every leg on a grid of crank angles: pos (n, 3), R (n, 3, 3),
    grid (G,) [rad].  Returns (stage (n, G, 3) int8, score (n, G, 3): the leg's smallest
    margin where all four checks pass, else -inf).  The atlas's grid box uses it;
    :func:`free_candidates` does the same per leg and keeps the IK of the best values."""
    n, G = pos.shape[0], grid.shape[0]
    stage = np.zeros((n, G, NL), dtype=np.int8)
    score = np.full((n, G, NL), -np.inf)
    for k in prange(n):
        row = np.zeros(NF)
        scratch = np.zeros(12)
        for g in range(G):
            for i in range(NL):
                s, m = leg_check(pos[k], R[k], grid[g], i, legc, par, geo, mode, ref, row,
                                 scratch)
                stage[k, g, i] = s
                if s == 4:
                    score[k, g, i] = m
    return stage, score


@njit(cache=True, inline="always", error_model="numpy")
def _world(legc, i, row, f, geo, out):
    """Point ``row[f:f+3]`` of leg i (leg frame; f = -1: the origin A, -2: B at
    (l6, 0, 0), -3: C at (-l7, 0, 0)) into ``out`` (3,), robot frame."""
    if f == -1:
        x, y, z = 0.0, 0.0, 0.0
    elif f == -2:
        x, y, z = geo[5], 0.0, 0.0
    elif f == -3:
        x, y, z = -geo[6], 0.0, 0.0
    else:
        x, y, z = row[f], row[f + 1], row[f + 2]
    for r in range(3):
        out[r] = (legc[i, 3 * r] * x + legc[i, 3 * r + 1] * y + legc[i, 3 * r + 2] * z
                  + legc[i, 9 + r])


@njit(cache=True, error_model="numpy")
def _segments(row, i, legc, geo, out):
    """The links AD, DP, BG, GE, CH, HF of leg i in the robot frame: out (6, 2, 3)."""
    for k, (f0, f1) in enumerate(((-1, PD), (PD, PP), (-2, PG), (PG, PE), (-3, PH),
                                  (PH, PF))):
        _world(legc, i, row, f0, geo, out[k, 0])
        _world(legc, i, row, f1, geo, out[k, 1])


@njit(cache=True, error_model="numpy")
def _finish(seg, pm, m_legs, pos, R, psi, legc, par, bodies, work):
    """Checks 5-6 of a candidate whose legs all passed 1-4 (their links ``seg`` (3, 6,
    2, 3), their smallest margin ``m_legs``; its crank angles ``psi`` (3,), its
    platform margin ``pm``): (stage 4..6, margin, -inf unless both pass).  Check 5 is
    the collision model's clearance >= 0 (kinematics.collision.clearance), with the
    bodies placed here: the legs' links, the hubs, the platform's spokes, edges and
    cranks (``bodies``: hubs, radii, pairs, base; ``work``: caps, mid, half)."""
    hubs, radii, pairs, base = bodies
    caps, mid, half = work
    for i in range(NL):
        for a in range(_NSEG):
            caps[_NSEG * i + a] = seg[i, a]
        caps[_NSEG * NL + i] = hubs[i]
    c = par[_P_C]
    p0 = _NSEG * NL + NL
    for i in range(NL):
        b = legc[i, 15] + psi[i]
        for r in range(3):
            ri = pos[r] + R[r, 0] * legc[i, 12] + R[r, 1] * legc[i, 13] + R[r, 2] * legc[i, 14]
            tip = ri + c * (R[r, 0] * math.cos(b) + R[r, 1] * math.sin(b))
            up = par[_P_PLATE] * R[r, 2]  # the plate above the cranks' plane
            caps[p0 + i, 0, r] = pos[r] + up  # spoke O -> R_i
            caps[p0 + i, 1, r] = ri + up
            caps[p0 + NL + i, 0, r] = ri + up  # edge R_i -> R_{i+1}
            caps[p0 + NL + (i + NL - 1) % NL, 1, r] = ri + up
            caps[p0 + 2 * NL + i, 0, r] = ri  # crank R_i -> P_i
            caps[p0 + 2 * NL + i, 1, r] = tip
    if pose_clearance(caps, radii, pairs, base, par[_P_BASE], 0.0, mid, half) < 0.0:
        return 4, -np.inf
    if pm < par[_P_MARGIN]:
        return 5, -np.inf
    return 6, min(pm, m_legs)


@njit(cache=True, parallel=True, error_model="numpy")
def platform_margins(psi, legc, par):
    """(m,) sigma_min / sigma_max of the column-scaled 9x9 platform Jacobian
    (kinematics.robot.platform_margin) for crank angles psi (m, 3) [rad].

    It depends on the crank angles only: block row i of J is
    [I, -[R t_i]x / L, (R z x R d_i) / c] = R [R^T, -[t_i]x R^T / L, (z x d_i) / c]
    (t_i the crank tip, d_i the crank, z = (0, 0, 1), all in the platform frame), and
    multiplying by the orthogonal diag(R, R, R) on the left and diag(R, R, I) on the
    right keeps the singular values; so it is computed at R = I, from the eigenvalues of
    J^T J.  The atlas tabulates it on its crank grid (tests check it against the numpy
    function at rotated poses)."""
    m = psi.shape[0]
    out = np.empty(m)
    for k in prange(m):
        out[k] = _platform_margin(psi[k], legc, par)
    return out


@njit(cache=True, error_model="numpy")
def _platform_margin(psi, legc, par):
    c, L = par[_P_C], par[_P_L]
    J = np.zeros((9, 9))
    for i in range(NL):
        b = legc[i, 15] + psi[i]
        lx, ly = legc[i, 12], legc[i, 13]
        # r = P - O = the crank tip, s = P - R_i = the crank (platform frame)
        sx, sy = c * math.cos(b), c * math.sin(b)
        rx, ry, rz = lx + sx, ly + sy, legc[i, 14]
        o = 3 * i
        J[o, 0] = J[o + 1, 1] = J[o + 2, 2] = 1.0
        # -[r]x / L
        J[o, 4], J[o, 5] = rz / L, -ry / L
        J[o + 1, 3], J[o + 1, 5] = -rz / L, rx / L
        J[o + 2, 3], J[o + 2, 4] = ry / L, -rx / L
        # z x s / c with z = (0, 0, 1)
        J[o, 6 + i], J[o + 1, 6 + i] = -sy / c, sx / c
    ev = np.linalg.eigvalsh(J.T @ J)  # ascending
    if ev[8] <= 0.0:
        return 0.0
    return math.sqrt(max(ev[0], 0.0) / ev[8])


@njit(cache=True, parallel=True, error_model="numpy")
def pose_checks(pos, R, psi, platform, packed):
    """Checks 1-6 of candidate crank choices: pos (n, 3), R (n, 3, 3), psi (n, k, 3)
    [rad], with their platform margins ``platform`` (n, k) (:func:`platform_margins`,
    which depend on psi only), for the robot ``packed`` (legc, par, geo, mode, ref,
    hubs, radii, pairs, base: ``AtlasChecks.packed``).  Returns (stage (n, k) int8:
    checks passed, 0..6; margin (n, k): the smallest leg and platform margin where all
    six pass, else -inf)."""
    legc, par, geo, mode, ref, hubs, radii, pairs, base = packed
    n, K = psi.shape[0], psi.shape[1]
    stage = np.zeros((n, K), dtype=np.int8)
    margin = np.full((n, K), -np.inf)
    for k in prange(n):
        row = np.zeros(NF)
        scratch = np.zeros(12)
        seg = np.empty((NL, _NSEG, 2, 3))
        caps = np.empty((_NBODY, 2, 3))
        mid = np.empty((_NBODY, 3))
        half = np.empty(_NBODY)
        for c in range(K):
            s_min = 4
            m_min = np.inf
            for i in range(NL):
                s, m = leg_check(pos[k], R[k], psi[k, c, i], i, legc, par, geo, mode, ref,
                                 row, scratch)
                if s < s_min:
                    s_min = s
                if s == 0:
                    break
                if s == 4:
                    m_min = min(m_min, m)
                    _segments(row, i, legc, geo, seg[i])
            stage[k, c] = s_min
            if s_min == 4:
                stage[k, c], margin[k, c] = _finish(
                    seg, platform[k, c], m_min, pos[k], R[k], psi[k, c], legc, par,
                    (hubs, radii, pairs, base), (caps, mid, half))
    return stage, margin


@njit(cache=True, parallel=True, error_model="numpy")
def free_candidates(pos, R, grid, table, packed):
    """The free search's candidates and their checks 1-6, in one pass per pose, for the
    robot ``packed`` (as :func:`pose_checks`).

    Checks 1-4 of every leg on the crank grid (as :func:`leg_grid`); per leg the best
    grid value by the leg's smallest margin (the first maximum) and the second best (the
    best otherwise where no other value passes); the 4 candidates are the best values
    and, each leg in turn, its second best; checks 5-6 reuse the legs' IK (a candidate's
    legs passed 1-4 on the grid) and ``table`` (G, G, G), the platform margins of the
    grid (:func:`platform_margins`).

    Returns (idx (n, 4, 3) grid indices, stage (n, 4) int8 (checks passed, 0..6; 0 where
    not all legs have a passing value), margin (n, 4) (-inf unless all six pass),
    leg_best (n, 3) int8: the most checks any grid value of each leg passed).
    """
    legc, par, geo, mode, ref, hubs, radii, pairs, base = packed
    n, G = pos.shape[0], grid.shape[0]
    idx = np.zeros((n, 4, NL), dtype=np.int64)
    stage = np.zeros((n, 4), dtype=np.int8)
    margin = np.full((n, 4), -np.inf)
    leg_best = np.zeros((n, NL), dtype=np.int8)
    for k in prange(n):
        row = np.zeros(NF)
        scratch = np.zeros(12)
        seg = np.empty((2, NL, _NSEG, 2, 3))  # the best and second values' links
        cand = np.empty((NL, _NSEG, 2, 3))
        caps = np.empty((_NBODY, 2, 3))
        mid = np.empty((_NBODY, 3))
        half = np.empty(_NBODY)
        psi_c = np.empty(NL)
        score = np.full((2, NL), -np.inf)
        pick = np.zeros((2, NL), dtype=np.int64)
        live = True
        for i in range(NL):
            top = 0
            for g in range(G):
                s, m = leg_check(pos[k], R[k], grid[g], i, legc, par, geo, mode, ref, row,
                                 scratch)
                if s > top:
                    top = s
                if s < 4:
                    continue
                if m > score[0, i]:
                    score[1, i], pick[1, i] = score[0, i], pick[0, i]
                    seg[1, i] = seg[0, i]
                    score[0, i], pick[0, i] = m, g
                    _segments(row, i, legc, geo, seg[0, i])
                elif m > score[1, i]:
                    score[1, i], pick[1, i] = m, g
                    _segments(row, i, legc, geo, seg[1, i])
            leg_best[k, i] = top
            if top < 4:
                live = False
            elif score[1, i] == -np.inf:  # one passing value: the second is the best
                pick[1, i] = pick[0, i]
                seg[1, i] = seg[0, i]
                score[1, i] = score[0, i]
        if not live:
            continue
        for c in range(4):
            m_min = np.inf
            for i in range(NL):
                w = 1 if c == i + 1 else 0
                idx[k, c, i] = pick[w, i]
                cand[i] = seg[w, i]
                psi_c[i] = grid[pick[w, i]]
                m_min = min(m_min, score[w, i])
            pm = table[idx[k, c, 0], idx[k, c, 1], idx[k, c, 2]]
            stage[k, c], margin[k, c] = _finish(cand, pm, m_min, pos[k], R[k], psi_c, legc,
                                                par, (hubs, radii, pairs, base),
                                                (caps, mid, half))
    return idx, stage, margin, leg_best
