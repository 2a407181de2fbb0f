"""The platform's singularity proxy in CasADi: the determinant of its crank lines.

The platform's official margin (a singular-value ratio of a 9x9, numeric,
:func:`sixplus3.kinematics.robot.platform_margin`) has no cheap smooth form; the
planner's row is this determinant instead, with the crank angles kept in a range, and
every plan's official margin is re-checked.
"""

from __future__ import annotations

import math
from typing import Any

import casadi as ca

from sixplus3.errors import SingularityError
from sixplus3.robot_description.robot_geometry import NUM_LEGS, RobotGeometry


def platform_line_det(psi: Any, geom: RobotGeometry) -> Any:
    """det of the platform's crank-line matrix B, divided by its value at psi = 90 deg.

    In the platform plane the crank rates eliminate, leaving the three lines along the
    cranks (through R_i and P_i): rows [s_i, (P_i x s_i)_z / L] with s_i the unit crank
    direction, L = sqrt(rho^2 + c^2).  B is singular when the lines are concurrent or
    parallel: the in-plane platform singularity (e.g. psi = (0, 90, 90) deg).  A smooth
    proxy of the platform margin of :func:`kinematics.robot.platform_margin` (which the
    planner re-checks on its result).  Works with numbers or CasADi symbols.
    """
    L = math.hypot(geom.platform_radius, geom.platform_crank)
    rows = []
    for i in range(NUM_LEGS):
        b = geom.crank_axis_angle(i) + psi[i]
        sx, sy = ca.cos(b), ca.sin(b)
        Pi = geom.crank_axis_position(i) + geom.platform_crank * ca.vertcat(sx, sy, 0)
        rows.append(ca.horzcat(sx, sy, (Pi[0] * sy - Pi[1] * sx) / L))
    return ca.det(ca.vertcat(*rows))


def platform_line_det_normalised(psi: Any, geom: RobotGeometry) -> Any:
    """:func:`platform_line_det` divided by its value at psi = 90 deg (this platform's
    reference, computed from its geometry), so that 1 is the nominal platform."""
    ref = float(ca.DM(platform_line_det([math.pi / 2] * NUM_LEGS, geom)))
    if abs(ref) < 1e-12:
        raise SingularityError("the platform's crank lines are singular at psi = 90 deg",
                               value=ref, valid="a platform whose crank lines at 90 deg "
                               "are not concurrent")
    return platform_line_det(psi, geom) / ref


__all__ = ["platform_line_det", "platform_line_det_normalised"]
