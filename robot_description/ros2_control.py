"""The ``<ros2_control>`` block of the robot's URDF (``sixplus3 robot export urdf
--ros2-control``): effort interfaces, the 72/34 transmissions, the rotor inertia and
friction as parameters, and the state interfaces' initial values."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence

import numpy as np

from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import _f, actuated_joint_names, robot_urdf


def ros2_control_block(robot: Robot, plugin: str = "mock_components/GenericSystem",
                       initial: Sequence[float] | None = None) -> str:
    """A ``<ros2_control>`` element for the nine actuated joints, to paste into (or let
    :func:`with_ros2_control` insert into) the robot's URDF: per joint an ``effort``
    command interface limited to the robot's torque, ``position``/``velocity``/``effort``
    state interfaces, and the joint's rotor inertia reflected through the belt, its
    viscous and Coulomb friction as parameters (a URDF has no element for them: they
    are the joint's armature and friction in Pinocchio and MuJoCo); per joint a
    ``transmission_interface/SimpleTransmission`` with the belt ratio (72/34) between
    the motor (``NAME_motor``) and the joint.  ``plugin``: the hardware interface
    (default ros2_control's mock system, for RViz and controller tests).

    ``initial``: the nine actuated angles [rad] the hardware starts at, written as each
    state interface's ``initial_value`` (position at ``initial``, velocity and effort 0):
    mock hardware otherwise starts every joint at 0 rad, a pose this robot cannot take.
    The caller passes the robot's home (``sixplus3.kinematics.robot.home``) or a
    trajectory's first sample; ``None`` writes no initial values."""
    lim, mot = robot.limits, robot.motors
    start: list[float] | None = None
    if initial is not None:
        start = [float(v) for v in np.asarray(initial, dtype=float).reshape(-1)]
        if len(start) != 9 or not all(math.isfinite(v) for v in start):
            raise ValueError(f"initial must be 9 finite angles [rad], got {initial!r}")
    root = ET.Element("ros2_control", name=robot.name, type="system")
    hw = ET.SubElement(root, "hardware")
    ET.SubElement(hw, "plugin").text = plugin
    for name in actuated_joint_names():
        j = ET.SubElement(root, "joint", name=name)
        cmd = ET.SubElement(j, "command_interface", name="effort")
        ET.SubElement(cmd, "param", name="min").text = _f(-lim.torque)
        ET.SubElement(cmd, "param", name="max").text = _f(lim.torque)
        jk = actuated_joint_names().index(name)
        for state in ("position", "velocity", "effort"):
            si = ET.SubElement(j, "state_interface", name=state)
            if start is not None:
                value = start[jk] if state == "position" else 0.0
                ET.SubElement(si, "param", name="initial_value").text = _f(value)
        for key, value in (("rotor_inertia_at_joint_kg_m2", mot.armature_per_joint[jk]),
                           ("rotor_inertia_motor_kg_m2",
                            mot.armature_per_joint[jk] / mot.gear_ratio ** 2),
                           ("viscous_friction_n_m_s", mot.viscous_per_joint[jk]),
                           ("coulomb_friction_n_m", mot.coulomb_per_joint[jk]),
                           ("velocity_limit_rad_s", lim.velocity)):
            ET.SubElement(j, "param", name=key).text = _f(value)
    for name in actuated_joint_names():
        tr = ET.SubElement(root, "transmission", name=f"{name}_transmission")
        ET.SubElement(tr, "plugin").text = "transmission_interface/SimpleTransmission"
        ET.SubElement(tr, "actuator", name=f"{name}_motor", role="actuator1")
        jt = ET.SubElement(tr, "joint", name=name, role="joint1")
        ET.SubElement(jt, "mechanical_reduction").text = _f(mot.gear_ratio)
    ET.indent(root, space="  ", level=1)
    return "  " + ET.tostring(root, encoding="unicode")


def with_ros2_control(robot: Robot, plugin: str = "mock_components/GenericSystem",
                      initial: Sequence[float] | None = None) -> str:
    """The robot's URDF with :func:`ros2_control_block` before ``</robot>``."""
    text = robot_urdf(robot)
    end = text.rindex("</robot>")
    return text[:end] + ros2_control_block(robot, plugin, initial) + "\n" + text[end:]


__all__ = ["ros2_control_block", "with_ros2_control"]
