"""The motion between samples: the quintic Hermite interpolant, bounded over whole intervals.

A trajectory file holds samples (theta, theta_dot, theta_ddot) every dt.  The motion the
gate judges between two samples is the quintic Hermite interpolant of both ends' data,
the C^2 motion through them.  On interval k, with s in [0, 1] and t = (k + s) dt, each
joint's position is a polynomial of degree 5 in s (:func:`coefficients`).  Its velocity,
acceleration and jerk are polynomials of degree 4, 3 and 2, whose largest magnitude over
the interval is found exactly: at an end or at a real root of the derivative in [0, 1]
(:func:`max_abs`).  Nothing is sampled, so no zig-zag hides between evaluation points.

**How much jerk a real motion's samples allow.**  The interpolant reproduces polynomials
of degree <= 5 exactly, so on an interval where the real motion is a cubic (a jerk-limited
profile between two switches) it *is* the real motion.  Where the jerk switches inside an
interval, the interpolant's jerk differs from the real one.  For every motion with
|jerk| <= J through the samples, the interpolant's jerk is at most :data:`C_JERK` J: the
L1 norm of the Peano kernel that maps the real jerk on the interval to the interpolant's
jerk at s, maximised over s (``tests/test_gate.py`` recomputes it).  An interpolant
whose jerk exceeds that is not the sampling of any motion within the jerk limit: a
*defect* (the zig-zag forgeries end here).  Likewise the interpolant's acceleration is
within :data:`C_ACC` J dt of the real motion's.

**Torque between the checked points.**  For a fixed configuration q and rate theta_dot,
the actuated torque of the closed chain is affine in theta_ddot:
tau = M(q) theta_ddot + b(q, theta_dot), with M = S^T M_tree S the reduced inertia
(rotors included) and b the rest (gravity, velocity terms, friction).  The gate evaluates
both exactly (Pinocchio) at the samples and the midpoints.  Between two neighbouring
checked points (half an interval) M and b move only with q and theta_dot, slowly;
theta_ddot moves fast (up to the whole acceleration range in one interval at the jerk
limit).  So on each half interval

    tau(u) ~ (1 - u) b_0 + u b_1 + ((1 - u) M_0 + u M_1) theta_ddot(u),   u in [0, 1]

with theta_ddot(u) the interpolant's exact cubic: a polynomial of degree 4 in u per joint,
bounded exactly.  What the straight lines for M and b miss is measured on the same
interval: the whole interval's line (ends only) predicts the midpoint's exact torque with
an error e; a half interval's line misses about e / 4 (second order), and the bound adds
e / 2, with e the largest of the interval's and its two neighbours' (where the motion
switches inside an interval, its own e can nearly vanish while one half is curved).
:func:`torque_bound` returns the bound per interval and joint.
"""

from __future__ import annotations

import math
from math import comb
from typing import TYPE_CHECKING

import numpy as np

from sixplus3.control.file.file_format import columns
from sixplus3.errors import InputError
from sixplus3.kinematics.rotations import rotvec_from_quat

if TYPE_CHECKING:
    from sixplus3.control.report import ValidationReport

#: For every motion with |jerk| <= J through the samples, the interpolant's jerk is at
#: most C_JERK J (Peano kernel, see the module doc; 2.17575... rounded up).
C_JERK = 2.1758
#: ... and its acceleration differs from the motion's by at most C_ACC J dt.
C_ACC = 0.20834


def coefficients(dt: float, th: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """(6, n - 1, m) coefficients c_0..c_5 of the interpolant's position in s on each
    interval, from samples (n, m) of positions, rates and accelerations spaced ``dt``."""
    p0, p1 = th[:-1], th[1:]
    v0, v1 = v[:-1] * dt, v[1:] * dt
    a0, a1 = a[:-1] * dt**2, a[1:] * dt**2
    d = p1 - p0
    return np.stack([
        p0, v0, a0 / 2,
        10 * d - 6 * v0 - 4 * v1 - (3 * a0 - a1) / 2,
        -15 * d + 8 * v0 + 7 * v1 + (3 * a0 - 2 * a1) / 2,
        6 * d - 3 * (v0 + v1) - (a0 - a1) / 2,
    ])


def derivative(c: np.ndarray) -> np.ndarray:
    """Coefficients (in s) of d/ds of the polynomials ``c`` (first axis: degree)."""
    k = np.arange(1, len(c)).reshape((-1,) + (1,) * (c.ndim - 1))
    return c[1:] * k


def evaluate(c: np.ndarray, s: np.ndarray | float) -> np.ndarray:
    """The polynomials ``c`` (first axis: degree) at ``s`` (broadcast), by Horner."""
    out = np.zeros(np.broadcast_shapes(c.shape[1:], np.shape(s)))
    for ck in c[::-1]:
        out = out * s + ck
    return out


def _real_roots_01(c: np.ndarray) -> np.ndarray:
    """(r, ...) real roots in [0, 1] of the polynomials ``c`` (degree <= 3, first axis),
    NaN where there are fewer; a polynomial that vanishes identically gives none."""
    shape = c.shape[1:]
    flat = c.reshape(len(c), -1)
    deg = len(c) - 1
    out = np.full((max(deg, 1), flat.shape[1]), np.nan)
    scale = np.abs(flat).max(axis=0)
    tiny = 1e-12 * np.where(scale > 0, scale, 1.0)
    # the effective degree of each polynomial: its highest coefficient that is not tiny
    eff = np.zeros(flat.shape[1], dtype=int)
    for k in range(deg, 0, -1):
        eff = np.where((eff == 0) & (np.abs(flat[k]) > tiny), k, eff)
    with np.errstate(all="ignore"):
        one = eff == 1
        out[0, one] = -flat[0, one] / flat[1, one]
        two = eff == 2
        if two.any():
            a2, a1, a0 = flat[2, two], flat[1, two], flat[0, two]
            disc = a1**2 - 4 * a2 * a0
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            # the numerically stable pair of roots
            qq = -0.5 * (a1 + np.copysign(sq, a1))
            out[0, two] = qq / a2
            out[1, two] = np.where(qq != 0, a0 / qq, np.nan)
        three = eff == 3
        if three.any():
            out[:3, three] = _cubic_real_roots(flat[3, three], flat[2, three],
                                               flat[1, three], flat[0, three])
    out[(out < 0) | (out > 1)] = np.nan
    return out.reshape((len(out),) + shape)


def _cubic_real_roots(a3: np.ndarray, a2: np.ndarray, a1: np.ndarray,
                      a0: np.ndarray) -> np.ndarray:
    """(3, m) real roots of a3 x^3 + a2 x^2 + a1 x + a0 (a3 != 0), NaN where fewer: the
    closed form (Cardano / the trigonometric form), each polished by two Newton steps."""
    with np.errstate(all="ignore"):
        B, C, D = a2 / a3, a1 / a3, a0 / a3
        p = C - B**2 / 3
        q = 2 * B**3 / 27 - B * C / 3 + D
        disc = (q / 2) ** 2 + (p / 3) ** 3
        roots = np.full((3,) + B.shape, np.nan)
        one = disc > 0
        sq = np.sqrt(np.where(one, disc, 0.0))
        roots[0] = np.where(one, np.cbrt(-q / 2 + sq) + np.cbrt(-q / 2 - sq), np.nan)
        three = ~one
        r = np.sqrt(np.where(three, -p / 3, 0.0))
        arg = np.where(three & (r > 0), -q / 2 / np.where(r > 0, r, 1.0) ** 3, 0.0)
        phi = np.arccos(np.clip(arg, -1.0, 1.0)) / 3
        for k in range(3):
            tk = 2 * r * np.cos(phi - 2 * np.pi * k / 3)
            roots[k] = np.where(three, tk, roots[k])
        roots -= B / 3
        for _ in range(2):  # Newton on the original polynomial
            f = ((a3 * roots + a2) * roots + a1) * roots + a0
            df = (3 * a3 * roots + 2 * a2) * roots + a1
            step = np.where(np.abs(df) > 0, f / np.where(df != 0, df, 1.0), 0.0)
            roots = roots - np.where(np.isfinite(step), step, 0.0)
    return roots


def max_abs(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(max |p(s)| over s in [0, 1], the s where it is reached) of the polynomials ``c``
    (degree <= 4, first axis): exact, at an end or a real root of p' in [0, 1]."""
    roots = _real_roots_01(derivative(c))
    cand = np.concatenate([np.zeros((1,) + c.shape[1:]), np.ones((1,) + c.shape[1:]),
                           roots])
    vals = np.abs(evaluate(c[:, None], np.nan_to_num(cand, nan=0.0)))
    vals = np.where(np.isnan(cand), -np.inf, vals)
    best = np.argmax(vals, axis=0)
    return (np.take_along_axis(vals, best[None], 0)[0],
            np.take_along_axis(np.nan_to_num(cand), best[None], 0)[0])


def rate_extremes(dt: float, th: np.ndarray, v: np.ndarray,
                  a: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Largest |theta_dot|, |theta_ddot| and |jerk| of the interpolant on each interval and
    joint: {"velocity" | "acceleration" | "jerk": (value (n-1, m), s (n-1, m))}."""
    c = coefficients(dt, th, v, a)
    c1 = derivative(c)
    c2 = derivative(c1)
    c3 = derivative(c2)
    return {"velocity": _scaled(max_abs(c1), 1 / dt),
            "acceleration": _scaled(max_abs(c2), 1 / dt**2),
            "jerk": _scaled(max_abs(c3), 1 / dt**3)}


def _scaled(pair: tuple[np.ndarray, np.ndarray], k: float) -> tuple[np.ndarray, np.ndarray]:
    return pair[0] * k, pair[1]


def hermite(dt: float, th: np.ndarray, v: np.ndarray, a: np.ndarray, k: np.ndarray,
            s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(theta, theta_dot, theta_ddot) at fraction s in [0, 1] of interval k (arrays) of
    the quintic Hermite interpolant through the samples (th, v, a) spaced dt [s]."""
    k = np.asarray(k, dtype=int)
    c = coefficients(dt, np.stack([th[k], th[k + 1]]), np.stack([v[k], v[k + 1]]),
                     np.stack([a[k], a[k + 1]]))[:, 0]
    ss = np.asarray(s, dtype=float)[:, None]
    c1 = derivative(c)
    return evaluate(c, ss), evaluate(c1, ss) / dt, evaluate(derivative(c1), ss) / dt**2


def hermite_midpoints(dt: float, th: np.ndarray, v: np.ndarray,
                      a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(theta, theta_dot, theta_ddot) halfway between consecutive samples."""
    k = np.arange(len(th) - 1)
    return hermite(dt, th, v, a, k, np.full(len(k), 0.5))


def torque_bound(dt: float, th: np.ndarray, v: np.ndarray, a: np.ndarray,
                 tau_s: np.ndarray, m_s: np.ndarray, tau_m: np.ndarray,
                 m_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(bound (n-1, 9) on |tau| over each whole interval and joint, the s where the model
    peaks) from the exact torques ``tau_s`` (n, 9) and reduced inertias ``m_s`` (n, 9, 9)
    at the samples and ``tau_m``, ``m_m`` at the midpoints (module doc).  NaN torques
    (singular states) give an infinite bound."""
    c = coefficients(dt, th, v, a)
    acc = derivative(derivative(c)) / dt**2  # (4, n-1, 9): theta_ddot(s), degree 3
    b_s = tau_s - np.einsum("nij,nj->ni", m_s, a)
    a_m = evaluate(acc, 0.5)
    b_m = tau_m - np.einsum("nij,nj->ni", m_m, a_m)
    # the whole interval's straight line predicts the midpoint: its miss measures what a
    # half interval's straight line misses (about a quarter of it; 2x margin).  Where
    # the motion changes inside an interval (a jerk switch), that interval's own miss can
    # nearly vanish while one half is curved; the curvature on either side of the switch
    # is its neighbours', so each interval takes the largest miss of itself and its two
    # neighbours (a real plan's interval read 1.6e-4 N m where its neighbours read 6e-3,
    # and its torque exceeded the bound by 1.2e-5 N m, tests/test_gate_attacks.py)
    pred = 0.5 * (b_s[:-1] + b_s[1:]) + np.einsum(
        "nij,nj->ni", 0.5 * (m_s[:-1] + m_s[1:]), a_m)
    miss = np.abs(tau_m - pred)
    near = np.pad(miss, ((1, 1), (0, 0)), mode="edge")
    slack = 0.5 * np.maximum.reduce([near[:-2], near[1:-1], near[2:]])
    best = np.full(tau_m.shape, -np.inf)
    where = np.zeros(tau_m.shape)
    for half, (b0, b1, m0, m1) in enumerate(((b_s[:-1], b_m, m_s[:-1], m_m),
                                             (b_m, b_s[1:], m_m, m_s[1:]))):
        # theta_ddot(u) on this half: s = (half + u) / 2, a cubic in u
        acc_u = _rescale(acc, 0.5 * half, 0.5)  # (4, n-1, 9)
        # (b0 + u (b1 - b0)) + (m0 + u (m1 - m0)) acc_u(u): degree 4 in u
        poly = np.zeros((5,) + tau_m.shape)
        poly[0] += b0
        poly[1] += b1 - b0
        poly[:4] += np.einsum("nij,knj->kni", m0, acc_u)
        poly[1:] += np.einsum("nij,knj->kni", m1 - m0, acc_u)
        val, s = max_abs(poly)
        take = val > best
        best = np.where(take, val, best)
        where = np.where(take, 0.5 * (half + s), where)
    bound = best + slack
    return np.nan_to_num(bound, nan=np.inf), where


def _rescale(c: np.ndarray, s0: float, h: float) -> np.ndarray:
    """Coefficients in u of the polynomials ``c`` in s, with s = s0 + h u."""
    deg = len(c) - 1
    out = np.zeros_like(c)
    # p(s0 + h u) = sum_k c_k (s0 + h u)^k = sum_k c_k sum_j C(k, j) s0^(k-j) h^j u^j
    for k in range(deg + 1):
        for j in range(k + 1):
            out[j] += c[k] * (comb(k, j) * s0 ** (k - j) * h**j)
    return out


#: How a drive holding each feed-forward for a tick is given the torque: ``sample`` the
#: torque at the tick, ``mean`` the mean of the torques at both ends of the interval the
#: drive holds it over (docs/validation.md, "Torque for sampled drives").
TORQUE_HOLDS = ("sample", "mean")


def check_torque_hold(hold: object) -> str:
    """``hold`` if it is one of :data:`TORQUE_HOLDS`, else an InputError naming them."""
    if hold not in TORQUE_HOLDS:
        raise InputError(f"torque hold must be one of {', '.join(TORQUE_HOLDS)}, got "
                         f"{hold!r}", value=hold, valid=", ".join(TORQUE_HOLDS))
    return str(hold)


def held_torque(tau: np.ndarray, hold: str) -> np.ndarray:
    """The feed-forward a sampled drive holds from each tick to the next: ``tau`` itself
    (``sample``), or (tau_k + tau_{k+1}) / 2 (``mean``; the last sample keeps its own,
    at rest)."""
    check_torque_hold(hold)
    tau = np.asarray(tau, dtype=float)
    if hold == "sample" or len(tau) < 2:
        return tau
    return np.vstack([0.5 * (tau[:-1] + tau[1:]), tau[-1:]])


def resample(rep: ValidationReport, rate: float, speed: float = 1.0
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The validated motion of ``rep`` (a report of
    :func:`~sixplus3.control.gate.validation.validate_file`) at ``rate`` [Hz], replayed at
    ``speed`` (time x 1/speed, rates x speed, accelerations x speed^2), on the quintic
    Hermite interpolant of its samples; the resting end is held until the next point of
    the new grid.  Returns (t, theta, theta_dot, theta_ddot, x_seed), the last the
    validated platform poses at the nearest samples (to seed the forward kinematics).
    The caller validates the result again."""
    data, header = rep.data, rep.header
    assert data is not None and header is not None and rep.position is not None
    assert rep.quaternion is not None and rep.psi is not None
    r0 = float(header["rate_hz"])
    n = len(data)
    T = float(data[-1, 0])
    m = math.ceil(T / speed * rate - 1e-9)
    t = np.arange(m + 1) / rate
    u = np.minimum(t * speed, T) * r0  # in sample periods of the file
    k = np.minimum(np.floor(u + 1e-9).astype(int), n - 2)
    frac = np.clip(u - k, 0.0, 1.0)
    th, v, a = hermite(1.0 / r0, columns(data, "pos"), columns(data, "vel"),
                       columns(data, "acc"), k, frac)
    v, a = v * speed, a * speed**2
    v[[0, -1]] = 0.0  # the file starts and ends at rest (checked)
    a[[0, -1]] = 0.0
    near = np.minimum(np.rint(u).astype(int), n - 1)
    x = np.c_[rep.position[near], rotvec_from_quat(rep.quaternion[near]),
              rep.psi[near]]
    return t, th, v, a, x


__all__ = ["C_ACC", "C_JERK", "TORQUE_HOLDS", "check_torque_hold", "coefficients",
           "derivative", "evaluate",
           "held_torque", "hermite", "hermite_midpoints", "max_abs", "rate_extremes", "resample",
           "torque_bound"]
