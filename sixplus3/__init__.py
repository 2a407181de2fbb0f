"""sixplus3: software for the kinematically redundant (6+3)-DoF RU/2-RUS parallel robot.

One explicit, frozen :class:`Robot` is the input of every part (this example runs as
a test: tests/test_packaging.py)::

    import tempfile

    import sixplus3 as s3
    from sixplus3 import examples

    robot = s3.Robot.default()                       # the built robot
    task = examples.load("tilt60_x")                 # or s3.load_task("my_task.yaml")
    sol = s3.plan(task, robot)                       # time-optimal, checked with Pinocchio
    sm = s3.smooth(sol, rate=1000.0)                 # controller-rate samples (Ruckig)
    out = s3.run_plan(task, tempfile.mkdtemp(), robot, html=False, plots=False)
    rep = s3.validate_file(out.csv, robot)           # the gate: -> ValidationReport
    assert rep.ok and sm.motion.rate == 1000.0

Subpackages (lower never imports higher): ``robot_description`` (Robot, URDF, closures,
Pinocchio model), ``kinematics``, ``dynamics``, ``design``, ``planner``, ``control``
(smoothing, validation, trajectory files, pipeline), ``visualization``, and ``cli``.

The names below are imported lazily (PEP 562), so that ``import sixplus3`` and
``sixplus3 --help`` stay fast; the heavy libraries load on first use.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

#: public name -> module that defines it
_API = {
    "Robot": "sixplus3.robot_description.robot",
    "RobotGeometry": "sixplus3.robot_description.robot_geometry",
    "MassModel": "sixplus3.robot_description.masses",
    "LegGeometry": "sixplus3.robot_description.geometry",
    "Limits": "sixplus3.robot_description.limits",
    "AssemblyMode": "sixplus3.robot_description.assembly",
    "load_robot": "sixplus3.robot_description.robot",
    "robot_ik": "sixplus3.kinematics.robot",
    "robot_ik_pose": "sixplus3.kinematics.robot",
    "robot_fk": "sixplus3.kinematics.robot_fk",
    "home": "sixplus3.kinematics.robot",
    "leg_ik": "sixplus3.kinematics.leg",
    "ClosedLoopDynamics": "sixplus3.dynamics.closed_loop",
    "Task": "sixplus3.planner.task",
    "load_task": "sixplus3.planner.task",
    "task_from_dict": "sixplus3.planner.task",
    "Problem": "sixplus3.planner.problem",
    "PlannerOptions": "sixplus3.planner.options",
    "Solution": "sixplus3.planner.solution",
    "plan": "sixplus3.planner.ocp",
    "smooth": "sixplus3.planner.smoothing",
    "ValidationReport": "sixplus3.control.report",
    "validate_joint_trajectory": "sixplus3.control.gate.validation",
    "validate_file": "sixplus3.control.gate.validation",
    "read_trajectory": "sixplus3.control.file.trajectory_read",
    "write_trajectory": "sixplus3.control.file.trajectory_file",
    "run_plan": "sixplus3.control.pipeline",
    "Sixplus3Error": "sixplus3.errors",
}

__all__ = ["AssemblyMode", "ClosedLoopDynamics", "LegGeometry", "Limits", "MassModel",
    "PlannerOptions", "Problem", "Robot", "RobotGeometry", "Sixplus3Error", "Solution", "Task",
    "ValidationReport", "home", "leg_ik", "load_robot", "load_task", "plan", "read_trajectory",
    "robot_fk", "robot_ik", "robot_ik_pose", "run_plan", "smooth", "task_from_dict",
    "validate_file", "validate_joint_trajectory", "write_trajectory", "__version__"]


def __getattr__(name: str) -> Any:
    if name in _API:
        value = getattr(importlib.import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'sixplus3' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))


if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs
    from sixplus3.control.file.trajectory_file import write_trajectory
    from sixplus3.control.file.trajectory_read import read_trajectory
    from sixplus3.control.gate.validation import validate_file, validate_joint_trajectory
    from sixplus3.control.pipeline import run_plan
    from sixplus3.control.report import ValidationReport
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.errors import Sixplus3Error
    from sixplus3.kinematics.leg import leg_ik
    from sixplus3.kinematics.robot import home, robot_ik, robot_ik_pose
    from sixplus3.kinematics.robot_fk import robot_fk
    from sixplus3.planner.ocp import plan
    from sixplus3.planner.options import PlannerOptions
    from sixplus3.planner.problem import Problem
    from sixplus3.planner.smoothing import smooth
    from sixplus3.planner.solution import Solution
    from sixplus3.planner.task import Task, load_task, task_from_dict
    from sixplus3.robot_description.assembly import AssemblyMode
    from sixplus3.robot_description.geometry import LegGeometry
    from sixplus3.robot_description.limits import Limits
    from sixplus3.robot_description.masses import MassModel
    from sixplus3.robot_description.robot import Robot, load_robot
    from sixplus3.robot_description.robot_geometry import RobotGeometry
