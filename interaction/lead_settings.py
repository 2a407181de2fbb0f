"""Lead-through's settings read by name with their ranges (interaction/leadthrough.py):
per-axis values of the tool point, as a (translation, rotation) pair or six numbers."""

from __future__ import annotations

import numpy as np

from sixplus3.errors import InputError, check_number


def six(name: str, value: object, lo: float, hi: float) -> np.ndarray:
    """Six values (translation x3, rotation x3) from a (translation, rotation) pair or
    six numbers, each within [lo, hi]."""
    vals = list(value) if isinstance(value, (list, tuple, np.ndarray)) else [value]
    if len(vals) == 2:
        vals = [vals[0]] * 3 + [vals[1]] * 3
    if len(vals) != 6:
        raise InputError(f"{name} must be (translation, rotation) or 6 numbers",
                         value=repr(value)[:80], valid="2 or 6 numbers")
    return np.array([check_number(name, v, lo, hi) for v in vals])


def pair(name: str, value: object, lo: float, hi: float) -> tuple[float, float]:
    """A (translation, rotation) pair of numbers, each within [lo, hi]."""
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 2:
        raise InputError(f"{name} must be a (translation, rotation) pair of numbers, got "
                         f"{repr(value)[:80]}", value=repr(value)[:80],
                         valid=f"2 numbers in [{lo:g}, {hi:g}]")
    return (check_number(name, value[0], lo, hi), check_number(name, value[1], lo, hi))


__all__ = ["pair", "six"]
