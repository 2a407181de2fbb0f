"""The geometry of the whole (6+3)-DoF robot: the leg, the base layout and the platform
(docs/conventions.md, "Robot frame").

Robot frame: origin at the base centre in the plane of the actuated axes, z up (floor
configuration).  Leg i (i = 0, 1, 2) sits at alpha_i = 90 deg + 120 deg i:
A_i = r_a [cos alpha_i, sin alpha_i, 0], r_a = 0.143 / sqrt(3) m (|a_j - a_i| = 0.143 m).
Its frame has x along the tangent [-sin alpha_i, cos alpha_i, 0], y towards the centre,
z up, i.e. it is R_z(gamma_i) with gamma_i = alpha_i + 90 deg.

Platform (Wen et al. 2021; the paper gives no numbers, these are ours): three revolute
joints with axes along the platform normal z_p, at radius rho = 0.0706 m in directions
beta_i = alpha_i + platform_phase, each with a crank of length c = 0.0706 m.  The crank
angle psi_i (a redundant coordinate) is measured about z_p from the outward radius: at
psi = 90 deg with rho = c the crank tips P_i lie at radius rho sqrt(2) in direction
beta_i + 45 deg, forming the paper's equilateral triangle of side 0.173 m.  With the
default phase of -45 deg, P_i then points at leg i.  psi = 0 or 180 deg (crank along its
radius) is the platform singularity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sixplus3.errors import GeometryError
from sixplus3.robot_description.geometry import LegGeometry

NUM_LEGS = 3


#: The platform phase at which P_i points at leg i at psi = 90 deg (the paper's layout).
PAPER_PHASE = -math.pi / 4


@dataclass(frozen=True)
class RobotGeometry:
    """Leg geometry, base layout and platform of the robot [m, rad]."""

    leg: LegGeometry = field(default_factory=LegGeometry)
    base_radius: float = field(default=0.143 / math.sqrt(3.0),
                               metadata={"doc": "|A_i| from the base centre [m]"})
    first_leg_angle: float = field(default=math.pi / 2,
                                   metadata={"doc": "alpha_0, direction of A_0 [rad]"})
    platform_radius: float = field(default=0.0706,
                                   metadata={"doc": "rho, radius of the crank axes [m]"})
    platform_crank: float = field(default=0.0706,
                                  metadata={"doc": "c, crank length R_i -> P_i [m]"})
    platform_phase: float = field(default=PAPER_PHASE,
                                  metadata={"doc": "beta_i - alpha_i [rad]"})
    axis_turn: float = field(default=0.0, metadata={
        "doc": "gamma, turn of every actuated axis about the vertical through its A_i, "
               "away from the tangent (0: the paper's tangential axes) [rad]"})

    def __post_init__(self) -> None:
        for name in ("base_radius", "platform_radius", "platform_crank"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 < v <= 2.0):
                raise GeometryError(name, v, "in (0, 2] m")
        for name in ("first_leg_angle", "platform_phase", "axis_turn"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v)
                                           and abs(v) <= 2.0 * math.pi):
                raise GeometryError(name, v, "a finite angle in [-2 pi, 2 pi] rad")

    # ----------------------------------------------------------------- base layout
    def leg_angle(self, i: int) -> float:
        """alpha_i [rad]."""
        return self.first_leg_angle + 2.0 * math.pi * i / NUM_LEGS

    def leg_yaw(self, i: int) -> float:
        """gamma_i: the leg frame is R_z(gamma_i) in the robot frame [rad]."""
        return self.leg_angle(i) + math.pi / 2 + self.axis_turn

    def leg_rotation(self, i: int) -> np.ndarray:
        """R_base_leg (3, 3): columns are the leg's x, y, z in the robot frame."""
        g = self.leg_yaw(i)
        c, s = math.cos(g), math.sin(g)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def leg_origin(self, i: int) -> np.ndarray:
        """A_i in the robot frame [m]."""
        a = self.leg_angle(i)
        return self.base_radius * np.array([math.cos(a), math.sin(a), 0.0])

    def actuated_joint_positions(self) -> np.ndarray:
        """(9, 3) A_i, B_i, C_i of every leg in the robot frame [m]."""
        pts = []
        for i in range(NUM_LEGS):
            a, x = self.leg_origin(i), self.leg_rotation(i)[:, 0]
            pts += [a, a + self.leg.l6 * x, a - self.leg.l7 * x]
        return np.array(pts)

    def to_leg(self, i: int, p_base: np.ndarray) -> np.ndarray:
        """Points (..., 3) from the robot frame to leg i's frame."""
        return (np.asarray(p_base) - self.leg_origin(i)) @ self.leg_rotation(i)

    def from_leg(self, i: int, p_leg: np.ndarray) -> np.ndarray:
        """Points (..., 3) from leg i's frame to the robot frame."""
        return np.asarray(p_leg) @ self.leg_rotation(i).T + self.leg_origin(i)

    # ----------------------------------------------------------------- platform
    def crank_axis_angle(self, i: int) -> float:
        """beta_i: direction of crank axis R_i in the platform frame [rad]."""
        return self.leg_angle(i) + self.platform_phase

    def crank_axis_position(self, i: int) -> np.ndarray:
        """R_i in the platform frame [m]."""
        b = self.crank_axis_angle(i)
        return self.platform_radius * np.array([math.cos(b), math.sin(b), 0.0])

    def crank_tip(self, i: int, psi: float) -> np.ndarray:
        """P_i in the platform frame for crank angle psi [rad] [m]."""
        b = self.crank_axis_angle(i)
        return self.crank_axis_position(i) + self.platform_crank * np.array(
            [math.cos(b + psi), math.sin(b + psi), 0.0])


#: The built robot's layout, the winner of the layout study (``sixplus3 design layout``,
#: docs/design.md "Layout"): every actuated axis turned by 28 deg about the vertical
#: through its A_i, the platform's crank axes 5 deg further than the paper's -45 deg.
DEFAULT_AXIS_TURN = math.radians(28.0)


DEFAULT_PLATFORM_PHASE = PAPER_PHASE + math.radians(5.0)


#: The built robot's E and F offset [m]: as small as two spherical joints side by side
#: allow; the type II-free COW shrinks as it grows (docs/design.md, "ey").
DEFAULT_EY = 0.010


def default_geometry() -> RobotGeometry:
    """The built robot's geometry: the paper's leg with ey = DEFAULT_EY on the layout of
    the layout study."""
    return RobotGeometry(leg=LegGeometry(ey=DEFAULT_EY, fy=-DEFAULT_EY),
                         axis_turn=DEFAULT_AXIS_TURN, platform_phase=DEFAULT_PLATFORM_PHASE)
