"""The files that replay a bag in RViz: the URDF, an RViz configuration, a launch file.

:func:`write_replay_files` puts them in the bag's directory (``sixplus3 export FILE
--format rosbag2 -o BAG``), so that one command replays the motion::

    ros2 launch BAG/replay.launch.py            # 10x slowed, looping; rate:=1.0 loop:=false

The launch file starts ``robot_state_publisher`` with the URDF (every revolute joint of
the spanning tree, the passive leg joints and cranks included, comes from the bag's
``/joint_states``; the floating platform joint from its ``/tf``), RViz with the
configuration, and ``ros2 bag play BAG --clock --rate R`` with every node on the bag's
clock (``use_sim_time``): a motion of 0.1 s is watched at ``rate:=0.1`` or slower.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from sixplus3.fileio import atomic_write
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import robot_urdf

#: The files written beside the bag's data.
FILES = ("robot.urdf", "sixplus3.rviz", "replay.launch.py")

LAUNCH = '''"""Replay the sixplus3 bag of this directory in RViz (written by sixplus3 {version}).

    ros2 launch {here}/replay.launch.py [rate:=0.1] [loop:=true]

robot_state_publisher gets robot.urdf; the bag's /joint_states carries every revolute
joint of it (the closures travel as joint states) and its /tf the floating platform.
Every node runs on the bag's clock (ros2 bag play --clock, use_sim_time), so a motion of
{duration:.3f} s plays at the chosen rate.
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

HERE = os.path.dirname(os.path.abspath(__file__))


def generate_launch_description():
    with open(os.path.join(HERE, "robot.urdf"), encoding="utf-8") as f:
        urdf = f.read()
    rate = LaunchConfiguration("rate")
    loop = LaunchConfiguration("loop")
    play = ["ros2", "bag", "play", HERE, "--clock", "--rate", rate]
    return LaunchDescription([
        DeclareLaunchArgument("rate", default_value="{rate}",
                              description="playback speed (1.0: real time)"),
        DeclareLaunchArgument("loop", default_value="true",
                              description="replay the motion over and over"),
        Node(package="robot_state_publisher", executable="robot_state_publisher",
             parameters=[{{"robot_description": urdf, "use_sim_time": True}}]),
        Node(package="rviz2", executable="rviz2",
             arguments=["-d", os.path.join(HERE, "sixplus3.rviz")],
             parameters=[{{"use_sim_time": True}}]),
        ExecuteProcess(cmd=play + ["--loop"], output="screen", condition=IfCondition(loop)),
        ExecuteProcess(cmd=play, output="screen", condition=UnlessCondition(loop)),
    ])
'''

RVIZ = """Panels:
  - Class: rviz_common/Displays
    Name: Displays
Visualization Manager:
  Class: ""
  Displays:
    - Class: rviz_default_plugins/Grid
      Name: Grid
      Enabled: true
      Cell Size: 0.1
      Plane Cell Count: 20
      Reference Frame: <Fixed Frame>
    - Class: rviz_default_plugins/RobotModel
      Name: {name}
      Enabled: true
      Description Source: Topic
      Description Topic:
        Value: /robot_description
      TF Prefix: ""
      Visual Enabled: true
      Collision Enabled: false
    - Class: rviz_default_plugins/TF
      Name: TF
      Enabled: false
  Global Options:
    Fixed Frame: base_link
    Frame Rate: 30
  Views:
    Current:
      Class: rviz_default_plugins/Orbit
      Name: Current View
      Distance: 1.6
      Focal Point:
        X: 0.0
        Y: 0.0
        Z: {focus:.3f}
      Pitch: 0.35
      Yaw: 0.8
Window Geometry:
  Height: 800
  Width: 1200
"""


def write_replay_files(bag_dir: str | Path, robot: Robot, joint_names: list[str],
                       duration: float, rate: float = 0.1) -> list[Path]:
    """Write :data:`FILES` into ``bag_dir`` (each atomically): the robot's URDF, the RViz
    configuration and the launch file; ``joint_names`` (the bag's ``/joint_states``)
    must all be joints of the URDF."""

    from sixplus3 import __version__  # deferred: the top-level package imports its parts lazily

    d = Path(bag_dir)
    urdf = robot_urdf(robot)
    joints = {j.get("name") for j in ET.fromstring(urdf).iter("joint")}
    missing = [n for n in joint_names if n not in joints]
    if missing:  # a bug, not an input: the bag and the URDF come from the same robot
        raise AssertionError(f"joint states not in the URDF: {missing[:3]}")
    texts = {
        "robot.urdf": urdf,
        "sixplus3.rviz": RVIZ.format(name=robot.name or "sixplus3",
                                     focus=0.5 * robot.home_position[2]),
        "replay.launch.py": LAUNCH.format(version=__version__, here="<this directory>",
                                          duration=duration, rate=rate),
    }
    out = []
    for name in FILES:
        atomic_write(d / name, texts[name].encode())
        out.append(d / name)
    return out


__all__ = ["FILES", "write_replay_files"]
