"""One root exception for the whole project, with specific subclasses.

Every message says what was wrong, the valid range, and how to fix it; the offending
values are kept as attributes so that callers can react programmatically.
"""

from __future__ import annotations


class Sixplus3Error(Exception):
    """Root of every error raised on purpose by sixplus3."""


class GeometryError(Sixplus3Error, ValueError):
    """A geometric parameter is out of its valid range or inconsistent with another."""

    def __init__(self, parameter: str, value: object, valid: str, hint: str = "") -> None:
        self.parameter = parameter
        self.value = value
        self.valid = valid
        msg = f"invalid geometry parameter {parameter}={value!r}: must be {valid}"
        if hint:
            msg += f" ({hint})"
        super().__init__(msg)


class InputError(Sixplus3Error, ValueError):
    """A user-supplied value is malformed (wrong shape, NaN, unknown name, ...)."""


class UnreachableError(Sixplus3Error):
    """A point or pose cannot be reached by the named kinematic chain."""

    def __init__(self, chain: str, point: object, reason: str) -> None:
        self.chain = chain
        self.point = point
        self.reason = reason
        super().__init__(f"{chain} chain cannot reach {point}: {reason}")


class ConvergenceError(Sixplus3Error):
    """An iterative solver (forward kinematics, ...) did not converge."""


class SingularityError(Sixplus3Error):
    """A computation was asked for at (or numerically at) a singular configuration."""
