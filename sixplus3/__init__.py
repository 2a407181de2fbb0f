"""sixplus3: software for the kinematically redundant (6+3)-DoF RU/2-RUS parallel robot.

The library is split by concept into top-level packages:

- ``robot_description`` -- the parametric geometry (paper defaults) and, later, the URDF;
- ``kinematics`` -- the leg's closed-form kinematics, Jacobians, singularities, statics;
- ``sixplus3`` -- the shared error types and the ``sixplus3`` command line.
"""

__version__ = "0.1.0"
