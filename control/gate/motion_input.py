"""The controller rates the gate accepts, and the one rate check (a motion's arrays are
checked once, where it is built: :class:`sixplus3.motion.Motion`)."""

from __future__ import annotations

import math

from sixplus3.errors import InputError

#: Controller rates accepted [Hz].  Below 1 kHz the gate and a sampled drive part: in a
#: MuJoCo replay of feed-forward held for a tick + PD (300 / 6), plans that pass the
#: gate peak at 133 N m at 100 Hz (tilt30_x: the PD loop near its discrete stability
#: bound) and at 11.0 N m at 500 Hz (translate); at 1 kHz every example stays within
#: 10 N m (docs/validation.md, "The lowest rate").  Above 10 kHz no drive listens.
RATE_RANGE = (1000.0, 10000.0)
#: Rates accepted for consumers that interpolate the quintic through the points instead
#: of holding each (a ROS 2 JointTrajectory controller with positions, velocities and
#: accelerations): the whole-interval checks prove that interpolated motion, at any rate.
INTERPOLATED_RATE_RANGE = (10.0, 10000.0)


def check_rate(rate: float, rate_range: tuple[float, float] = RATE_RANGE,
               name: str = "controller rate") -> float:
    """``rate`` [Hz] as a float if it is a finite number in ``rate_range`` (default
    :data:`RATE_RANGE`), else an InputError naming the range: the one rate check of the
    planner's pipeline, the smoothing, the MuJoCo replay and the CLI."""
    lo, hi = rate_range
    if not (isinstance(rate, (int, float)) and not isinstance(rate, bool)
            and math.isfinite(rate) and lo <= rate <= hi):
        raise InputError(f"{name} must be in [{lo:g}, {hi:g}] Hz, got {rate!r}", value=rate,
                         valid=f"[{lo:g}, {hi:g}] Hz")
    return float(rate)
