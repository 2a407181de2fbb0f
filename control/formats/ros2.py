"""ROS 2 trajectory exports: a ``trajectory_msgs/msg/JointTrajectory`` as a plain mapping
(YAML or JSON): ``joint_names`` (the nine actuated joints, legs 0..2 each A, B, C, as in
the URDF), one point per sample with ``positions`` [rad], ``velocities`` [rad/s],
``accelerations`` [rad/s^2], ``effort`` [N m] at the joint and ``time_from_start``
{sec, nanosec}.  ``rclpy``'s ``set_message_fields`` takes it as is; ``ros2 topic pub``
takes it on its command line only while it is under Linux's 128 KiB limit for one
argument (a 0.14 s motion at 1 kHz is already ~135 KB): for longer motions use
``--rate`` (fewer points, validated again), the FollowJointTrajectory goal
(:func:`follow_joint_trajectory_goal`) from a node, or the rosbag2 export
(:mod:`sixplus3.control.formats.rosbag`)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import yaml

from sixplus3.control.formats.export_format import Export, ExportFormat
from sixplus3.motion import Motion
from sixplus3.robot_description.urdf import actuated_joint_names


def ros2_joint_trajectory(motion: Motion, tau: np.ndarray,
                          frame_id: str = "base_link") -> dict[str, Any]:
    """A ``trajectory_msgs/msg/JointTrajectory`` of ``motion`` with the efforts ``tau``
    (n, 9) [N m] as a mapping (header stamp zero: start on reception)."""
    t, theta, theta_dot, theta_ddot = (motion.t, motion.theta, motion.theta_dot,
                                       motion.theta_ddot)
    points = []
    for k in range(len(t)):
        ns_total = int(round(float(t[k]) * 1e9))
        points.append({
            "positions": [float(v) for v in theta[k]],
            "velocities": [float(v) for v in theta_dot[k]],
            "accelerations": [float(v) for v in theta_ddot[k]],
            "effort": [float(v) for v in tau[k]],
            "time_from_start": {"sec": ns_total // 1_000_000_000,
                                "nanosec": ns_total % 1_000_000_000},
        })
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": frame_id},
            "joint_names": actuated_joint_names(), "points": points}


def _yaml_float(x: float) -> str:
    """A float as YAML 1.1 reads it back exactly (PyYAML wants a '.' before an exponent:
    '1e-05' would be text)."""
    r = repr(float(x))
    if r in ("inf", "-inf", "nan"):
        return {"inf": ".inf", "-inf": "-.inf", "nan": ".nan"}[r]
    if "e" in r and "." not in r:
        r = r.replace("e", ".0e")
    return r


def ros2_yaml(msg: dict[str, Any]) -> str:
    """The JointTrajectory mapping of :func:`ros2_joint_trajectory` as block YAML, the
    points' arrays in flow style, written line by line (``yaml.safe_dump`` of a long
    motion held ~2.8 GB; this holds the text only).  ``yaml.safe_load`` returns ``msg``."""
    h = msg["header"]
    lines = ["header:", "  stamp:", f"    sec: {int(h['stamp']['sec'])}",
             f"    nanosec: {int(h['stamp']['nanosec'])}",
             f"  frame_id: {json.dumps(h['frame_id'])}", "joint_names:"]
    lines += [f"- {json.dumps(n)}" for n in msg["joint_names"]]
    lines.append("points:" if msg["points"] else "points: []")
    for p in msg["points"]:
        for k, key in enumerate(("positions", "velocities", "accelerations", "effort")):
            lead = "- " if k == 0 else "  "
            lines.append(f"{lead}{key}: [" + ", ".join(_yaml_float(v) for v in p[key]) + "]")
        tf = p["time_from_start"]
        lines += ["  time_from_start:", f"    sec: {int(tf['sec'])}",
                  f"    nanosec: {int(tf['nanosec'])}"]
    return "\n".join(lines) + "\n"


def follow_joint_trajectory_goal(msg: dict[str, Any],
                                 goal_time_tolerance_s: float = 0.0) -> dict[str, Any]:
    """A ``control_msgs/action/FollowJointTrajectory`` goal around a JointTrajectory
    mapping: empty path and goal tolerances (the controller's own) and the goal time
    tolerance, in the form ``ros2 action send_goal`` takes."""
    ns = int(round(goal_time_tolerance_s * 1e9))
    return {"trajectory": msg, "path_tolerance": [], "goal_tolerance": [],
            "goal_time_tolerance": {"sec": ns // 1_000_000_000,
                                    "nanosec": ns % 1_000_000_000}}


def _message(ex: Export) -> dict[str, Any]:
    msg = ros2_joint_trajectory(ex.motion, ex.tau)
    return follow_joint_trajectory_goal(msg) if ex.goal else msg


def render_json(ex: Export) -> str:
    return json.dumps(_message(ex)) + "\n"


def render_yaml(ex: Export) -> str:
    msg = _message(ex)
    if not ex.goal:
        return ros2_yaml(msg)
    tolerances = {k: v for k, v in msg.items() if k != "trajectory"}
    body = ros2_yaml(msg["trajectory"])
    return ("trajectory:\n" + "".join(f"  {line}\n" for line in body.splitlines())
            + yaml.safe_dump(tolerances, sort_keys=False, default_flow_style=False))


YAML = ExportFormat("ros2-yaml", "ROS 2 trajectory_msgs/JointTrajectory as YAML", "sample",
                    True, render_yaml)
JSON = ExportFormat("ros2-json", "ROS 2 trajectory_msgs/JointTrajectory as JSON", "sample",
                    True, render_json)

__all__ = ["JSON", "YAML", "follow_joint_trajectory_goal", "render_json", "render_yaml",
           "ros2_joint_trajectory", "ros2_yaml"]
