"""Compiled kernel of the leg-interference check (:func:`kinematics.robot.leg_clearance`).

Scalar code compiled with numba, the same arithmetic as the numpy reference
:func:`kinematics.robot._segment_distance` (tested to agree): the distance between two
segments is Ericson's closest-point computation, clamped to both segments.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always", error_model="numpy")
def _clip01(x):
    return min(max(x, 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def segment_distance(p1, q1, p2, q2):
    """Distance between the segments [p1, q1] and [p2, q2] (3-vectors) [m]."""
    a = b = c = e = f = 0.0
    for k in range(3):
        d1 = q1[k] - p1[k]
        d2 = q2[k] - p2[k]
        r = p1[k] - p2[k]
        a += d1 * d1
        e += d2 * d2
        f += d2 * r
        c += d1 * r
        b += d1 * d2
    den = a * e - b * b
    s = _clip01((b * f - c * e) / max(den, 1e-300)) if den > 1e-14 else 0.0
    t = (b * s + f) / max(e, 1e-300)
    t_c = _clip01(t)
    if t < 0.0:
        s = _clip01(-c / max(a, 1e-300))
    elif t > 1.0:
        s = _clip01((b - c) / max(a, 1e-300))
    dist2 = 0.0
    for k in range(3):
        dk = (p1[k] + (q1[k] - p1[k]) * s) - (p2[k] + (q2[k] - p2[k]) * t_c)
        dist2 += dk * dk
    return math.sqrt(dist2)


@njit(cache=True, error_model="numpy")
def min_link_distance(seg, links):
    """(n,) smallest distance between the links ``links`` of different legs.

    seg (n, legs, links, 2 ends, 3) segments [m]; links (k,) int64 the link indices
    compared (every pair of legs, every pair of those links).
    """
    n, legs = seg.shape[0], seg.shape[1]
    out = np.empty(n)
    for m in range(n):
        best = np.inf
        for i in range(legs):
            for j in range(i + 1, legs):
                for a in links:
                    for b in links:
                        d = segment_distance(seg[m, i, a, 0], seg[m, i, a, 1],
                                             seg[m, j, b, 0], seg[m, j, b, 1])
                        best = min(best, d)
        out[m] = best
    return out
