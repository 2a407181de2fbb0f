"""The collision model: the physical size of every body, as capsules (docs/robot.md,
"Collision model").

Every moving link is a capsule (a segment swept by a sphere) around its joint-to-joint
segment; the static parts at the base are capsules too, and the base plate is the
half-space below ``base_top``.  One model, one set of sizes: the planner's rows, its
dense check, the gate, the COW, the atlas and the layout study all measure the same
bodies (:mod:`sixplus3.kinematics.collision`).

Bodies (36 capsules, indices of :data:`sixplus3.kinematics.collision.BODIES`):

- per leg i, the moving links AD, DP, BG, GE, CH, HF (``link_radius``; the cranks
  ``crank_radius``; the carbon distal tubes GE, HF ``distal_radius``);
- per leg i, the crank hubs at A, B and C: the 72-tooth belt pulley and the joint's
  bearing housing, coaxial with the actuated axis, centred on the joint
  (``hub_radius``, ``hub_width``);
- the platform plate, as the three spokes O -> R_i and the three edges R_i -> R_j
  (``plate_radius``: half the plate's thickness), ``plate_offset`` above the plane of
  the three platform cranks R_i -> P_i (``link_radius``);
- the base plate: the half-space z <= ``base_top``.  The motors (Yaskawa SGMCS-05B,
  outer diameter 135 mm, code "B" of the SGMCS model designation) are below it and
  drive the hubs through the belts; no moving body reaches below the plate, so they
  need no capsule of their own.

Sizes are ASSUMPTIONS until the prototype's CAD exists (docs/robot.md says why each).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from sixplus3.errors import GeometryError


def _size(default: float, doc: str) -> Any:
    return field(default=default, metadata={"doc": doc, "unit": "m"})


#: Largest radius or width accepted [m] (a guard against mm typed for m).
MAX_SIZE = 0.2


@dataclass(frozen=True)
class CollisionModel:
    """Sizes of the bodies of the collision model [m] (see the module doc)."""

    link_radius: float = _size(0.015, "capsule radius of AD, DP and the platform "
                               "cranks: a 20 mm aluminium tube with its clamps and "
                               "joint housings")
    crank_radius: float = _size(0.006, "capsule radius of the cranks BG, CH: an 8 x 8 mm "
                                "7075 aluminium bar (half its diagonal 5.7 mm; 117 MPa "
                                "at 10 N m); the roots of adjacent legs' cranks are 13 mm "
                                "apart at the corners of the paper's layout")
    distal_radius: float = _size(0.008, "capsule radius of the carbon distal tubes GE, HF: "
                                 "16 mm tubes, their U-joint and ball-joint ends no wider; "
                                 "the two of one leg clear each other while ey > this")
    hub_radius: float = _size(0.025, "radius of the pulley stack at A: the three 72-tooth "
                              "2 mm-pitch belt pulleys (pitch diameter 45.8 mm) of the "
                              "leg's concentric shafts, with their flanges")
    hub_width: float = _size(0.060, "axial length of the stack's axis segment, centred on "
                             "A (the capsule reaches hub_radius beyond each end)")
    plate_radius: float = _size(0.012, "half the thickness of the platform plate (its "
                                "spokes and edges)")
    plate_offset: float = _size(0.030, "height of the plate's mid-plane above the plane of "
                                "the platform cranks, along the platform normal: the "
                                "cranks (15 mm) turn 3 mm under the plate (12 mm), the "
                                "legs come from below")
    base_top: float = _size(-0.030, "height of the base plate's top surface (z of the "
                            "actuated axes is 0; the hubs stand on the plate)")

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise GeometryError(f"collision.{f.name}", v, "a finite number [m]")
            object.__setattr__(self, f.name, float(v))
            if f.name == "base_top":
                if not -0.5 <= v < 0.0:
                    raise GeometryError("collision.base_top", v, "in [-0.5, 0) m",
                                        "the plate lies below the actuated axes")
            elif f.name == "plate_offset":
                if not 0.0 <= v <= MAX_SIZE:
                    raise GeometryError("collision.plate_offset", v, f"in [0, {MAX_SIZE}] m")
            elif not 0.0 < v <= MAX_SIZE:
                raise GeometryError(f"collision.{f.name}", v, f"in (0, {MAX_SIZE}] m",
                                    "sizes are in metres, not mm")
        if self.hub_radius > -self.base_top + 1e-12:
            raise GeometryError("collision.hub_radius", self.hub_radius,
                                f"<= -base_top = {-self.base_top} m",
                                "a hub would reach through the base plate")

    def as_dict(self) -> dict[str, float]:
        return asdict(self)
