"""The doors of the gate's library functions: the controller rates accepted, and the
checks a motion handed in as arrays passes before anything is allocated per sample."""

from __future__ import annotations

import math

import numpy as np

from sixplus3.control.file.trajectory_file import MAX_SAMPLES
from sixplus3.errors import InputError
from sixplus3.fileio import short_repr

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


def check_motion_arrays(t: object, theta: object, theta_dot: object, theta_ddot: object,
                        rate: object) -> None:
    """Refuse, before anything is allocated per sample, a motion the gate does not take:
    a rate that is not a real number (a string, a bool), arrays that are missing, not
    real numbers (complex, objects) or longer than the file format's cap of
    :data:`~sixplus3.control.file.trajectory_file.MAX_SAMPLES` samples."""
    if isinstance(rate, bool) or not isinstance(rate, (int, float, np.integer, np.floating)):
        raise InputError(f"rate must be a number [Hz], got {type(rate).__name__}",
                         value=short_repr(rate, 40), valid=f"a number in {RATE_RANGE} Hz")
    for name, arr in (("t", t), ("theta", theta), ("theta_dot", theta_dot),
                      ("theta_ddot", theta_ddot)):
        if arr is None:
            raise InputError(f"{name} is missing", value=None, valid="an array of numbers")
        shape = np.shape(arr)  # type: ignore[call-overload]  # a view: nothing allocated
        if len(shape) == 0 or shape[0] > MAX_SAMPLES:
            raise InputError(f"{name} must have 1 to {MAX_SAMPLES} samples, got "
                             f"{shape[0] if shape else 'a scalar'}", value=shape,
                             valid=f"<= {MAX_SAMPLES} samples")
        kind = np.asarray(arr).dtype.kind if not isinstance(arr, np.ndarray) else arr.dtype.kind
        if kind not in "iuf":
            raise InputError(f"{name} must be real numbers, got dtype kind {kind!r}",
                             value=kind, valid="real (integer or float) numbers")
