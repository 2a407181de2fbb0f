"""Kinematics of sixplus3: the RU/2-RUS leg (paper §III-IV)."""

from sixplus3.kinematics.leg import (
    SINGULAR_TOL,
    LegEval,
    LegState,
    leg_eval,
    leg_fk,
    leg_fk_point,
    leg_ik,
    leg_ik_point,
    status_reason,
)
from sixplus3.robot_description.assembly import DEFAULT_MODE, AssemblyMode

__all__ = [
    "DEFAULT_MODE", "SINGULAR_TOL", "AssemblyMode", "LegEval", "LegState", "leg_eval",
    "leg_fk", "leg_fk_point", "leg_ik", "leg_ik_point", "status_reason",
]
