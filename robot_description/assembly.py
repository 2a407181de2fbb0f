"""Assembly modes of the RU/2-RUS leg: which of the 2^4 inverse-kinematics branches.

A robot is assembled once, in one mode, and never switches inside a motion; the mode is
part of the :class:`sixplus3.robot_description.Robot`.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from sixplus3.errors import InputError


@dataclass(frozen=True)
class AssemblyMode:
    """One of the 2^4 IK branches, as signs (+1/-1) for (th1, th_s3, th2, th3).

    - th1: ``+`` is th1 = atan2(z, y) + acos(k / r): the proximal link is rotated
      positively about x_f from the direction of P (for P in the horizontal half-plane,
      D above it: the paper's configuration);
    - th_s3: ``+`` is cos th_s3 > 0: E (the +ey body point) lies on the +x_f side, the side
      of B it is linked to;
    - th2, th3: ``+`` likewise rotates each crank positively from the direction of its
      spherical joint.

    The default mode ``++++`` is the paper's assembly (all links above the horizontal
    plane for points of the design half-plane).  Names are four characters of + and -,
    e.g. ``+-++``; ``default`` is an alias of ``++++``.
    """

    signs: tuple[int, int, int, int]

    ALIASES: ClassVar[dict[str, str]] = {"default": "++++"}

    def __post_init__(self) -> None:
        if not isinstance(self.signs, (tuple, list)) or len(self.signs) != 4 or any(
                isinstance(s, bool) or s not in (1, -1) for s in self.signs):
            raise InputError(f"assembly mode signs must be four values in {{+1, -1}}, got "
                             f"{self.signs!r}", value=self.signs, valid="four values in {+1, -1}")

    @property
    def name(self) -> str:
        return "".join("+" if s > 0 else "-" for s in self.signs)

    def __str__(self) -> str:
        return self.name

    @classmethod
    def parse(cls, name: str | AssemblyMode) -> AssemblyMode:
        if isinstance(name, AssemblyMode):
            return name
        key = cls.ALIASES.get(str(name).strip().lower(), str(name).strip())
        if len(key) != 4 or any(ch not in "+-" for ch in key):
            raise InputError(
                f"unknown assembly mode {name!r}: use four characters of '+'/'-' for "
                "(th1, th_s3, th2, th3), e.g. '++++', or 'default'"
            , value=name, valid="four of '+'/'-', or 'default'")
        return cls(tuple(1 if ch == "+" else -1 for ch in key))  # type: ignore[arg-type]

    @classmethod
    def all(cls) -> list[AssemblyMode]:
        return [cls(s) for s in itertools.product((1, -1), repeat=4)]  # type: ignore[arg-type]

    def array(self) -> np.ndarray:
        return np.array(self.signs, dtype=np.float64)


DEFAULT_MODE = AssemblyMode((1, 1, 1, 1))
