"""Robot description: the parametric geometry (paper defaults) of sixplus3."""

from sixplus3.robot_description.geometry import GRAVITY, LegGeometry, LegLoad

__all__ = ["GRAVITY", "LegGeometry", "LegLoad"]
