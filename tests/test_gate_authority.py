"""The gate's authority (docs/validation.md, "The envelope"): hardware limits that no
robot, task or trajectory file can raise, exports checked as the controller runs them,
and the audit's hostile inputs, each built here."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sixplus3.cli import main as cli
from sixplus3.control.file.trajectory_read import read_trajectory
from sixplus3.control.gate.validation import validate_and_write, validate_file
from sixplus3.control.pipeline import run_plan
from sixplus3.errors import GeometryError, InputError, TaskError
from sixplus3.fileio import parse_yaml
from sixplus3.motion import Motion
from sixplus3.planner.task import Task, task_from_dict
from sixplus3.planner.waypoint import Waypoint
from sixplus3.robot_description import hardware
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()


pytestmark = pytest.mark.usefixtures("catalogue_hardware")  # tests/conftest.py


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    out = tmp_path_factory.mktemp("authority")
    task = task_from_dict({"name": "auth", "nodes_per_segment": 6, "waypoints": [
        {"position": [0, 0, 0.58]}, {"position": [0.03, 0, 0.58]}]})
    res = run_plan(task, out, ROBOT, html=False, plots=False)
    return res.csv


def _run(args: list[str], env: dict | None = None):
    return CliRunner().invoke(cli, args, env=env)


# ----------------------------------------------------------------- the envelope
@pytest.mark.parametrize("doc, figure", [
    ({"motors": {"rated_torque": 50}, "limits": {"torque": 100}}, "rated_torque"),
    ({"motors": {"gear_ratio": 0.1}, "limits": {"velocity": 300}}, "gear_ratio"),
    ({"limits": {"torque": 10.5}}, "limits.torque"),
    ({"limits": {"velocity": 20}}, "limits.velocity"),
    ({"motors": {"encoder_bits": 24}}, "encoder_bits"),
    ({"motors": {"model": "SGMCS-35E+belt-72/34"}}, "motors.model"),
])
def test_a_robot_file_cannot_raise_the_envelope(tmp_path, planned, doc, figure) -> None:
    path = tmp_path / "r.yaml"
    path.write_text(yaml.safe_dump(doc))
    res = _run(["--robot", str(path), "validate", str(planned)])
    assert res.exit_code == 2, res.output
    assert figure in res.output and "Traceback" not in res.output
    assert len(res.output.strip().splitlines()) == 1
    with pytest.raises(GeometryError):
        Robot.from_dict(doc)


def test_a_robot_file_may_change_what_a_lab_measures_and_tighten() -> None:
    r = Robot.from_dict({"motors": {"rotor_inertia": 0.006, "viscous": 0.03, "coulomb": 0.2,
                                    "directions": [-1] + [1] * 8},
                         "limits": {"torque": 8.0}, "masses": {"platform": 0.4}})
    assert r.limits.torque == 8.0 and r.motors.armature > ROBOT.motors.armature
    assert hardware.effective_limits(r).torque == 8.0


def test_the_site_file_tightens_and_names_itself(tmp_path, planned) -> None:
    ok = _run(["validate", str(planned)])
    assert ok.exit_code == 0, ok.output
    assert "envelope: SGMCS-05B+belt-72/34 from the built-in catalogue" in ok.output
    peak = validate_file(planned, ROBOT).max_torque_ratio * ROBOT.limits.torque
    site = tmp_path / "site.yaml"
    site.write_text(yaml.safe_dump({"drive_train": "SGMCS-05B+belt-72/34",
                                    "limits": {"torque": round(0.8 * peak, 3)}}))
    res = _run(["--hardware", str(site), "validate", str(planned)])
    assert res.exit_code == 1, res.output
    assert "site file site.yaml, sha256" in res.output and "torque" in res.output
    # through the environment, the same
    res = _run(["validate", str(planned)], env={hardware.ENV: str(site)})
    assert res.exit_code == 1, res.output
    # a robot file above the site's envelope is refused, naming both values
    robot = tmp_path / "r.yaml"
    robot.write_text(yaml.safe_dump({"limits": {"torque": 9.5}}))
    res = _run(["--hardware", str(site), "--robot", str(robot), "robot", "show"])
    assert res.exit_code == 2 and "limits.torque=9.5" in res.output, res.output
    assert "site hardware" in res.output
    # a site file cannot raise the catalogue either
    site.write_text(yaml.safe_dump({"limits": {"torque": 12}}))
    res = _run(["--hardware", str(site), "validate", str(planned)])
    assert res.exit_code == 2 and "hardware.limits.torque" in res.output, res.output


def test_people_limits_hold_whatever_the_header_says(tmp_path, planned) -> None:
    """A file planned with no platform limit, judged at a collaborative site: the gate
    enforces the site's platform speed; deleting a header's limit cannot undo it."""
    rep = validate_file(planned, ROBOT)
    assert rep.ok and rep.max_tcp_speed > 0.25
    site = tmp_path / "cobot.yaml"
    site.write_text("people: collaborative\n")
    res = _run(["--hardware", str(site), "validate", "--json", str(planned)])
    assert res.exit_code == 1, res.output
    out = json.loads(res.output)
    assert out["limits"]["tcp_speed"] == 0.25
    assert any("tcp speed" in f for f in out["findings"])
    # the robot's own platform limit is part of the robot the gate judges by
    slow = ROBOT.replace(limits=ROBOT.limits.tightened(tcp_speed=0.25))
    assert hardware.effective_limits(slow).tcp_speed == 0.25


# ----------------------------------------------------------------- exports
def test_export_at_a_low_rate_is_refused_with_the_lowest_safe_rate(planned, tmp_path) -> None:
    from sixplus3.control.formats.exports import dense_rate_for, densify

    assert dense_rate_for(10.0) == 1000.0 and dense_rate_for(300.0) == 1200.0
    t = np.arange(3) / 10.0
    th = np.array([[0.0] * 9, [0.1] * 9, [0.1] * 9])
    z = np.zeros((3, 9))
    td, dth, dv, da, _ = densify(t, th, z, z, np.zeros((3, 9)), 10.0, 1000.0)
    assert len(td) == 201 and np.allclose(dth[::100], th) and np.allclose(dv[::100], z)
    res = _run(["export", str(planned), "--format", "ros2-json", "--rate", "10"])
    assert res.exit_code in (0, 1), res.output
    if res.exit_code == 1:
        assert "lowest safe rate" in res.output and "Traceback" not in res.output
    # a rate typed a hair off the file's own is the file's own (once refused with "at
    # 1000 Hz fails ... the lowest safe rate is the file's own 1000 Hz")
    near = _run(["export", str(planned), "--format", "ros2-json", "--rate", "999.9999999"])
    same = _run(["export", str(planned), "--format", "ros2-json", "--rate", "1000"])
    assert near.exit_code == same.exit_code == 0 and near.output == same.output


def test_export_never_writes_over_its_input_or_a_trajectory(planned, tmp_path) -> None:
    copy = tmp_path / "t.csv"
    copy.write_bytes(planned.read_bytes())
    before = copy.read_bytes()
    res = _run(["export", str(copy), "--format", "ros2-json", "-o", str(copy)])
    assert res.exit_code == 2 and "input" in res.output and copy.read_bytes() == before
    link = tmp_path / "link.csv"
    os.link(copy, link)  # the same inode under another name
    res = _run(["export", str(copy), "--format", "drive-csv", "-o", str(link)])
    assert res.exit_code == 2 and copy.read_bytes() == before
    other = tmp_path / "other.csv"
    other.write_bytes(before)
    res = _run(["export", str(copy), "--format", "drive-csv", "-o", str(other)])
    assert res.exit_code == 2 and "--force" in res.output and other.read_bytes() == before
    res = _run(["export", str(copy), "--format", "drive-csv", "-o", str(other), "--force"])
    assert res.exit_code == 0 and other.read_bytes() != before


def test_rosbag2_refuses_rate_and_goal(planned, tmp_path) -> None:
    for extra in (["--rate", "100"], ["--goal"]):
        res = _run(["export", str(planned), "--format", "rosbag2", "-o",
                    str(tmp_path / "bag")] + extra)
        assert res.exit_code == 2 and "rosbag2" in res.output, res.output
        assert not (tmp_path / "bag").exists()


def test_play_refuses_what_the_gate_refuses(planned, tmp_path) -> None:
    lines = planned.read_text().splitlines(keepends=True)
    bad = tmp_path / "bad.csv"
    bad.write_text("".join(lines[:-3]))  # cut: the digest fails
    page = tmp_path / "p.html"
    res = _run(["play", str(bad), "--html", str(page)])
    assert res.exit_code == 2 and not page.exists() and "digest" in res.output


def test_play_unsafe_shows_a_red_banner_for_a_limit_violation(planned, tmp_path) -> None:
    pytest.importorskip("meshcat")
    site = tmp_path / "site.yaml"
    site.write_text("people: collaborative\n")
    page = tmp_path / "p.html"
    res = _run(["--hardware", str(site), "play", str(planned), "--html", str(page)])
    assert res.exit_code == 1 and not page.exists()
    res = _run(["--hardware", str(site), "play", str(planned), "--html", str(page),
                "--unsafe"])
    assert res.exit_code == 0, res.output
    html = page.read_text()
    assert 'id="sixplus3-refused"' in html and "tcp speed" in html


# ----------------------------------------------------------------- input doors
def test_a_yaml_alias_bomb_is_refused_at_once() -> None:
    lines = ["a0: &a0 [1, 2, 3, 4, 5, 6, 7, 8]"]
    for i in range(1, 10):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 8) + "]")
    text = "\n".join(lines) + "\n"
    assert len(text) < 1100 and text.count("*") == 72
    with pytest.raises(InputError, match="alias bomb"):
        parse_yaml(text, "bomb")
    assert parse_yaml("a: &x [1, 2]\nb: *x\n", "ok") == {"a": [1, 2], "b": [1, 2]}


def test_the_cli_reads_every_yaml_input_through_the_cap(tmp_path, planned) -> None:
    lines = ["a0: &a0 [1, 2, 3, 4, 5, 6, 7, 8]"]
    for i in range(1, 10):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 8) + "]")
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("\n".join(lines) + "\n")
    for args in (["--robot", str(bomb), "robot", "show"], ["plan", str(bomb), "-o",
                                                           str(tmp_path)],
                 ["validate", str(planned), "--task", str(bomb)],
                 ["--hardware", str(bomb), "robot", "show"]):
        res = _run(args)
        assert res.exit_code == 2 and "alias bomb" in res.output, (args, res.output)


def test_validate_and_write_caps_and_types(tmp_path) -> None:
    big = np.broadcast_to(np.zeros(9), (10 ** 8, 9))
    t = np.broadcast_to(np.zeros(1), (10 ** 8,))
    with pytest.raises(InputError, match="120000"):
        validate_and_write(tmp_path / "x.csv", Motion(t, big, big, big, 1000.0), ROBOT, big)
    n = 130_000
    z = np.broadcast_to(np.zeros(9), (n, 9))
    with pytest.raises(InputError, match="120000"):
        validate_and_write(tmp_path / "x.csv", Motion(np.arange(n) / 1e3, z, z, z, 1000.0), ROBOT,
                           z)
    z = np.zeros((5, 9))
    with pytest.raises(InputError, match="theta is missing"):
        validate_and_write(tmp_path / "x.csv", Motion(np.arange(5) / 1e3, None, z, z, 1e3), ROBOT,
                           z)
    with pytest.raises(InputError, match="rate must be a number"):
        validate_and_write(tmp_path / "x.csv", Motion(np.arange(5) / 1e3, z, z, z, "1000"), ROBOT,
                           z)
    with pytest.raises(InputError, match="real numbers"):
        validate_and_write(tmp_path / "x.csv", Motion(np.arange(5) / 1e3, z + 0j, z, z, 1e3),
                           ROBOT, z)
    assert not list(tmp_path.iterdir())


def test_trajectory_data_indexing(planned) -> None:
    traj = read_trajectory(planned, ROBOT)
    header, data = traj
    assert traj[0] is header and traj[1] is data
    for key in (123, None, 2.0, True):
        with pytest.raises(InputError):
            traj[key]


def test_dynamics_doors() -> None:
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.kinematics.robot import robot_ik_pose

    dyn = ClosedLoopDynamics(ROBOT)
    cfg = robot_ik_pose((0, 0, 0.58), np.zeros(3), np.radians([90] * 3), robot=ROBOT)
    q = cfg.q[0]
    assert np.all(np.isfinite(dyn.gravity_torques(q)))
    with pytest.raises(InputError, match="theta_dot"):
        dyn.consistent_state(q, np.full(9, np.nan), np.zeros(9))
    q2 = q.copy()
    quat = slice(dyn.model.joints[-1].idx_q, None)  # any: find the free joint below
    for j in dyn.model.joints:
        if j.nq == 7:
            quat = slice(j.idx_q + 3, j.idx_q + 7)
    q2[quat] *= 2.0  # a quaternion of norm 2
    with pytest.raises(InputError, match="norm 1"):
        dyn.gravity_torques(q2)


def test_task_and_waypoint_doors() -> None:
    with pytest.raises(TaskError, match="at least 2"):
        Task(waypoints=())
    with pytest.raises(TaskError, match="position"):
        Waypoint(np.array([np.nan, 0, 0.5]), np.eye(3))
    with pytest.raises(TaskError, match="rotation"):
        Waypoint(np.zeros(3), 2 * np.eye(3))


def test_names_are_printable_and_numbers_strict(tmp_path) -> None:
    for name in ("evil\x1b[31m", "two\nlines"):
        with pytest.raises(GeometryError, match="printable"):
            ROBOT.replace(name=name)
        path = tmp_path / "r.yaml"
        path.write_text(yaml.safe_dump({"name": name}))
        res = _run(["--robot", str(path), "robot", "show"])
        assert res.exit_code == 2 and "\x1b" not in res.output
    for bad in ("1_000", "inf", "nan", "0x10", "1e3.5"):
        res = _run(["plan", "tilt30_x", "--rate", bad, "-o", str(tmp_path)])
        assert res.exit_code == 2 and "is not a number" in res.output, (bad, res.output)


def test_no_command_writes_over_its_robot_file(tmp_path) -> None:
    """The invocation's --robot file is an input of every command: an output named after
    it is refused (exit 2, one line) and the file is kept."""
    from sixplus3.identification.report import robot_yaml

    path = tmp_path / "robot.yaml"
    path.write_text(robot_yaml(ROBOT))
    before = path.read_bytes()
    res = _run(["--robot", str(path), "commission", "zero", "--counts", *["0"] * 9,
                "-o", str(path)])
    assert res.exit_code == 2 and "input" in res.output and "Traceback" not in res.output
    assert path.read_bytes() == before
