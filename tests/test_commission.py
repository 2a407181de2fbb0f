"""Commissioning on simulated prototypes: zero offsets to one encoder count, a planted
reversed motor named, the corrected robot file, and read-back counts to a start state.

The plants (identification.plants.perturbed_plant, seeds 23 and 37, never used to tune
the check) carry random zero offsets within +-3 rad and one reversed motor each; the
lab's robot file starts from the nominal offsets 0 and directions +1."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from sixplus3.cli import main as cli
from sixplus3.control.drive.plant import run_jog
from sixplus3.control.file.drive_log import (
    DriveLog,
    counts_per_rad,
    read_log,
    to_drive_units,
    write_log,
)
from sixplus3.errors import InputError
from sixplus3.identification.commission import (
    check_directions,
    counts_to_theta,
    known_pose,
    zero_offsets,
)
from sixplus3.identification.plants import perturbed_plant
from sixplus3.identification.report import robot_yaml
from sixplus3.robot_description.robot import Robot, load_robot

NOMINAL = Robot.default()
K = counts_per_rad(NOMINAL)


def _plant(seed: int, reversed_motor: int) -> Robot:
    rng = np.random.default_rng(seed)
    dirs = [1] * 9
    dirs[reversed_motor] = -1
    p = perturbed_plant(NOMINAL, seed)
    return p.replace(motors=replace(p.motors, zero_offsets=tuple(rng.uniform(-3, 3, 9)),
                                    directions=tuple(dirs)))


@pytest.fixture(scope="module", params=[(23, 4), (37, 8)], ids=["seed23-leg1_B", "seed37-leg2_C"])
def jogged(request, tmp_path_factory):
    seed, rev = request.param
    plant = _plant(seed, rev)
    d = tmp_path_factory.mktemp(f"jog{seed}")
    (d / "plant.yaml").write_text(robot_yaml(plant))
    res = CliRunner().invoke(cli, ["commission", "jog", "--plant", str(d / "plant.yaml"),
                                   "-o", str(d / "jog.csv"), "--seed", str(seed)])
    assert res.exit_code == 0, res.output
    return plant, rev, d


def test_zero_then_directions_recover_the_planted_offsets_and_reversal(jogged) -> None:
    plant, rev, d = jogged
    run = CliRunner()
    # the first 0.3 s of the jog log: the robot resting in the home jig
    lines = (d / "jog.csv").read_text().splitlines()
    (d / "rest.csv").write_text("\n".join(lines[:2 + 290]) + "\n")
    res = run.invoke(cli, ["commission", "zero", "--log", str(d / "rest.csv"),
                           "-o", str(d / "zeroed.yaml")])
    assert res.exit_code == 0, res.output
    zeroed = load_robot(d / "zeroed.yaml")
    err = (np.array(zeroed.motors.zero_offsets) - np.array(plant.motors.zero_offsets)) * K
    ok = [j for j in range(9) if j != rev]
    assert np.abs(err[ok]).max() <= 1.0  # one encoder count
    assert abs(err[rev]) > 1000  # the reversed motor's offset cannot be right yet
    # the direction check on the zeroed robot names the planted motor, and only it
    res = run.invoke(cli, ["--robot", str(d / "zeroed.yaml"), "commission", "directions",
                           str(d / "jog.csv")])
    assert res.exit_code == 1, res.output  # reversed, and no -o: not fixed
    names = [ln.split(":")[0].strip() for ln in res.output.splitlines() if "REVERSED" in ln]
    assert names == [("leg0_A leg0_B leg0_C leg1_A leg1_B leg1_C leg2_A leg2_B "
                      "leg2_C").split()[rev]]
    res = run.invoke(cli, ["--robot", str(d / "zeroed.yaml"), "commission", "directions",
                           str(d / "jog.csv"), "-o", str(d / "commissioned.yaml")])
    assert res.exit_code == 0, res.output
    done = load_robot(d / "commissioned.yaml")
    assert done.motors.directions == plant.motors.directions
    err = (np.array(done.motors.zero_offsets) - np.array(plant.motors.zero_offsets)) * K
    assert np.abs(err).max() <= 1.0
    # the commissioned robot reads the jog log as the plant's true angles, and the check
    # finds nothing more to reverse
    lab = read_log(d / "jog.csv", done)
    truth = read_log(d / "jog.csv", plant)
    assert np.abs(lab.theta - truth.theta).max() <= 1.0 / K
    again = check_directions(done, lab)
    assert again.reversed == () and again.unjudged == ()
    assert again.total_before < 0.5 * check_directions(zeroed, read_log(
        d / "jog.csv", zeroed)).total_before


def test_zeroing_refuses_a_moving_robot_and_offsets_beyond_a_turn() -> None:
    pose = known_pose(NOMINAL)
    c = np.zeros((5, 9), dtype=np.int64)
    c[3, 2] = 5000  # leg0_C moved 0.8 deg while read
    with pytest.raises(InputError, match="leg0_C moved"):
        zero_offsets(NOMINAL, c, pose)
    with pytest.raises(InputError, match="more than a turn"):
        zero_offsets(NOMINAL, np.full(9, round(10 * K)), pose)
    with pytest.raises(InputError, match="whole"):
        zero_offsets(NOMINAL, np.full(9, 0.5), pose)
    z = zero_offsets(NOMINAL, np.zeros(9), pose)
    np.testing.assert_allclose(z.offsets, pose)


def test_read_back_counts_give_the_start_state(tmp_path) -> None:
    """feed --start-counts: the counts of a file's first sample pass the start check,
    counts a degree away are refused (exit 2, nothing sent)."""
    run = CliRunner()
    robot = NOMINAL.replace(motors=replace(NOMINAL.motors, zero_offsets=(0.3,) * 9,
                                           directions=(1, -1, 1, 1, 1, -1, 1, 1, 1)))
    (tmp_path / "r.yaml").write_text(robot_yaml(robot))
    res = run.invoke(cli, ["--robot", str(tmp_path / "r.yaml"), "plan", "tilt30_x", "-o",
                           str(tmp_path), "--no-html", "--quiet"])
    assert res.exit_code == 0, res.output
    path = tmp_path / "tilt30_x.csv"
    from sixplus3.control.file.trajectory_read import read_trajectory

    first = read_trajectory(path, robot).joints("pos")[0]
    counts, _, _ = to_drive_units(robot, first[None], None, np.zeros((1, 9)))
    np.testing.assert_allclose(counts_to_theta(robot, counts[0]), first, atol=0.5 / K)
    args = ["--robot", str(tmp_path / "r.yaml"), "feed", str(path), "--dry-run",
            "--start-counts", *map(str, counts[0].tolist())]
    res = run.invoke(cli, args)
    assert res.exit_code == 0, res.output
    off = counts[0].copy()
    off[4] += int(math.radians(1.0) * K)
    res = run.invoke(cli, [*args[:-9], *map(str, off.tolist())])
    assert res.exit_code == 2 and "Traceback" not in res.output
    res = run.invoke(cli, ["--robot", str(tmp_path / "r.yaml"), "commission", "theta",
                           *map(str, counts[0].tolist())])
    assert res.exit_code == 0
    # within half a count of the file's angle, plus the 1e-6 deg the print rounds to
    np.testing.assert_allclose(np.radians([float(v) for v in res.output.split()]), first,
                               atol=0.5 / K + math.radians(1e-6))


def test_drive_unit_logs_round_trip(tmp_path) -> None:
    """A log written in the drive's integer units reads back as the same joint angles
    (to a count) and torques (to 0.1 % of rated), through offsets and directions."""
    robot = NOMINAL.replace(motors=replace(NOMINAL.motors, zero_offsets=(-1.0,) * 9,
                                           directions=(-1,) * 9))
    t = np.arange(300) / 1000.0
    th = np.tile(known_pose(robot), (300, 1)) + 0.01 * np.sin(t)[:, None]
    tau = np.tile(np.linspace(-3, 3, 9), (300, 1))
    write_log(tmp_path / "d.csv", DriveLog(t=t, theta=th, tau=tau), robot, units="drive")
    text = (tmp_path / "d.csv").read_text()
    assert "robot_kinematics" not in text and "_counts" in text
    back = read_log(tmp_path / "d.csv", robot)
    assert back.counts is not None and back.counts.dtype == np.int64
    assert np.abs(back.theta - th).max() <= 0.5 / K + 1e-12
    unit = robot.motors.gear_ratio * robot.motors.rated_torque / 1000.0
    assert np.abs(back.tau - tau).max() <= 0.5 * unit + 1e-12
    with pytest.raises(InputError, match="joint or drive"):
        write_log(tmp_path / "e.csv", back, robot, units="counts")


def test_a_jog_is_refused_outside_its_ranges() -> None:
    with pytest.raises(InputError, match="amplitude"):
        run_jog(NOMINAL, amplitude=2.0)
