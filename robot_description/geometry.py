"""Parametric geometry of the RU/2-RUS leg (paper Fig. 2, docs/conventions.md conventions).

Leg frame: origin at A, x along the common actuated axis x_f, y horizontal towards the
robot centre, z up.  With Q = R(x, th1) R(x, ths2) R(z, ths3 - pi/2) (paper eq. 1-2):

    d = a + l1 [0, cos th1, sin th1]      b = a + l6 x_f      c = a - l7 x_f
    g = b + l2 [0, cos th2, sin th2]      h = c + l3 [0, cos th3, sin th3]
    p = d + Q p_b,  e = d + Q e_b,  f = d + Q f_b,  p_b = [dp, 0, 0]

E (the +ey side of the body) is linked to B (the +l6 side); F to C.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from sixplus3.errors import GeometryError

#: Standard gravity [m/s^2] used by every static/dynamic computation.
GRAVITY = 9.81

# Order of the packed parameter vector handed to the compiled kernels.
_PACK_ORDER = ("l1", "l2", "l3", "l4", "l5", "l6", "l7", "dp", "ex", "ey", "ez", "fx", "fy", "fz")

#: Largest length accepted for any link [m]; a guard against unit mistakes (mm vs m).
MAX_LENGTH = 5.0


def _length(doc: str, default: float) -> float:
    return field(default=default, metadata={"doc": doc, "unit": "m"})


@dataclass(frozen=True)
class LegGeometry:
    """Every length of one RU/2-RUS leg [m], with the paper's optimal design as default.

    The defaults are the paper's optimum (l2 = 0.139, l4 = 0.350, ex = 0.097) with
    l1 = dp = 0.350 and l6 = l7 = 0.130; ey = -fy = 0.020 is our choice (the paper says
    "as small as possible" without a number).
    """

    l1: float = _length("proximal link of the RU chain, |D - A| [m]", 0.350)
    l2: float = _length("crank of the RUS chain at B, |G - B| [m]", 0.139)
    l3: float = _length("crank of the RUS chain at C, |H - C| [m]", 0.139)
    l4: float = _length("distal link of the RUS chain at B, |E - G| [m]", 0.350)
    l5: float = _length("distal link of the RUS chain at C, |F - H| [m]", 0.350)
    l6: float = _length("offset of B along +x_f from A [m]", 0.130)
    l7: float = _length("offset of C along -x_f from A [m]", 0.130)
    dp: float = _length("distance |P - D| of the end-effector from the U joint [m]", 0.350)
    ex: float = _length("E in the body frame, along D->P [m]", 0.097)
    ey: float = _length("E in the body frame, along y_b (towards B) [m]", 0.020)
    ez: float = _length("E in the body frame, along z_b [m]", 0.0)
    fx: float = _length("F in the body frame, along D->P [m]", 0.097)
    fy: float = _length("F in the body frame, along y_b [m]", -0.020)
    fz: float = _length("F in the body frame, along z_b [m]", 0.0)

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise GeometryError(f.name, v, "a real number in metres")
            if not math.isfinite(float(v)):
                raise GeometryError(f.name, v, "finite")
            object.__setattr__(self, f.name, float(v))
        for name in ("l1", "l2", "l3", "l4", "l5", "l6", "l7", "dp"):
            v = getattr(self, name)
            if not 0.0 < v <= MAX_LENGTH:
                raise GeometryError(
                    name, v, f"in (0, {MAX_LENGTH}] m", "lengths are in metres, not mm"
                )
        for name in ("ex", "ey", "ez", "fx", "fy", "fz"):
            v = getattr(self, name)
            if abs(v) > MAX_LENGTH:
                raise GeometryError(name, v, f"in [-{MAX_LENGTH}, {MAX_LENGTH}] m")
        if self.ey < self.fy:
            raise GeometryError(
                "ey", self.ey, f">= fy = {self.fy}",
                "E is the +y_b side of the body and is linked to B (docs/conventions.md)",
            )
        # A RUS chain closes only if |S - R| can lie in [|crank - link|, crank + link].
        # |E - B| <= l1 + |e_b| + l6 everywhere (triangle inequality through A and D), so
        # a distal link longer than crank + that bound can never close.
        for side, crank, link, off, body in (
            ("B", self.l2, self.l4, self.l6, self.e_b),
            ("C", self.l3, self.l5, self.l7, self.f_b),
        ):
            far = self.l1 + float(np.linalg.norm(body)) + off
            if link - crank >= far:
                raise GeometryError(
                    "l4" if side == "B" else "l5", link, f"< crank + {far:.4f} m",
                    f"the RUS chain at {side} could never close",
                )

    # ------------------------------------------------------------------ helpers
    @classmethod
    def symmetric(cls, l2: float, l4: float, ex: float, **kw: float) -> LegGeometry:
        """The symmetric leg of paper §V: l3 = l2, l5 = l4, fx = ex, fy = -ey, fz = ez."""
        base = cls(**kw) if kw else cls()
        return replace(base, l2=l2, l3=l2, l4=l4, l5=l4, ex=ex, fx=ex,
                       fy=-base.ey, fz=base.ez)

    def packed(self) -> np.ndarray:
        """Parameters as a float64 vector in kernel order (l1..l7, dp, e_b, f_b)."""
        return np.array([getattr(self, n) for n in _PACK_ORDER], dtype=np.float64)

    @property
    def e_b(self) -> np.ndarray:
        """E in the body frame [m], shape (3,)."""
        return np.array([self.ex, self.ey, self.ez])

    @property
    def f_b(self) -> np.ndarray:
        """F in the body frame [m], shape (3,)."""
        return np.array([self.fx, self.fy, self.fz])

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class LegLoad:
    """Load model of the paper's design study (§V-A): a point mass at P."""

    mass: float = field(default=0.5, metadata={"doc": "moving mass lumped at P [kg]"})
    accel_g: float = field(
        default=2.0, metadata={"doc": "required acceleration of P in any direction [g]"}
    )
    gravity: float = field(default=GRAVITY, metadata={"doc": "gravity [m/s^2]"})
    torque_limit: float = field(default=10.0, metadata={"doc": "actuator torque limit [N m]"})

    def __post_init__(self) -> None:
        for name, lo in (("mass", 0.0), ("accel_g", 0.0), ("gravity", 0.0),
                         ("torque_limit", 0.0)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= lo):
                raise GeometryError(name, v, f"a finite number >= {lo}")
            object.__setattr__(self, name, float(v))
        if self.torque_limit == 0.0:
            raise GeometryError("torque_limit", 0.0, "> 0 N m")
