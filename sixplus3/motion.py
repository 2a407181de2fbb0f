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
            t = _frozen(self.t).reshape(-1)
            t.setflags(write=False)
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

    def with_theta(self, theta: np.ndarray) -> Motion:
        """The same times, rates and accelerations with the angles ``theta``."""
        return Motion(self.t, theta, self.theta_dot, self.theta_ddot, self.rate)


def samples_fingerprint(t: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray,
                        theta_ddot: np.ndarray, rate: float) -> str:
    """SHA-256 of a motion's samples (as float64) and its rate (:attr:`Motion.fingerprint`)."""
    sha = hashlib.sha256(repr(float(rate)).encode())
    for arr in (t, theta, theta_dot, theta_ddot):
        a = np.ascontiguousarray(np.asarray(arr, dtype=np.float64))
        sha.update(repr(a.shape).encode())
        sha.update(a.tobytes())
    return sha.hexdigest()


__all__ = ["MAX_SAMPLES", "Motion", "samples_fingerprint"]
