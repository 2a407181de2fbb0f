"""The collision model's clearance in CasADi: smooth lower bounds for the planner's rows.

The same bodies and radii as the numeric clearance of
:mod:`sixplus3.kinematics.collision`, written with CasADi symbols: the distance between
two capsules' segments (the numeric closest-point formula), and per family of body
pairs a soft minimum that never exceeds the true minimum.  Used by
:mod:`sixplus3.dynamics.symbolic` to build the node function's clearance rows.
"""

from __future__ import annotations

from typing import Any

import casadi as ca

from sixplus3.kinematics.collision import BASE_BODIES, PAIR_FAMILY, PAIRS, radii
from sixplus3.kinematics.near import near_pairs
from sixplus3.robot_description.robot import Robot


def segment_distance(p1: Any, q1: Any, p2: Any, q2: Any) -> Any:
    """Distance between segments [p1, q1] and [p2, q2] with CasADi symbols: the same
    closest-point formula as :func:`kinematics.collision._segment_distance`."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = ca.dot(d1, d1), ca.dot(d2, d2)
    f, c, b = ca.dot(d2, r), ca.dot(d1, r), ca.dot(d1, d2)
    den = a * e - b * b

    def clip01(v: Any) -> Any:
        return ca.fmin(ca.fmax(v, 0), 1)

    s = ca.if_else(den > 1e-14, clip01((b * f - c * e) / ca.fmax(den, 1e-300)), 0)
    t = (b * s + f) / ca.fmax(e, 1e-300)
    s = ca.if_else(t < 0, clip01(-c / ca.fmax(a, 1e-300)),
                   ca.if_else(t > 1, clip01((b - c) / ca.fmax(a, 1e-300)), s))
    diff = (p1 + d1 * s) - (p2 + d2 * clip01(t))
    return ca.sqrt(ca.dot(diff, diff) + 1e-12)


#: sharpness of the soft minimum over body pairs [1/m]: each row under-estimates the
#: true minimum of its pairs by at most ln(pairs in the row) / 2000 m (on the safe side)
CLEARANCE_SHARPNESS = 2000.0
#: The rows measure the pairs that come within this of contact somewhere in the sample
#: of :func:`sixplus3.kinematics.near.near_pairs` [m]
PAIR_MARGIN = 0.02
#: The value of a row none of whose pairs comes near in that sample [m]
FAR = 1.0


def clearance_rows(caps: Any, robot: Robot) -> ca.SX:
    """(3,) smooth lower bounds on the collision model's clearance [m]
    (:mod:`sixplus3.kinematics.collision`: same bodies and radii): the bodies of the
    legs (links and hubs), the platform against the legs and hubs, the platform above
    the base plate.  Each row is a soft minimum -ln(sum exp(-k d)) / k, shifted for
    numerical range, over the pairs of its family that come within ``PAIR_MARGIN`` of
    contact in :func:`~sixplus3.kinematics.near.near_pairs`'s sample (all 333 make
    a C file gcc needs 15 GB to optimise); the dense check and the gate measure every
    pair."""

    r = radii(robot)
    pair_idx, base_idx = near_pairs(robot, PAIR_MARGIN)
    fams: dict[str, list[Any]] = {"legs": [], "platform": [], "base": []}
    for m in pair_idx:
        a, b = PAIRS[m]
        d = segment_distance(*caps[a], *caps[b]) - float(r[a] + r[b])
        fams["platform" if PAIR_FAMILY[m] == "platform" else "legs"].append(d)
    top = robot.collision.base_top
    for m in base_idx:
        b = BASE_BODIES[m]
        fams["base"].append(ca.fmin(caps[b][0][2], caps[b][1][2]) - float(r[b]) - top)
    k = CLEARANCE_SHARPNESS
    rows = []
    for dist in fams.values():
        if not dist:
            rows.append(ca.SX(FAR))
            continue
        dmin = dist[0]
        for dd in dist[1:]:
            dmin = ca.fmin(dmin, dd)
        acc = sum(ca.exp(-k * (dd - dmin)) for dd in dist)
        rows.append(dmin - ca.log(acc) / k)
    return ca.vertcat(*rows)


__all__ = ["CLEARANCE_SHARPNESS", "FAR", "PAIR_MARGIN", "clearance_rows", "segment_distance"]
