"""Compiled kernels of the collision model (:mod:`kinematics.collision`): the distance
between two segments, and the clearance of whole poses.

Scalar code compiled with numba, the same arithmetic as the numpy reference
:func:`kinematics.collision._segment_distance` (tested to agree): the distance between two
segments is Ericson's closest-point computation, clamped to both segments.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always", error_model="numpy")
def _clip01(x):
    return min(max(x, 0.0), 1.0)


@njit(cache=True, inline="always", error_model="numpy")
def _distance(d1x, d1y, d1z, d2x, d2y, d2z, rx, ry, rz):
    """Distance between the segments p1 + s d1 and p2 + t d2 (s, t in [0, 1]), r = p1 - p2
    (scalars: no array views, whose reference counts cost more than the arithmetic)."""
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    c = d1x * rx + d1y * ry + d1z * rz
    b = d1x * d2x + d1y * d2y + d1z * d2z
    den = a * e - b * b
    s = _clip01((b * f - c * e) / max(den, 1e-300)) if den > 1e-14 else 0.0
    t = (b * s + f) / max(e, 1e-300)
    t_c = _clip01(t)
    if t < 0.0:
        s = _clip01(-c / max(a, 1e-300))
    elif t > 1.0:
        s = _clip01((b - c) / max(a, 1e-300))
    dx = rx + d1x * s - d2x * t_c
    dy = ry + d1y * s - d2y * t_c
    dz = rz + d1z * s - d2z * t_c
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, error_model="numpy")
def segment_distance(p1, q1, p2, q2):
    """Distance between the segments [p1, q1] and [p2, q2] (3-vectors) [m]."""
    return _distance(q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2], q2[0] - p2[0],
                     q2[1] - p2[1], q2[2] - p2[2], p1[0] - p2[0], p1[1] - p2[1],
                     p1[2] - p2[2])


@njit(cache=True, inline="always", error_model="numpy")
def capsule_distance(caps, a, b):
    """:func:`segment_distance` of the segments caps[a] and caps[b] ((K, 2, 3))."""
    return _distance(caps[a, 1, 0] - caps[a, 0, 0], caps[a, 1, 1] - caps[a, 0, 1],
                     caps[a, 1, 2] - caps[a, 0, 2], caps[b, 1, 0] - caps[b, 0, 0],
                     caps[b, 1, 1] - caps[b, 0, 1], caps[b, 1, 2] - caps[b, 0, 2],
                     caps[a, 0, 0] - caps[b, 0, 0], caps[a, 0, 1] - caps[b, 0, 1],
                     caps[a, 0, 2] - caps[b, 0, 2])


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


@njit(cache=True, error_model="numpy")
def pose_clearance(caps, radii, pairs, base, base_top, stop, mid, half):
    """Smallest signed surface distance of one pose's collision model [m].

    caps (K, 2, 3) capsule segments, radii (K,), pairs (P, 2) the body pairs compared,
    base (B,) the bodies kept above the plane z = base_top; mid (K, 3), half (K,) work
    space.  A pair whose bounding spheres (centre the midpoint, radius half the length
    plus the capsule radius) are further apart than the best distance so far cannot be
    the minimum and is not measured: the result is exact.  Returns as soon as the
    minimum is below ``stop`` (-inf: never), with a value below ``stop``.
    """
    best = np.inf
    for b in base:
        low = min(caps[b, 0, 2], caps[b, 1, 2]) - radii[b] - base_top
        best = min(best, low)
        if best < stop:
            return best
    for k in range(caps.shape[0]):
        h = 0.0
        for r in range(3):
            mid[k, r] = 0.5 * (caps[k, 0, r] + caps[k, 1, r])
            h += (caps[k, 1, r] - caps[k, 0, r]) ** 2
        half[k] = 0.5 * math.sqrt(h) + radii[k]
    for m in range(pairs.shape[0]):
        a, b = pairs[m, 0], pairs[m, 1]
        d2 = 0.0
        for r in range(3):
            d2 += (mid[a, r] - mid[b, r]) ** 2
        reach = best + half[a] + half[b]
        if reach > 0.0 and d2 >= reach * reach:
            continue
        d = capsule_distance(caps, a, b)
        best = min(best, d - radii[a] - radii[b])
        if best < stop:
            return best
    return best


@njit(cache=True, parallel=True, error_model="numpy")
def batch_clearance(caps, radii, pairs, base, base_top):
    """(n,) :func:`pose_clearance` of every pose of caps (n, K, 2, 3), exact."""
    n, k = caps.shape[0], caps.shape[1]
    out = np.empty(n)
    for m in prange(n):
        mid = np.empty((k, 3))
        half = np.empty(k)
        out[m] = pose_clearance(caps[m], radii, pairs, base, base_top, -np.inf, mid, half)
    return out


@njit(cache=True, parallel=True, error_model="numpy")
def pair_distances(caps, radii, pairs):
    """(n, P) signed surface distance of every pair of every pose [m] (no pruning)."""
    n, p = caps.shape[0], pairs.shape[0]
    out = np.empty((n, p))
    for m in prange(n):
        for j in range(p):
            a, b = pairs[j, 0], pairs[j, 1]
            out[m, j] = capsule_distance(caps[m], a, b) - radii[a] - radii[b]
    return out
