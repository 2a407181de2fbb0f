"""One root exception for the whole project, with specific subclasses.

Every message says what was wrong, the valid range, and how to fix it.  The offending
value and the valid range are kept as attributes (``value``, ``valid``) so that callers
can react programmatically; subclasses add their own context (``parameter``, ``chain``,
``waypoint``, ``limit``, ...).  The command line catches :class:`Sixplus3Error` once and
prints its message on one line with exit code 2 (bad input); a trajectory that violates
a limit is reported by ``sixplus3 validate`` with exit code 1.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


class Sixplus3Error(Exception):
    """Root of every error raised on purpose by sixplus3.

    Attributes: ``value`` (the offending value, or None) and ``valid`` (a description of
    the valid range, or None).
    """

    def __init__(self, message: str, *, value: object = None, valid: object = None) -> None:
        super().__init__(message)
        self.value = value
        self.valid = valid


class InputError(Sixplus3Error, ValueError):
    """A user-supplied value is malformed (wrong shape, NaN, unknown name, ...)."""


class _NamedValueError(InputError):
    """A named value out of its valid range: ``name``, ``value``, ``valid``."""

    what = "value"

    def __init__(self, name: str, value: object, valid: str, hint: str = "") -> None:
        self.name = name
        msg = f"invalid {self.what} {name}={value!r}: must be {valid}"
        if hint:
            msg += f" ({hint})"
        super().__init__(msg, value=value, valid=valid)


class GeometryError(_NamedValueError):
    """A robot parameter is out of its valid range or inconsistent with another."""

    what = "robot parameter"

    @property
    def parameter(self) -> str:
        return self.name


class LimitError(_NamedValueError):
    """A limit is non-finite, non-positive, or looser than the robot's hardware limit.

    The robot's hardware limits are the authority: a task or a file may only tighten
    them.
    """

    what = "limit"


def check_number(name: str, value: object, lo: float, hi: float, *,
                 integer: bool = False, lo_open: bool = False) -> float:
    """The one scalar range check: ``value`` a finite number (an integer with
    ``integer``; never a bool; numpy scalars count) in [lo, hi] (``(lo, hi]`` with
    ``lo_open``), returned as a float (an int with ``integer``); else an InputError
    naming ``name`` and the valid range."""
    left = "(" if lo_open else "["
    valid = (f"an integer in {left}{lo:g}, {hi:g}]" if integer
             else f"a number in {left}{lo:g}, {hi:g}]")
    v: object = value
    if not isinstance(v, (bool, int, float)) and hasattr(v, "item"):  # a numpy scalar
        try:
            v = v.item()
        except (TypeError, ValueError):
            pass
    kinds: tuple[type, ...] = (int,) if integer else (int, float)
    if isinstance(v, bool) or not isinstance(v, kinds):
        raise InputError(f"{name} must be {valid}, got {value!r}", value=value, valid=valid)
    x = float(v)  # type: ignore[arg-type]
    if not (math.isfinite(x) and (lo < x if lo_open else lo <= x) and x <= hi):
        raise InputError(f"{name} must be {valid}, got {value!r}", value=value, valid=valid)
    return int(v) if integer else x  # type: ignore[call-overload]


class TaskError(InputError):
    """A task file or task value is malformed or out of range; nothing was planned."""


class UnreachableError(Sixplus3Error):
    """A point or pose cannot be reached by the named kinematic chain."""

    def __init__(self, chain: str, point: object, reason: str) -> None:
        self.chain = chain
        self.point = point
        self.reason = reason
        super().__init__(f"{chain} chain cannot reach {point}: {reason}", value=point,
                         valid=f"inside the reach of the {chain} chain")


class ConvergenceError(Sixplus3Error):
    """An iterative solver (forward kinematics, ...) did not converge."""


class SingularityError(Sixplus3Error):
    """A computation was asked for at (or numerically at) a singular configuration."""


class InfeasibleTaskError(Sixplus3Error):
    """No motion satisfies the task's limits; says which waypoint or limit binds."""

    def __init__(self, message: str, waypoint: int | None = None, limit: str | None = None,
                 *, value: object = None, valid: object = None) -> None:
        self.waypoint = waypoint
        self.limit = limit
        #: a failed NLP solve's work, (seconds, IPOPT iterations, seconds of function
        #: evaluations): the planner counts it in the plan it returns
        self.nlp_work: tuple[float, int, float] | None = None
        super().__init__(message, value=value, valid=valid)


class SmoothingError(Sixplus3Error):
    """Ruckig could not compute a segment."""


class TrajectoryFileError(Sixplus3Error):
    """A trajectory file is missing, corrupted, forged or made for another robot."""


class ValidationFailed(Sixplus3Error):
    """A motion failed the gate: ``exit_code`` 1 for a violated limit, 2 for a motion
    that is not consistent; ``report`` holds every finding."""

    def __init__(self, message: str, exit_code: int, report: object = None) -> None:
        self.exit_code = exit_code
        self.report = report
        super().__init__(message)


def as_float_array(value: object, name: str, valid: str) -> np.ndarray:
    """``numpy.asarray(value, dtype=float)``, or an :class:`InputError` naming ``name``
    and ``valid`` for anything that is not numbers (None, text, a mapping, ragged lists)."""
    # deferred: errors stay importable without numpy (--help)
    import numpy as np

    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        text = repr(value)
        raise InputError(f"{name} must be numbers ({valid}), got "
                         f"{text if len(text) <= 60 else text[:57] + '...'}",
                         value=text[:60], valid=valid) from None


__all__ = [
    "ConvergenceError", "GeometryError", "InfeasibleTaskError", "InputError", "LimitError",
    "SingularityError", "Sixplus3Error", "SmoothingError", "TaskError",
    "TrajectoryFileError", "UnreachableError", "ValidationFailed", "as_float_array",
]
