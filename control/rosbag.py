"""A validated trajectory as a ROS 2 bag (rosbag2, MCAP storage), for ``ros2 bag play``.

:func:`write_rosbag2` validates the file (the gate; nothing is written for a file that
fails it) and writes a bag directory with, on the file's time grid:

- ``/joint_states`` (``sensor_msgs/msg/JointState``), one message per sample: every
  revolute joint of the URDF (30: the 9 actuated, the 18 passive leg joints, the 3
  platform cranks),
  positions from the validator's own configuration (forward kinematics, then the
  closed-form IK of the whole robot) and velocities from the closures (v = G θ̇);
  efforts empty (the actuated torques are in the trajectory);
- ``/tf`` (``tf2_msgs/msg/TFMessage``), one per sample: ``base_link`` → ``platform``
  (the URDF's floating joint, which ``robot_state_publisher`` does not publish);
- ``/joint_trajectory`` (``trajectory_msgs/msg/JointTrajectory``), once at the start:
  the nine actuated joints (:func:`sixplus3.control.exports.ros2_joint_trajectory`).

With ``robot_state_publisher`` fed the URDF (``sixplus3 robot export urdf``), RViz shows
the whole robot move.  Message types are ROS 2 Humble's (the ``rosbags`` library's type
store); the ``rosbags`` package is optional (``pip install 'sixplus3[ros]'``).  The
directory is written beside its final name and renamed into place when complete; an
existing output is never replaced.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from sixplus3.errors import InputError, ValidationFailed
from sixplus3.robot_description.robot import Robot

#: Topics of the bag.
TOPICS = {"joint_states": "/joint_states", "tf": "/tf", "trajectory": "/joint_trajectory"}


def _rosbags():
    try:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError("the rosbag2 export needs the rosbags library: pip install "
                         "'sixplus3[ros]'", value=None, valid="rosbags installed") from None
    return Writer, StoragePlugin, get_typestore(Stores.ROS2_HUMBLE)


def _stamp(types, t: float):
    ns = int(round(t * 1e9))
    return types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000,
                                                 nanosec=ns % 1_000_000_000)


def revolute_joints(robot: Robot) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(names, q indices, v indices) of every one-degree-of-freedom joint of the model,
    in the URDF's order (the floating platform joint left out)."""
    m = robot.closed_loop_model().model
    names, iq, iv = [], [], []
    for j in range(1, m.njoints):
        if m.nqs[j] == 1:
            names.append(m.names[j])
            iq.append(m.idx_qs[j])
            iv.append(m.idx_vs[j])
    return names, np.array(iq), np.array(iv)


def write_rosbag2(path: str | Path, robot: Robot, out_dir: str | Path) -> Path:
    """Validate the trajectory file ``path`` for ``robot`` and write it as a rosbag2
    directory ``out_dir`` (MCAP).  Raises :class:`ValidationFailed` for a file that fails
    the gate and :class:`InputError` for an existing output or a missing ``rosbags``."""
    from sixplus3.control.exports import ros2_joint_trajectory
    from sixplus3.control.trajectory_file import columns
    from sixplus3.control.validation import validate_file
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.kinematics.robot import robot_ik
    from sixplus3.kinematics.rotations import matrix_from_quat

    Writer, StoragePlugin, store = _rosbags()
    out = Path(out_dir)
    if out.exists() or out.is_symlink():
        raise InputError(f"{out} exists: a bag is never written over something",
                         value=str(out), valid="a new directory name")
    if not out.parent.is_dir():
        raise InputError(f"no such directory {out.parent}", value=str(out.parent),
                         valid="an existing directory")
    rep = validate_file(path, robot)
    if rep.exit_code != 0 or rep.data is None:
        raise ValidationFailed("not exported: " + "; ".join(rep.messages()),
                               exit_code=rep.exit_code, report=rep)
    assert rep.position is not None and rep.quaternion is not None and rep.psi is not None
    data = rep.data
    t, th, thd = data[:, 0], columns(data, "pos"), columns(data, "vel")
    cfg = robot_ik(rep.position, matrix_from_quat(rep.quaternion), rep.psi, robot,
                   platform_margins=False)
    names, iq, iv = revolute_joints(robot)
    dyn = ClosedLoopDynamics(robot)
    zero = np.zeros(9)
    T = store.types
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name[:80]}.", suffix=".tmp"))
    bag = tmp / "bag"
    try:
        with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            c_js = writer.add_connection(TOPICS["joint_states"], "sensor_msgs/msg/JointState",
                                         typestore=store)
            c_tf = writer.add_connection(TOPICS["tf"], "tf2_msgs/msg/TFMessage",
                                         typestore=store)
            c_tr = writer.add_connection(TOPICS["trajectory"],
                                         "trajectory_msgs/msg/JointTrajectory",
                                         typestore=store)
            writer.write(c_tr, 0, store.serialize_cdr(
                _trajectory(T, ros2_joint_trajectory(t, th, thd, columns(data, "acc"),
                                                     columns(data, "tau"))),
                "trajectory_msgs/msg/JointTrajectory"))
            for k in range(len(t)):
                stamp = _stamp(T, float(t[k]))
                q = cfg.q[k]
                v, _ = dyn.consistent_state(q, thd[k], zero)
                js = T["sensor_msgs/msg/JointState"](
                    header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="base_link"),
                    name=names, position=q[iq].astype(np.float64),
                    velocity=np.asarray(v)[iv].astype(np.float64),
                    effort=np.zeros(0, dtype=np.float64))
                ns = int(round(float(t[k]) * 1e9))
                writer.write(c_js, ns, store.serialize_cdr(js, "sensor_msgs/msg/JointState"))
                x, y, z, w = (float(c) for c in rep.quaternion[k])
                tf = T["geometry_msgs/msg/TransformStamped"](
                    header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="base_link"),
                    child_frame_id="platform",
                    transform=T["geometry_msgs/msg/Transform"](
                        translation=T["geometry_msgs/msg/Vector3"](
                            *(float(c) for c in rep.position[k])),
                        rotation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)))
                writer.write(c_tf, ns, store.serialize_cdr(
                    T["tf2_msgs/msg/TFMessage"](transforms=[tf]), "tf2_msgs/msg/TFMessage"))
        os.rename(bag, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _trajectory(T, msg: dict):
    """A JointTrajectory message of the typestore from the mapping of
    :func:`ros2_joint_trajectory`."""
    Time, Duration = T["builtin_interfaces/msg/Time"], T["builtin_interfaces/msg/Duration"]
    points = [T["trajectory_msgs/msg/JointTrajectoryPoint"](
        positions=np.array(p["positions"]), velocities=np.array(p["velocities"]),
        accelerations=np.array(p["accelerations"]), effort=np.array(p["effort"]),
        time_from_start=Duration(sec=p["time_from_start"]["sec"],
                                 nanosec=p["time_from_start"]["nanosec"]))
        for p in msg["points"]]
    header = T["std_msgs/msg/Header"](stamp=Time(sec=0, nanosec=0),
                                      frame_id=msg["header"]["frame_id"])
    return T["trajectory_msgs/msg/JointTrajectory"](header=header,
                                                    joint_names=msg["joint_names"],
                                                    points=points)


__all__ = ["TOPICS", "revolute_joints", "write_rosbag2"]
