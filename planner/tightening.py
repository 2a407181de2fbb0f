"""What a re-solve changes after the dense check found a limit violated between the NLP's
points (:func:`tightened`), for :func:`sixplus3.planner.strategy.resolve`.

The dense check (:func:`sixplus3.planner.solution.dense_check`, the one limit rule of
:mod:`sixplus3.kinematics.checks`) names each violated limit first; a re-solve tightens
that limit's rows: the rate limits' safety shares, the platform's proxy, a reserve below
the spherical joints' limit, clearance beyond the overlap found.  A geometric limit
whose rows were imposed at the nodes only (``midpoint_rows="motion"``) first gets its
rows at the midpoints too (the formulation with every row there) before anything is
tightened.
"""

from __future__ import annotations

import math
from typing import Any

from sixplus3.planner.nlp import RATE_LIMITS, Bounds

#: [m] of clearance a re-solve asks beyond the overlap the dense check found.  Plans
#: that slide along contact dip between their points by some hundredths of a mm
#: (broad_11 of `--broad --seed 2`: 0.05 mm); 0.5 mm made that re-solve hit the iteration
#: cap and the baseline come back after 52 s, 0.1 mm re-solves it in 19 iterations
#: (BENCHMARKS.md, "Planner v2").
CLEARANCE_RESERVE = 1e-4
#: the dense check's names of the limits whose rows ``midpoint_rows="motion"`` imposes at
#: the nodes only (kinematics.checks.limit_measures, solution.dense_check)
GEOMETRIC = ("an actuated angle", "unreachable", "spherical", "interference")


def tightened(bounds: Bounds, chk: Any, spherical_limit: float) -> tuple[Bounds, bool]:
    """(the bounds with every limit the dense check ``chk`` found violated tightened,
    whether a re-solve can fix them)."""
    bad = chk.violations
    if bounds.midpoint_rows == "motion" and any(v.startswith(GEOMETRIC) for v in bad):
        # new -> old: a limit whose rows were at the nodes only, with every row at the
        # midpoints too (the measured formulation) before anything is tightened
        return bounds.replace(midpoint_rows="all"), True
    ratios = {"torque": chk.max_torque_ratio, "velocity": chk.max_velocity_ratio,
              "acceleration": chk.max_acceleration_ratio}
    safety = dict(bounds.safety)
    fixable = False
    for name in RATE_LIMITS:
        if any(v.startswith(name) for v in bad):
            safety[name] *= 0.985 / ratios[name]
            fixable = True
    new = bounds.replace(safety=safety)
    if any(v.startswith("platform") for v in bad):
        new = new.replace(platform_proxy=min(0.9, bounds.platform_proxy + 0.2))
        fixable = True
    if any(v.startswith("spherical") for v in bad):
        # bound the tilts below the limit by the overshoot found, plus 0.25 deg
        over = chk.max_spherical_tilt - (spherical_limit - bounds.spherical_reserve)
        reserve = bounds.spherical_reserve + over + math.radians(0.25)
        new = new.replace(spherical_reserve=reserve)
        fixable = fixable or reserve < math.radians(10.0)
    if any(v.startswith("interference") for v in bad):
        # ask the NLP for the overlap found plus CLEARANCE_RESERVE at its points, except
        # at the waypoints' nodes, which keep the bound they had (a given pose near
        # contact may have less than the reserve: heldout_20's has 0.1 mm at most);
        # rows that were unbounded are bounded first
        if bounds.clearance is None:
            new = new.replace(clearance=0.0)
        else:
            at_wp = (bounds.clearance if bounds.clearance_waypoints is None
                     else bounds.clearance_waypoints)
            new = new.replace(clearance=bounds.clearance - chk.min_clearance
                              + CLEARANCE_RESERVE, clearance_waypoints=at_wp)
        fixable = fixable or (new.clearance or 0.0) < 0.01
    return new, fixable


__all__ = ["CLEARANCE_RESERVE", "GEOMETRIC", "tightened"]
