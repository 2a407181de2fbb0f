"""Exports for the controller side: ROS 2 JointTrajectory and a servo-drive table, only
of files that pass the gate."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sixplus3.cli import main
from sixplus3.control.file.file_format import columns, motion_of
from sixplus3.control.file.trajectory_read import read_trajectory
from sixplus3.control.formats.drive_csv import drive_table
from sixplus3.control.formats.exports import export_file
from sixplus3.control.pipeline import run_plan
from sixplus3.errors import GeometryError, InputError, TrajectoryFileError
from sixplus3.motion import Motion
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.physical import MotorModel
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names

ROBOT = Robot.default()


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    out = tmp_path_factory.mktemp("exp")
    task = task_from_dict({"name": "exp", "nodes_per_segment": 6, "waypoints": [
        {"position": [0, 0, 0.58]}, {"position": [0.02, 0, 0.59], "rpy": [8, 0, 0]}]})
    path = run_plan(task, out, ROBOT, html=False, plots=False).csv
    return path, read_trajectory(path, ROBOT)[1]


def test_ros2_joint_trajectory_is_the_file(planned) -> None:
    path, data = planned
    msg = yaml.safe_load(export_file(path, ROBOT, "ros2-yaml"))
    assert msg["joint_names"] == actuated_joint_names()
    assert len(msg["points"]) == len(data)
    for k in (0, len(data) // 2, len(data) - 1):
        p = msg["points"][k]
        assert p["positions"] == list(columns(data, "pos")[k])  # exact (%.17g round trip)
        assert p["effort"] == list(columns(data, "tau")[k])
        t = p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"]
        assert t == pytest.approx(data[k, 0], abs=1e-9)
        assert 0 <= p["time_from_start"]["nanosec"] < 1_000_000_000
    assert json.loads(export_file(path, ROBOT, "ros2-json")) == msg


def test_drive_table_units(planned) -> None:
    path, data = planned
    offs = tuple(np.linspace(-0.5, 0.5, 9))
    dirs = (1, -1, 1, 1, -1, 1, -1, 1, 1)
    robot = ROBOT.replace(motors=MotorModel(zero_offsets=offs, directions=dirs))
    th, thd, tau = columns(data, "pos"), columns(data, "vel"), columns(data, "tau")
    counts, vel, torque = drive_table(robot, motion_of(data, 1000.0), tau)
    n, bits = 72 / 34, 20
    # back to joint angles: within half a count of the file
    back = counts / (n * 2 ** bits / (2 * math.pi)) * np.array(dirs) + np.array(offs)
    assert np.abs(back - th).max() <= 0.5 * 2 * math.pi / (n * 2 ** bits) + 1e-12
    # the drive's velocity objects are integers: within half a count per second
    assert counts.dtype == vel.dtype == torque.dtype == np.int64
    np.testing.assert_allclose(vel * np.array(dirs) / (n * 2 ** bits / (2 * math.pi)), thd,
                               atol=0.5 / (n * 2 ** bits / (2 * math.pi)) + 1e-12)
    # 0.1 % of the 5 N m rated motor torque: the joint torque through the belt
    np.testing.assert_allclose(torque * np.array(dirs) * 5.0 * n / 1000.0, tau,
                               atol=0.5 * 5.0 * n / 1000.0 + 1e-12)
    assert np.abs(torque).max() <= 1000 * 10.0 / (n * 5.0) + 1  # the 10 N m joint limit
    with pytest.raises(GeometryError, match="directions"):
        MotorModel(directions=(1,) * 8 + (2,))


def test_only_valid_files_are_exported(planned, tmp_path) -> None:
    path, _ = planned
    lines = path.read_text().splitlines(keepends=True)
    bad = tmp_path / "bad.csv"
    bad.write_text("".join(lines[:-5]))  # cut: the integrity digest no longer matches
    runner = CliRunner()
    res = runner.invoke(main, ["export", str(bad), "--format", "ros2-yaml"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    out = tmp_path / "ok.csv"
    res = runner.invoke(main, ["export", str(path), "--format", "drive-csv", "-o", str(out)])
    assert res.exit_code == 0, res.output
    head = json.loads(out.read_text().splitlines()[0].split(" ", 4)[4])
    assert head["encoder_bits"] == 20 and head["gear_ratio"] == pytest.approx(72 / 34)
    # the drive's own torque limit: the envelope's, rounded down in the drive's units
    lim = head["drive_torque_limit"]
    assert lim["joint_n_m"] == ROBOT.limits.torque
    per_rated = ROBOT.limits.torque / (ROBOT.motors.gear_ratio * ROBOT.motors.rated_torque)
    assert lim["max_torque_0p1pct"] <= 1000 * per_rated < lim["max_torque_0p1pct"] + 1
    assert lim["torque_limit_pct"] <= 100 * per_rated < lim["torque_limit_pct"] + 1
    weak = ROBOT.replace(limits=ROBOT.limits.tightened(torque=1.0))
    with pytest.raises(TrajectoryFileError, match="robot mismatch"):  # not exported
        export_file(path, weak, "ros2-yaml")
    with pytest.raises(InputError, match="format"):
        export_file(path, ROBOT, "excel")


def test_outputs_never_replace_a_non_regular_file(tmp_path) -> None:
    """An output path that is a FIFO (or a device) is refused with one line naming it,
    exit 2, and left as it was; a missing directory is named too."""
    import os
    import stat

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    runner = CliRunner()
    res = runner.invoke(main, ["robot", "export", "mjcf", "-o", str(fifo)])
    assert res.exit_code == 2 and "not a regular file" in res.output and str(fifo) in res.output
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    missing = tmp_path / "no" / "x.xml"
    res = runner.invoke(main, ["robot", "export", "mjcf", "-o", str(missing)])
    assert res.exit_code == 2 and str(missing) in res.output and "Traceback" not in res.output


def test_the_ros2_yaml_reads_back_exactly_for_any_floats() -> None:
    """The hand-written YAML (a long motion's yaml.safe_dump held 2.8 GB) reads back with
    PyYAML as the message itself, for floats PyYAML 1.1 is fussy about (1e-05 without a
    '.', -0.0, subnormals, 1e16, 1e300)."""
    from sixplus3.control.formats.ros2 import ros2_joint_trajectory, ros2_yaml

    rng = np.random.default_rng(1)
    n = 40
    vals = [rng.normal(size=(n, 9)) * 10.0 ** rng.integers(-20, 20, size=(n, 9))
            for _ in range(4)]
    vals[0][0, 0], vals[1][0, 1], vals[2][0, 2] = 1e-5, -0.0, 1e300
    vals[3][0, 3], vals[3][0, 4] = 5e-324, 1e16
    msg = ros2_joint_trajectory(Motion(np.arange(n) / 1000.0, *vals[:3], 1000.0), vals[3])
    assert yaml.safe_load(ros2_yaml(msg)) == msg


def test_read_trajectory_names_its_columns(planned) -> None:
    from sixplus3.control.file.file_format import COLUMNS
    from sixplus3.errors import InputError

    path, data = planned
    traj = read_trajectory(path, ROBOT)
    header, same = traj  # unpacks as before
    assert same is traj.data and header["format"] == "sixplus3-trajectory/2"
    np.testing.assert_array_equal(traj["leg1_B_tau"], data[:, COLUMNS.index("leg1_B_tau")])
    np.testing.assert_array_equal(traj.joints("vel")[:, 4], traj["leg1_B_vel"])
    np.testing.assert_array_equal(traj.t, data[:, 0])
    np.testing.assert_array_equal(traj.platform_quaternion[:, 3], traj["platform_qw"])
    np.testing.assert_array_equal(traj.psi[:, 2], traj["psi_2"])
    df = traj.to_pandas()
    assert list(df.columns) == COLUMNS[1:] and df["leg2_C_pos"].iloc[-1] == data[-1, 33]
    # indexed by time, with every column's unit and the file's rate and robot
    assert df.index.name == "t [s]" and df.index[-1] == data[-1, 0]
    units = df.attrs["units"]
    assert (units["t"], units["leg0_A_pos"], units["leg1_B_vel"], units["leg2_C_acc"],
            units["leg0_A_tau"], units["platform_z"], units["platform_qw"], units["psi_1"]) \
        == ("s", "rad", "rad/s", "rad/s^2", "N m", "m", "1", "rad")
    assert set(units) == set(COLUMNS)
    assert df.attrs["rate_hz"] == header["rate_hz"] and df.attrs["robot_hash"] == ROBOT.hash
    named = traj.to_pandas(unit_names=True)
    assert named.columns[0] == "leg0_A_pos [rad]" and named.columns[-1] == "psi_2 [rad]"
    assert "platform_qx [1]" in named.columns and "leg0_A_tau [N m]" in named.columns
    with pytest.raises(InputError, match="no column"):
        traj["leg3_A_pos"]


def test_the_rosbag2_export_reads_back_in_rosbags(planned, tmp_path) -> None:
    """`export --format rosbag2 -o DIR`: an MCAP bag that the rosbags library reads with
    ROS 2 Humble's types: /joint_states of the 30 one-DoF joints on the file's time grid
    (the actuated positions exactly the file's), /tf of the platform, the trajectory."""
    rosbags = pytest.importorskip("rosbags")  # noqa: F841 - the optional extra
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from sixplus3.control.formats.rosbag import revolute_joints

    path, data = planned
    out = tmp_path / "bag"
    res = CliRunner().invoke(main, ["export", str(path), "--format", "rosbag2", "-o",
                                    str(out), "--start-time", "1790000000.5"])
    assert res.exit_code == 0, res.output
    start = 1_790_000_000_500_000_000  # the stamps start at the chosen time
    store = get_typestore(Stores.ROS2_HUMBLE)
    names = revolute_joints(ROBOT)[0]
    assert len(names) == 30 and set(actuated_joint_names()) <= set(names)
    act = [names.index(n) for n in actuated_joint_names()]
    seen = {"/joint_states": 0, "/tf": 0, "/joint_trajectory": 0}
    with Reader(out) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {"/joint_states": "sensor_msgs/msg/JointState",
                         "/tf": "tf2_msgs/msg/TFMessage",
                         "/joint_trajectory": "trajectory_msgs/msg/JointTrajectory"}
        for conn, stamp, raw in reader.messages():
            msg = store.deserialize_cdr(raw, conn.msgtype)
            if conn.topic == "/joint_trajectory":
                assert list(msg.joint_names) == actuated_joint_names()
                assert len(msg.points) == len(data)
            elif conn.topic == "/joint_states":
                k = seen["/joint_states"]
                assert stamp == start + round(data[k, 0] * 1e9)
                assert (msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec) == stamp
                assert list(msg.name) == names and len(msg.velocity) == 30
                np.testing.assert_allclose(msg.position[act], columns(data, "pos")[k],
                                           atol=1e-9)
                np.testing.assert_allclose(msg.velocity[act], columns(data, "vel")[k],
                                           atol=1e-9)
            else:
                k = seen["/tf"]
                tr = msg.transforms[0]
                assert tr.header.frame_id == "base_link" and tr.child_frame_id == "platform"
                assert tr.transform.translation.z == pytest.approx(data[k, 39], abs=1e-9)
            seen[conn.topic] += 1
    assert seen == {"/joint_states": len(data), "/tf": len(data), "/joint_trajectory": 1}
    again = CliRunner().invoke(main, ["export", str(path), "--format", "rosbag2", "-o",
                                      str(out)])
    assert again.exit_code == 2 and "directory" in again.output  # never written over
    from sixplus3.control.formats.rosbag import write_rosbag2
    from sixplus3.errors import InputError

    with pytest.raises(InputError, match="exists"):
        write_rosbag2(path, ROBOT, out)
    nodir = CliRunner().invoke(main, ["export", str(path), "--format", "rosbag2"])
    assert nodir.exit_code == 2


def test_decimation_is_validated_again_and_the_goal_form_wraps_it(planned, tmp_path) -> None:
    """--rate resamples on the quintic interpolant (at a whole fraction of the file's
    rate: exactly every m-th sample) and validates the motion interpolated through the
    new points again: a rate either gives a valid trajectory or is refused for what the
    interpolation does between the points (exit 1), never silently.  --goal wraps the
    trajectory into a FollowJointTrajectory goal."""
    from sixplus3.control.formats.exports import decimate
    from sixplus3.control.gate.validation import validate_file
    from sixplus3.errors import InputError, ValidationFailed

    path, data = planned
    rep = validate_file(path, ROBOT)
    passed = []
    for rate in (500.0, 250.0, 200.0, 100.0, 50.0, 10.0, 333.0, 37.5):
        try:
            t, th, v, a, tau, again = decimate(rep, ROBOT, rate)
        except ValidationFailed as exc:
            assert exc.exit_code == 1 and "between samples" in str(exc), str(exc)[:300]
            continue
        passed.append(rate)
        assert again.ok and again.rate_hz == rate
        np.testing.assert_array_equal(t, np.arange(len(t)) / rate)
        if 1000.0 % rate == 0:  # a whole fraction: exactly every m-th sample
            m = int(round(1000.0 / rate))
            inner = min(len(t), (len(data) - 1) // m + 1)
            np.testing.assert_allclose(th[:inner], columns(data, "pos")[::m][:inner],
                                       rtol=0, atol=1e-12)
        np.testing.assert_allclose(th[-1], columns(data, "pos")[-1], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(tau, again.tau)
        out = json.loads(export_file(path, ROBOT, "ros2-json", rate=rate))
        assert len(out["points"]) == len(t)
    assert passed, "no decimation of the small plan validated"
    for bad in (2000.0, 5.0, float("nan"), True):
        with pytest.raises(InputError, match="--rate must be in"):
            decimate(rep, ROBOT, bad)
    with pytest.raises(InputError, match="ROS 2 forms"):
        export_file(path, ROBOT, "drive-csv", rate=500.0)
    goal = yaml.safe_load(export_file(path, ROBOT, "ros2-yaml", goal=True))
    assert set(goal) == {"trajectory", "path_tolerance", "goal_tolerance",
                         "goal_time_tolerance"}
    assert goal["trajectory"] == yaml.safe_load(export_file(path, ROBOT, "ros2-yaml"))
    assert json.loads(export_file(path, ROBOT, "ros2-json", goal=True)) == goal
    r = CliRunner().invoke(main, ["export", str(path), "--format", "ros2-json", "--rate",
                                  "5"])
    assert r.exit_code == 2 and "--rate must be in" in r.output
