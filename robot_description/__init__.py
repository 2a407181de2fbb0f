"""Robot description: the :class:`Robot` value (geometry, assembly, masses, limits,
mounting), its URDF + closures, and its Pinocchio closed-loop model.

In two lines, as example-robot-data does::

    robot = Robot.default()
    clm = closed_loop_model(robot)   # robot_description.model; clm.model, clm.constraint_models
                                     # (caller-owned)
"""

from sixplus3.robot_description.assembly import DEFAULT_MODE, AssemblyMode
from sixplus3.robot_description.geometry import GRAVITY, LegGeometry, LegLoad
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.masses import POINT_MASS, MassModel
from sixplus3.robot_description.robot import MOUNTINGS, Robot, load_robot
from sixplus3.robot_description.robot_geometry import RobotGeometry

__all__ = ["DEFAULT_MODE", "GRAVITY", "MOUNTINGS", "POINT_MASS", "AssemblyMode",
           "LegGeometry", "LegLoad", "Limits", "MassModel", "Robot", "RobotGeometry",
           "load_robot"]
