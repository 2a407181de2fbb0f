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
  the nine actuated joints (:func:`sixplus3.control.formats.ros2.ros2_joint_trajectory`).

With ``robot_state_publisher`` fed the URDF, RViz shows the whole robot move: the bag
directory also holds ``robot.urdf``, ``sixplus3.rviz`` and ``replay.launch.py``
(:mod:`sixplus3.control.formats.ros_replay`).  Message types are ROS 2 Humble's (the ``rosbags``
library's type store); the ``rosbags`` package is optional (``pip install
'sixplus3[ros]'``).  The directory is written beside its final name and renamed into
place when complete; an existing output is never replaced.

**Distributions.**  A bag's ``metadata.yaml`` moves forward across ROS 2 distributions,
not back: Humble's reader (rosbag2 0.15, metadata version 5) fails on a newer version's
file.  ``distro="humble"`` (the default) writes Humble's version 5 with exactly the
fields of its ``metadata_io.cpp`` (:func:`humble_metadata`), which every later reader
also reads; ``"jazzy"`` keeps the ``rosbags`` writer's version 9.  The MCAP storage is
the same for both (Humble needs ``ros-humble-rosbag2-storage-mcap``).

**Stamps** start at ``start_ns`` (nanoseconds since the epoch; default: now), so that
``ros2 bag play --clock`` publishes a clock near the wall clock; the samples keep the
file's grid.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from sixplus3.control.file.file_format import columns, motion_of
from sixplus3.control.formats.export_format import ExportFormat
from sixplus3.control.formats.ros2 import ros2_joint_trajectory
from sixplus3.control.formats.ros_replay import write_replay_files
from sixplus3.control.gate.validation import validate_file
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InputError, ValidationFailed
from sixplus3.fileio import atomic_write
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.rotations import matrix_from_quat
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot

#: Topics of the bag.
TOPICS = {"joint_states": "/joint_states", "tf": "/tf", "trajectory": "/joint_trajectory"}
#: metadata.yaml's version per distribution (rosbag2's BagMetadata::version there).
DISTROS = {"humble": 5, "jazzy": 9}
#: The rosbags writer's metadata version per distribution (8 serialises the QoS as the
#: integer-enum YAML string Humble decodes; its file is then rewritten as version 5).
WRITER_VERSION = {"humble": 8, "jazzy": 9}


def _qos() -> list[Any]:
    """The QoS offered on every topic (in the MCAP channels and the metadata): keep last
    10, reliable, volatile, automatic liveliness, durations unspecified (0)."""
    # deferred: rosbags (optional) loads only when this runs
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    zero = QosTime(sec=0, nsec=0)
    return [Qos(history=QosHistory.KEEP_LAST, depth=10, reliability=QosReliability.RELIABLE,
                durability=QosDurability.VOLATILE, deadline=zero, lifespan=zero,
                liveliness=QosLiveliness.AUTOMATIC, liveliness_lease_duration=zero,
                avoid_ros_namespace_conventions=False)]


def check_distro(distro: object) -> str:
    if not isinstance(distro, str) or distro not in DISTROS:
        raise InputError(f"unknown ROS 2 distribution {distro!r}", value=distro,
                         valid=f"one of {sorted(DISTROS)}")
    return distro


def humble_metadata(doc: dict[str, Any]) -> dict[str, Any]:
    """Humble's ``metadata.yaml`` (version 5) of the ``rosbags`` writer's version 8
    document: exactly the fields rosbag2's humble ``metadata_io.cpp`` encodes and
    decodes (``BagMetadata``, ``TopicInformation``, ``TopicMetadata`` with its
    ``offered_qos_profiles`` as a YAML string of integer enums, ``FileInformation``)."""
    info = doc["rosbag2_bagfile_information"]

    def ns(d: Any) -> dict[str, int]:
        return {"nanoseconds": int(d["nanoseconds"])}

    def since(d: Any) -> dict[str, int]:
        return {"nanoseconds_since_epoch": int(d["nanoseconds_since_epoch"])}

    return {"rosbag2_bagfile_information": {
        "version": DISTROS["humble"],
        "storage_identifier": str(info["storage_identifier"]),
        "duration": ns(info["duration"]),
        "starting_time": since(info["starting_time"]),
        "message_count": int(info["message_count"]),
        "topics_with_message_count": [
            {"topic_metadata": {"name": str(t["topic_metadata"]["name"]),
                                "type": str(t["topic_metadata"]["type"]),
                                "serialization_format":
                                    str(t["topic_metadata"]["serialization_format"]),
                                "offered_qos_profiles":
                                    str(t["topic_metadata"]["offered_qos_profiles"])},
             "message_count": int(t["message_count"])}
            for t in info["topics_with_message_count"]],
        "compression_format": str(info["compression_format"] or ""),
        "compression_mode": str(info["compression_mode"] or ""),
        "relative_file_paths": [str(p) for p in info["relative_file_paths"]],
        "files": [{"path": str(f["path"]), "starting_time": since(f["starting_time"]),
                   "duration": ns(f["duration"]), "message_count": int(f["message_count"])}
                  for f in info["files"]],
    }}


def _finish_metadata(bag: Path, distro: str) -> None:
    """Rewrite the bag's ``metadata.yaml`` for ``distro`` (atomically)."""


    meta = bag / "metadata.yaml"
    doc = yaml.safe_load(meta.read_text())
    if distro == "humble":
        doc = humble_metadata(doc)
    else:
        doc["rosbag2_bagfile_information"]["ros_distro"] = distro
    atomic_write(meta, yaml.safe_dump(doc, sort_keys=False).encode())


def _rosbags() -> tuple[Any, Any, Any]:
    try:
        # deferred: rosbags (optional) loads only when this runs
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError("the rosbag2 export needs the rosbags library: pip install "
                         "'sixplus3[ros]'", value=None, valid="rosbags installed") from None
    return Writer, StoragePlugin, get_typestore(Stores.ROS2_HUMBLE)


def _stamp(types: Any, ns: int) -> Any:
    return types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000,
                                                 nanosec=ns % 1_000_000_000)


def revolute_joints(robot: Robot) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(names, q indices, v indices) of every one-degree-of-freedom joint of the model,
    in the URDF's order (the floating platform joint left out)."""
    m = closed_loop_model(robot).model
    names, iq, iv = [], [], []
    for j in range(1, m.njoints):
        if m.nqs[j] == 1:
            names.append(m.names[j])
            iq.append(m.idx_qs[j])
            iv.append(m.idx_vs[j])
    return names, np.array(iq), np.array(iv)


def write_rosbag2(path: str | Path, robot: Robot, out_dir: str | Path,
                  distro: str = "humble", start_ns: int | None = None) -> Path:
    """Validate the trajectory file ``path`` for ``robot`` and write it as a rosbag2
    directory ``out_dir`` (MCAP) that ``distro``'s rosbag2 reads, its stamps from
    ``start_ns`` [ns since the epoch] (default: now), with the replay files beside the
    data (module doc).  Raises :class:`ValidationFailed` for a file that fails the gate
    and :class:`InputError` for an existing output, a bad distribution or start time,
    or a missing ``rosbags``."""

    check_distro(distro)
    if start_ns is None:
        start_ns = time.time_ns()
    if (isinstance(start_ns, bool) or not isinstance(start_ns, int)
            or not 0 <= start_ns <= 2**62):
        raise InputError(f"the bag's start time must be whole nanoseconds since the epoch "
                         f"in [0, 2^62], got {start_ns!r}", value=start_ns,
                         valid="[0, 2^62] ns")
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
    assert rep.rate_hz is not None
    motion = motion_of(data, rep.rate_hz)
    t, thd = motion.t, motion.theta_dot
    cfg = robot_ik(rep.position, matrix_from_quat(rep.quaternion), rep.psi, robot,
                   platform_margins=False)
    names, iq, iv = revolute_joints(robot)
    dyn = ClosedLoopDynamics(robot)
    zero = np.zeros(9)
    T = store.types
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name[:80]}.", suffix=".tmp"))
    bag = tmp / "bag"
    try:
        qos = _qos()
        with Writer(bag, version=WRITER_VERSION[distro],
                    storage_plugin=StoragePlugin.MCAP) as writer:
            c_js = writer.add_connection(TOPICS["joint_states"], "sensor_msgs/msg/JointState",
                                         typestore=store, offered_qos_profiles=qos)
            c_tf = writer.add_connection(TOPICS["tf"], "tf2_msgs/msg/TFMessage",
                                         typestore=store, offered_qos_profiles=qos)
            c_tr = writer.add_connection(TOPICS["trajectory"],
                                         "trajectory_msgs/msg/JointTrajectory",
                                         typestore=store, offered_qos_profiles=qos)
            writer.write(c_tr, start_ns, store.serialize_cdr(
                _trajectory(T, ros2_joint_trajectory(motion,
                                                     columns(data, "tau")), start_ns),
                "trajectory_msgs/msg/JointTrajectory"))
            for k in range(len(t)):
                ns = start_ns + int(round(float(t[k]) * 1e9))
                stamp = _stamp(T, ns)
                q = cfg.q[k]
                v, _ = dyn.consistent_state(q, thd[k], zero)
                js = T["sensor_msgs/msg/JointState"](
                    header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="base_link"),
                    name=names, position=q[iq].astype(np.float64),
                    velocity=np.asarray(v)[iv].astype(np.float64),
                    effort=np.zeros(0, dtype=np.float64))
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
        _finish_metadata(bag, distro)
        write_replay_files(bag, robot, names, float(t[-1]))
        os.rename(bag, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def _trajectory(T: Any, msg: dict[str, Any], start_ns: int) -> Any:
    """A JointTrajectory message of the typestore from the mapping of
    :func:`ros2_joint_trajectory`."""
    Duration = T["builtin_interfaces/msg/Duration"]
    points = [T["trajectory_msgs/msg/JointTrajectoryPoint"](
        positions=np.array(p["positions"]), velocities=np.array(p["velocities"]),
        accelerations=np.array(p["accelerations"]), effort=np.array(p["effort"]),
        time_from_start=Duration(sec=p["time_from_start"]["sec"],
                                 nanosec=p["time_from_start"]["nanosec"]))
        for p in msg["points"]]
    header = T["std_msgs/msg/Header"](stamp=_stamp(T, start_ns),
                                      frame_id=msg["header"]["frame_id"])
    return T["trajectory_msgs/msg/JointTrajectory"](header=header,
                                                    joint_names=msg["joint_names"],
                                                    points=points)


#: The registry's entry (control/formats/registry.py): a directory, not text.
FORMAT = ExportFormat(
    "rosbag2", "a ROS 2 bag (MCAP directory: /joint_states of every joint, /tf, the "
    "trajectory) with its replay launch file", torque_hold="sample", interpolated=False,
    directory=write_rosbag2)


__all__ = ["DISTROS", "FORMAT", "TOPICS", "WRITER_VERSION", "check_distro", "humble_metadata",
           "revolute_joints", "write_rosbag2"]
