"""Compiled design-search kernel: many leg designs x one workspace grid.

Parallel over designs (``prange``); each design walks the grid serially so that it can
stop at the first point its RUS chains cannot reach (pruning: such a design does not
count, paper §V-B).  Reuses the leg kernels of :mod:`kinematics._leg_kernel`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from sixplus3.kinematics._leg_kernel import NF, STATUS_OK, TAU_EXT, TH, ik_point, jacobian_point

_TWO_PI = 2.0 * math.pi


@njit(cache=True, error_model="numpy")
def _theta_ok(row, zero, direction, th_max):
    """All three actuated angles within [0, th_max] in the reading's convention.

    theta_reading = (direction * theta - zero) mod 2 pi, in [0, 2 pi): the paper counts
    angles in [0, 360) deg with the base collision at (270, 360).
    """
    for j in range(3):
        t = (direction * row[TH + j] - zero) % _TWO_PI
        if t > th_max:
            return False
    return True


@njit(cache=True, parallel=True, error_model="numpy")
def evaluate_designs(designs, base_geo, points, weights, mode, mass_g, accel_g,
                     zero, direction, th_max, tau_limit):
    """Counted area of each design [grid-weight units]; -1 where a RUS chain fails.

    ``designs`` (m, 3) holds (l2 = l3, l4 = l5, ex = fx); ``points`` (n, 3) the grid,
    ordered so that likely failures come first; ``weights`` (n,) each point's area.
    Returns (area (m,), evaluated points (m,)).
    """
    m = designs.shape[0]
    n = points.shape[0]
    area = np.zeros(m)
    work = np.zeros(m, dtype=np.int64)
    for k in prange(m):
        geo = base_geo.copy()
        geo[1] = designs[k, 0]
        geo[2] = designs[k, 0]
        geo[3] = designs[k, 1]
        geo[4] = designs[k, 1]
        geo[8] = designs[k, 2]
        geo[11] = designs[k, 2]
        row = np.empty(NF)
        acc = 0.0
        feasible = True
        i = 0
        while i < n:
            st = ik_point(points[i, 0], points[i, 1], points[i, 2], geo, mode, row, False)
            i += 1
            if st != STATUS_OK:
                feasible = False
                break
            if _theta_ok(row, zero, direction, th_max):
                jacobian_point(geo, mass_g, accel_g, row, False)
                if row[TAU_EXT] <= tau_limit:
                    acc += weights[i - 1]
        work[k] = i
        area[k] = acc if feasible else -1.0
    return area, work
