"""A sampled motion of the nine actuated joints: one frozen value.

:class:`Motion` holds the sample times t (n,) [s], the angles theta, the rates theta_dot
and the accelerations theta_ddot (n, 9) [rad, rad/s, rad/s^2] of the actuated joints and
the rate they are sampled at [Hz].  It is what the planner's smoothing produces
(``Smoothed.motion``), what the trajectory file's reader returns (``TrajectoryData.motion``),
and what the gate (``validate_motion``), the writer, the exports and the feed take.

It is checked once, when it is built, before anything is allocated per sample: the rate
is a real number, every array is real numbers of the right shape, at most
:data:`MAX_SAMPLES` samples.  Its arrays are float64 copies, read-only: no one who holds
a motion can change what another judged.  Whether the motion is a *valid* motion (a grid
at the rate, finite, at rest at its ends, within the limits) is the gate's to judge
(docs/validation.md): a motion with a NaN is a motion the gate refuses, not a malformed
value.  Its :attr:`~Motion.fingerprint` (the SHA-256 of the samples and the rate) is
computed once; a validation report records the fingerprint of the motion it judged and
the writer refuses a report of another motion.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from sixplus3.errors import InputError
from sixplus3.fileio import short_repr

#: Most samples of a motion this package makes or takes (a plan at a rate, its dwells, a
#: slower replay): 2 minutes at 1 kHz.  Checked before anything is allocated.
MAX_SAMPLES = 120_000

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


def check_samples(duration: float, rate: float, what: str) -> int:
    """The number of samples of ``duration`` [s] at ``rate`` [Hz], refused (InputError
    naming ``what``) past :data:`MAX_SAMPLES`, before anything is allocated."""
    n = duration * rate + 1 if math.isfinite(duration * rate) else math.inf
    if not n <= MAX_SAMPLES:
        raise InputError(f"{what}: {duration:.6g} s at {rate:g} Hz would make {n:.6g} "
                         f"samples, over the cap of {MAX_SAMPLES} ({MAX_SAMPLES / rate:g} s "
                         "at this rate): shorten it, or plan it in parts", value=n,
                         valid=f"<= {MAX_SAMPLES} samples")
    return int(n)


_ARRAYS = ("t", "theta", "theta_dot", "theta_ddot")


def _check_kinds(arrays: dict[str, object], rate: object) -> None:
    """Refuse, before anything is allocated per sample, what is not a motion: a rate that
    is not a real number (a string, a bool), arrays that are missing, not real numbers
    (complex, objects) or longer than :data:`MAX_SAMPLES`."""
    if isinstance(rate, bool) or not isinstance(rate, (int, float, np.integer, np.floating)):
        raise InputError(f"rate must be a number [Hz], got {type(rate).__name__}",
                         value=short_repr(rate, 40), valid="a number [Hz]")
    for name, arr in arrays.items():
        if arr is None:
            raise InputError(f"{name} is missing", value=None, valid="an array of numbers")
        shape = np.shape(arr)  # type: ignore[call-overload]  # a view: nothing allocated
        if len(shape) == 0 or shape[0] > MAX_SAMPLES:
            raise InputError(f"{name} must have 1 to {MAX_SAMPLES} samples, got "
                             f"{shape[0] if shape else 'a scalar'}", value=shape,
                             valid=f"<= {MAX_SAMPLES} samples")
        kind = arr.dtype.kind if isinstance(arr, np.ndarray) else np.asarray(arr).dtype.kind
        if kind not in "iuf":
            raise InputError(f"{name} must be real numbers, got dtype kind {kind!r}",
                             value=kind, valid="real (integer or float) numbers")


def _frozen(arr: object) -> np.ndarray:
    out = np.array(arr, dtype=np.float64, order="C")  # a copy: the caller keeps theirs
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class Motion:
    """Samples of the actuated joints (module doc): ``t`` (n,) [s]; ``theta``,
    ``theta_dot``, ``theta_ddot`` (n, 9) [rad, rad/s, rad/s^2]; ``rate`` [Hz]."""

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    rate: float

    def __post_init__(self) -> None:
        _check_kinds({k: getattr(self, k) for k in _ARRAYS}, self.rate)
        try:
            t = _frozen(self.t).reshape(-1)  # a view of a read-only copy: read-only
            arrays = [_frozen(getattr(self, k)) for k in _ARRAYS[1:]]
        except (TypeError, ValueError) as exc:
            raise InputError(f"the motion must be numeric arrays: {exc}"[:200], value=None,
                             valid="(n,) times and (n, 9) arrays") from None
        n = len(t)
        for name, arr in zip(_ARRAYS[1:], arrays, strict=True):
            if arr.shape != (n, 9):
                raise InputError(f"{name} must be ({n}, 9), got {arr.shape}",
                                 value=arr.shape, valid=f"({n}, 9)")
        object.__setattr__(self, "t", t)
        for name, arr in zip(_ARRAYS[1:], arrays, strict=True):
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "rate", float(self.rate))

    @classmethod
    def on_grid(cls, theta: object, theta_dot: object, theta_ddot: object,
                rate: object) -> Motion:
        """The motion sampled at t = k / ``rate``, k = 0 .. n - 1."""
        _check_kinds({"theta": theta}, rate)
        n = int(np.shape(theta)[0])  # type: ignore[call-overload]
        r = float(rate)  # type: ignore[arg-type]
        t = np.arange(n) / r if math.isfinite(r) and r > 0 else np.full(n, np.nan)
        return cls(t, theta, theta_dot, theta_ddot, r)  # type: ignore[arg-type]

    def __len__(self) -> int:
        return len(self.t)

    @property
    def duration(self) -> float:
        """The last sample's time [s]."""
        return float(self.t[-1])

    @cached_property
    def fingerprint(self) -> str:
        """SHA-256 of the samples (as float64) and the rate: what a validation report
        records of the motion it judged, and what the writer checks."""
        return samples_fingerprint(self.t, self.theta, self.theta_dot, self.theta_ddot,
                                   self.rate)

    def window(self, start: int, stop: int) -> Motion:
        """Samples ``start`` .. ``stop`` - 1: views of this motion's read-only arrays
        (checked once, when this motion was made), not copies."""
        out = object.__new__(Motion)
        for name in _ARRAYS:
            object.__setattr__(out, name, getattr(self, name)[start:stop])
        object.__setattr__(out, "rate", self.rate)
        return out

    def with_theta(self, theta: np.ndarray) -> Motion:
        """The same times, rates and accelerations with the angles ``theta``."""
        return Motion(self.t, theta, self.theta_dot, self.theta_ddot, self.rate)


class HasMotion:
    """A value holding a ``motion`` (the smoothing's result, the feed's plan) reads its
    samples through it: ``t``, ``theta``, ``theta_dot``, ``theta_ddot``, ``rate``."""

    motion: Motion

    @property
    def t(self) -> np.ndarray:
        """(n,) [s]"""
        return self.motion.t

    @property
    def theta(self) -> np.ndarray:
        """(n, 9) [rad]"""
        return self.motion.theta

    @property
    def theta_dot(self) -> np.ndarray:
        """(n, 9) [rad/s]"""
        return self.motion.theta_dot

    @property
    def theta_ddot(self) -> np.ndarray:
        """(n, 9) [rad/s^2]"""
        return self.motion.theta_ddot

    @property
    def rate(self) -> float:
        """[Hz]"""
        return self.motion.rate


def samples_fingerprint(t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray,
                        theta_ddot: np.ndarray, rate: float) -> str:
    """SHA-256 of a motion's samples (as float64) and its rate (:attr:`Motion.fingerprint`)."""
    sha = hashlib.sha256(repr(float(rate)).encode())
    for arr in (t, theta, theta_dot, theta_ddot):
        a = np.ascontiguousarray(np.asarray(arr, dtype=np.float64))
        sha.update(repr(a.shape).encode())
        sha.update(a.tobytes())
    return sha.hexdigest()


__all__ = ["INTERPOLATED_RATE_RANGE", "MAX_SAMPLES", "RATE_RANGE", "HasMotion", "Motion",
           "check_rate",
           "check_samples", "samples_fingerprint"]
