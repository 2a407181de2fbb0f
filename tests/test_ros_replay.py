"""The bag a lab's ROS 2 reads: Humble's metadata.yaml (version 5, exactly the fields of
its reader), Jazzy's (version 9), stamps from a chosen start, and the launch file and
RViz configuration that replay it on robot_state_publisher with the URDF."""

from __future__ import annotations

import sys
import time
import types
import xml.etree.ElementTree as ET

import pytest
import yaml
from click.testing import CliRunner

from sixplus3.cli import main
from sixplus3.control.formats.rosbag import DISTROS, revolute_joints
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()

# rosbag2's humble branch (d256a5ba), rosbag2_storage/src/rosbag2_storage/metadata_io.cpp:
# the keys convert<BagMetadata>, <TopicInformation>, <TopicMetadata>, <FileInformation>,
# <nanoseconds> and <time_point> encode (and decode for version 5), each with its type.
NS = {"nanoseconds": int}
SINCE = {"nanoseconds_since_epoch": int}
HUMBLE_SCHEMA = {"rosbag2_bagfile_information": {
    "version": int, "storage_identifier": str, "duration": NS, "starting_time": SINCE,
    "message_count": int,
    "topics_with_message_count": [{"topic_metadata": {
        "name": str, "type": str, "serialization_format": str,
        "offered_qos_profiles": str}, "message_count": int}],
    "compression_format": str, "compression_mode": str,
    "relative_file_paths": [str],
    "files": [{"path": str, "starting_time": SINCE, "duration": NS,
               "message_count": int}]}}
# rosbag2_transport/src/rosbag2_transport/qos.cpp (humble): the keys Rosbag2QoS decodes
QOS_KEYS = {"history", "depth", "reliability", "durability", "deadline", "lifespan",
            "liveliness", "liveliness_lease_duration", "avoid_ros_namespace_conventions"}


def _conforms(doc, schema, where="") -> None:
    if isinstance(schema, dict):
        assert isinstance(doc, dict) and set(doc) == set(schema), (where, set(doc) ^ set(schema))
        for k, sub in schema.items():
            _conforms(doc[k], sub, f"{where}.{k}")
    elif isinstance(schema, list):
        assert isinstance(doc, list) and doc, where
        for i, item in enumerate(doc):
            _conforms(item, schema[0], f"{where}[{i}]")
    else:
        assert type(doc) is schema, (where, type(doc), schema)


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    d = tmp_path_factory.mktemp("plan")
    res = CliRunner().invoke(main, ["plan", "tilt30_x", "-o", str(d), "--no-html", "--quiet"])
    assert res.exit_code == 0, res.output
    return d / "tilt30_x.csv"


def test_humble_metadata_has_exactly_the_fields_of_humbles_reader(planned, tmp_path) -> None:
    pytest.importorskip("rosbags")
    res = CliRunner().invoke(main, ["export", str(planned), "--format", "rosbag2", "-o",
                                    str(tmp_path / "h"), "--ros-distro", "humble",
                                    "--start-time", "1800000000"])
    assert res.exit_code == 0, res.output
    doc = yaml.safe_load((tmp_path / "h" / "metadata.yaml").read_text())
    _conforms(doc, HUMBLE_SCHEMA)
    info = doc["rosbag2_bagfile_information"]
    assert info["version"] == DISTROS["humble"] == 5
    assert info["storage_identifier"] == "mcap"
    assert info["starting_time"]["nanoseconds_since_epoch"] == 1_800_000_000 * 10**9
    assert info["files"][0]["path"] == info["relative_file_paths"][0] == "bag.mcap"
    assert info["message_count"] == sum(t["message_count"]
                                        for t in info["topics_with_message_count"])
    for t in info["topics_with_message_count"]:
        qos = yaml.safe_load(t["topic_metadata"]["offered_qos_profiles"])
        assert isinstance(qos, list) and len(qos) == 1 and set(qos[0]) == QOS_KEYS
        assert qos[0]["deadline"] == {"sec": 0, "nsec": 0}
    # and the bag still reads (rosbags reads every version)
    from rosbags.highlevel import AnyReader

    with AnyReader([tmp_path / "h"]) as reader:
        assert reader.start_time == 1_800_000_000 * 10**9
        assert reader.message_count == info["message_count"]


def test_jazzy_metadata_and_the_default_start_is_now(planned, tmp_path) -> None:
    pytest.importorskip("rosbags")
    before = time.time_ns()
    res = CliRunner().invoke(main, ["export", str(planned), "--format", "rosbag2", "-o",
                                    str(tmp_path / "j"), "--ros-distro", "jazzy"])
    after = time.time_ns()
    assert res.exit_code == 0, res.output
    info = yaml.safe_load((tmp_path / "j" / "metadata.yaml").read_text())[
        "rosbag2_bagfile_information"]
    assert info["version"] == DISTROS["jazzy"] == 9 and info["ros_distro"] == "jazzy"
    assert before <= info["starting_time"]["nanoseconds_since_epoch"] <= after
    bad = CliRunner().invoke(main, ["export", str(planned), "--format", "rosbag2", "-o",
                                    str(tmp_path / "x"), "--ros-distro", "foxy"])
    assert bad.exit_code == 2 and "foxy" in bad.output
    bad = CliRunner().invoke(main, ["export", str(planned), "--format", "ros2-yaml",
                                    "--ros-distro", "jazzy"])
    assert bad.exit_code == 2 and "rosbag2" in bad.output


class _Recorder:
    """A stand-in for the launch API's classes: records its arguments."""

    def __init__(self, *args, **kw):
        self.args, self.kw = args, kw


def _stub_launch(monkeypatch) -> None:
    mods = {"launch": ["LaunchDescription"],
            "launch.actions": ["DeclareLaunchArgument", "ExecuteProcess"],
            "launch.conditions": ["IfCondition", "UnlessCondition"],
            "launch.substitutions": ["LaunchConfiguration"],
            "launch_ros.actions": ["Node"]}
    for name in ("launch_ros",):
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))
    for name, classes in mods.items():
        mod = types.ModuleType(name)
        for c in classes:
            setattr(mod, c, type(c, (_Recorder,), {}))
        monkeypatch.setitem(sys.modules, name, mod)


def test_the_launch_file_replays_the_bag_on_the_urdf(planned, tmp_path, monkeypatch) -> None:
    """The launch file runs (against a stand-in of ROS 2's launch API) and starts
    robot_state_publisher with the bag's URDF, RViz with its configuration and `ros2 bag
    play --clock`, every node on the bag's clock; every joint the bag publishes is a
    joint of that URDF and every revolute joint of the URDF is published."""
    pytest.importorskip("rosbags")
    bag = tmp_path / "bag"
    res = CliRunner().invoke(main, ["export", str(planned), "--format", "rosbag2", "-o",
                                    str(bag)])
    assert res.exit_code == 0, res.output
    urdf = ET.fromstring((bag / "robot.urdf").read_text())
    revolute = {j.get("name") for j in urdf.iter("joint") if j.get("type") == "revolute"}
    links = {lk.get("name") for lk in urdf.iter("link")}
    names = revolute_joints(ROBOT)[0]
    assert set(names) == revolute and len(names) == 30
    rviz = yaml.safe_load((bag / "sixplus3.rviz").read_text())
    vm = rviz["Visualization Manager"]
    assert vm["Global Options"]["Fixed Frame"] in links
    model = [d for d in vm["Displays"] if d["Class"] == "rviz_default_plugins/RobotModel"]
    assert model and model[0]["Description Topic"]["Value"] == "/robot_description"
    # run the launch file
    _stub_launch(monkeypatch)
    code = compile((bag / "replay.launch.py").read_text(), str(bag / "replay.launch.py"),
                   "exec")
    ns = {"__file__": str(bag / "replay.launch.py"), "__name__": "replay"}
    exec(code, ns)  # noqa: S102 - our own generated file, under test
    ld = ns["generate_launch_description"]()
    actions = ld.args[0]
    nodes = {a.kw["package"]: a for a in actions if type(a).__name__ == "Node"}
    assert set(nodes) == {"robot_state_publisher", "rviz2"}
    rsp = nodes["robot_state_publisher"].kw["parameters"][0]
    assert rsp["use_sim_time"] is True
    assert rsp["robot_description"] == (bag / "robot.urdf").read_text()
    assert nodes["rviz2"].kw["parameters"][0]["use_sim_time"] is True
    assert nodes["rviz2"].kw["arguments"][-1] == str(bag / "sixplus3.rviz")
    plays = [a.kw["cmd"] for a in actions if type(a).__name__ == "ExecuteProcess"]
    assert plays and all(c[:4] == ["ros2", "bag", "play", str(bag)] and "--clock" in c
                         for c in plays)
    rate = [a for a in actions if type(a).__name__ == "DeclareLaunchArgument"
            and a.args[0] == "rate"]
    assert rate and float(rate[0].kw["default_value"]) == pytest.approx(0.1)
