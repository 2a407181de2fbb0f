"""A second physics engine: MuJoCo, built from the MJCF export, against Pinocchio.

MuJoCo shares no code with our dynamics: its kinematics give the velocities and
accelerations of the tree (site Jacobians and mj_jacDot), its mass matrix and bias
forces the torques.  Only the configuration comes from our kinematics, and MuJoCo's
closure residual checks it.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from sixplus3.cli import main
from sixplus3.control.drive.mujoco_model import MujocoRobot
from sixplus3.control.drive.simulation import (
    engine_check,
    mujoco_inverse_dynamics,
    simulate_file,
)
from sixplus3.control.file.file_format import columns
from sixplus3.control.gate.findings import FEEDFORWARD_TOL
from sixplus3.control.gate.validation import validate_file
from sixplus3.control.pipeline import run_plan
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InputError
from sixplus3.examples import load as load_example
from sixplus3.kinematics.robot import robot_ik, robot_ik_pose
from sixplus3.kinematics.rotations import matrix_from_quat
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.physical import Payload
from sixplus3.robot_description.robot import Robot

mujoco = pytest.importorskip("mujoco")

ROBOT = Robot.default()
EXAMPLES = Path(__file__).parents[1] / "examples"


@pytest.fixture(scope="module")
def planned(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("mj")
    task = task_from_dict({"name": "short", "waypoints": [
        {"position": [0.0, 0.0, 0.58]}, {"position": [0.01, 0.0, 0.59], "rpy": [15, 0, 0]}],
        "nodes_per_segment": 8})
    return run_plan(task, out, ROBOT, html=False, plots=False).csv


@pytest.fixture(scope="module")
def ceiling(tmp_path_factory) -> tuple[Path, Robot]:
    """The ceiling example: a TCP task with a payload, planned and validated."""
    out = tmp_path_factory.mktemp("ceiling")
    task = load_example("ceiling_handle")
    return run_plan(task, out, ROBOT, html=False, plots=False).csv, task.robot_for(ROBOT)


def test_mjcf_is_the_robot() -> None:
    """The export has the tree, the 9 closures, 9 motors, the armature, the payload."""
    heavy = ROBOT.replace(payload=Payload(mass=0.5))
    sim = MujocoRobot(heavy)
    m = sim.model
    assert (m.nq, m.nv, m.neq, m.nu) == (37, 36, 9, 9)
    np.testing.assert_allclose(m.dof_armature[sim.act_dof], heavy.motors.armature)
    assert np.count_nonzero(m.dof_armature) == 9
    np.testing.assert_allclose(m.dof_damping[sim.act_dof], heavy.motors.viscous)
    total = float(m.body_mass.sum())
    assert total == pytest.approx(heavy.moving_mass, abs=1e-6)
    assert total == pytest.approx(MujocoRobot(ROBOT).model.body_mass.sum() + 0.5, abs=1e-6)


@pytest.mark.parametrize("robot", [ROBOT, Robot.mounted("ceiling", payload=Payload(
    mass=0.7, com=(0.02, 0.0, 0.05), inertia=(1e-3, 2e-3, 1.5e-3, 0, 1e-4, 0)))],
    ids=["default", "ceiling+payload"])
def test_mujoco_inverse_dynamics_matches_pinocchio_at_random_states(robot) -> None:
    rng = np.random.default_rng(1)
    dyn = ClosedLoopDynamics(robot)
    cfgs = [robot_ik_pose((0.03, -0.02, 0.60), (0.2, -0.1, 0.3), (1.4, 1.7, 1.2), robot=robot),
            robot_ik_pose((-0.04, 0.03, 0.56), (-0.3, 0.2, -0.4), (1.8, 1.3, 1.6), robot=robot)]
    sim = MujocoRobot(robot)
    for cfg in cfgs:
        q = cfg.q[0]
        thd, thdd = rng.normal(scale=2.0, size=9), rng.normal(scale=80.0, size=9)
        tau_pin, _ = dyn.actuated_inverse_dynamics(q, thd, thdd)
        tau_mj, res = sim.inverse_dynamics(q, thd, thdd)
        assert res < 1e-12  # MuJoCo sees the closures closed at our configuration
        assert np.abs(tau_mj - tau_pin).max() < 1e-6


def test_mujoco_inverse_dynamics_matches_the_planned_file(planned: Path) -> None:
    rep = validate_file(planned, ROBOT)
    assert rep.ok
    q = robot_ik(rep.position, matrix_from_quat(rep.quaternion), rep.psi, ROBOT).q
    tau, res = mujoco_inverse_dynamics(ROBOT, q, columns(rep.data, "vel"),
                                       columns(rep.data, "acc"))
    assert res.max() < 1e-10
    assert np.abs(tau - columns(rep.data, "tau")).max() <= FEEDFORWARD_TOL
    # and the rotors matter: without their armature MuJoCo's torques differ visibly
    bare = ROBOT.replace(motors=ROBOT.motors.__class__(rotor_inertia=0.0))
    tau0, _ = mujoco_inverse_dynamics(bare, q, columns(rep.data, "vel"),
                                      columns(rep.data, "acc"))
    assert np.abs(tau0 - tau).max() > 0.5


def test_open_loop_replay_stays_close(planned: Path) -> None:
    """Feed-forward only, no feedback: the drift over the short plan stays below 0.5 deg
    (the plant's friction is MuJoCo's dry friction, not the planner's smooth law)."""
    _, sim = simulate_file(planned, ROBOT, kp=0.0, kd=0.0)
    assert sim is not None and sim.pd_share == 0.0
    assert sim.max_tracking_error_rad < math.radians(0.5)
    assert sim.max_closure_residual_m < 1e-5


def test_pd_share_is_small_and_grows_with_a_wrong_feedforward(planned: Path) -> None:
    _, good = simulate_file(planned, ROBOT)
    _, weak = simulate_file(planned, ROBOT, feedforward_scale=0.9)
    assert good is not None and weak is not None
    assert good.pd_share < 0.1
    assert weak.pd_share > 1.5 * good.pd_share
    assert weak.max_tracking_error_rad > 1.5 * good.max_tracking_error_rad
    # the planner's 10 % torque reserve covers the feedback: within the hardware limit
    assert good.within_torque_limit


def test_ceiling_example_plans_validates_and_simulates(ceiling) -> None:
    path, robot = ceiling
    rep = validate_file(path, robot)
    assert rep.ok and rep.exit_code == 0
    eng = engine_check(robot, rep)
    assert eng.feedforward_error <= FEEDFORWARD_TOL and eng.exit_code == 0, eng.messages
    # the file's first TCP pose is the task's first waypoint
    task = load_example("ceiling_handle")
    R = matrix_from_quat(rep.quaternion[0])[0]
    p_tcp, R_tcp = robot.tool.tcp_pose(rep.position[0], R)
    np.testing.assert_allclose(p_tcp, task.waypoints[0].position, atol=1e-6)
    np.testing.assert_allclose(R_tcp, task.waypoints[0].rotation, atol=1e-6)
    # the payload and the mounting are in the torques: the default robot refuses the file
    res = CliRunner().invoke(main, ["validate", str(path)])
    assert res.exit_code == 2 and "robot mismatch" in res.output
    res = CliRunner().invoke(main, ["validate", str(path), "--simulate", "--json", "--task",
                                    str(EXAMPLES / "ceiling_handle.yaml")])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["mujoco"]["mujoco_feedforward_error"] <= FEEDFORWARD_TOL


def test_cli_simulate_and_bad_gains(planned: Path) -> None:
    runner = CliRunner()
    res = runner.invoke(main, ["simulate", str(planned), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["within_torque_limit"] and out["samples"] > 10
    for bad in (["--kp", "-1"], ["--kd", "nan"], ["--ff-scale", "5"]):
        res = runner.invoke(main, ["simulate", str(planned), *bad])
        assert res.exit_code == 2 and "Traceback" not in res.output, res.output
    with pytest.raises(InputError):
        simulate_file(planned, ROBOT, kp=float("inf"))


def test_export_mjcf_loads_in_mujoco(tmp_path) -> None:
    out = tmp_path / "robot.xml"
    res = CliRunner().invoke(main, ["robot", "export", "mjcf", "-o", str(out)])
    assert res.exit_code == 0, res.output
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.neq == 9 and m.nu == 9


_HOLD = r"""
import json, sys
import numpy as np
import mujoco as mj
m = mj.MjModel.from_xml_path(sys.argv[1])
d = mj.MjData(m)
mj.mj_resetDataKeyframe(m, d, mj.mj_name2id(m, mj.mjtObj.mjOBJ_KEY, "home"))
mj.mj_forward(m, d)
pairs = [(m.eq_obj1id[i], m.eq_obj2id[i]) for i in range(m.neq)]
def gap():
    return max(float(np.linalg.norm(d.site_xpos[a] - d.site_xpos[b])) for a, b in pairs)
plat = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, "platform_free")
p0, worst, contacts = d.xpos[plat].copy(), gap(), d.ncon
for k in range(int(round(1.0 / m.opt.timestep))):
    mj.mj_step(m, d)
    if k % 50 == 0:
        worst = max(worst, gap())
        contacts = max(contacts, d.ncon)
print(json.dumps({"gap": worst, "drift": float(np.linalg.norm(d.xpos[plat] - p0)),
                  "finite": bool(np.isfinite(d.qpos).all() and np.isfinite(d.qacc).all()),
                  "contacts": int(contacts), "sixplus3": "sixplus3" in sys.modules,
                  "ctrlrange": m.actuator_ctrlrange.tolist(),
                  "forcerange": m.actuator_forcerange.tolist(),
                  "limited": [int(m.jnt_limited[m.actuator_trnid[i, 0]]) for i in range(m.nu)],
                  "range": [m.jnt_range[m.actuator_trnid[i, 0]].tolist() for i in range(m.nu)]}))
"""


@pytest.mark.parametrize("mounting", ["floor", "ceiling"])
def test_the_exported_mjcf_runs_as_exported_in_plain_mujoco(tmp_path, mounting) -> None:
    """The exported file in a fresh Python process with MuJoCo and no sixplus3 code:
    from its 'home' keyframe, held by the keyframe's ctrl (the holding torques) for
    1 s, it stays assembled (closures <= 1e-4 m), the platform drifts <= 1 mm, nothing
    is NaN; actuators and actuated joints carry the robot's limits."""
    robot_file = tmp_path / "robot.yaml"
    robot_file.write_text(f"mounting: {mounting}\n")
    out = tmp_path / "robot.xml"
    res = CliRunner().invoke(main, ["--robot", str(robot_file), "robot", "export", "mjcf",
                                    "-o", str(out)])
    assert res.exit_code == 0, res.output
    run = subprocess.run([sys.executable, "-c", _HOLD, str(out)], capture_output=True,
                         text=True, timeout=300, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    got = json.loads(run.stdout)
    assert not got["sixplus3"] and got["finite"]
    assert got["gap"] <= 1e-4 and got["drift"] <= 1e-3, got
    lim = ROBOT.limits
    assert got["ctrlrange"] == [[-lim.torque, lim.torque]] * 9
    assert got["forcerange"] == [[-lim.torque, lim.torque]] * 9
    assert got["limited"] == [1] * 9
    assert got["range"] == [[lim.theta_min, lim.theta_max]] * 9


def test_mjcf_contacts_see_the_paper_legs_cross_and_the_default_free(tmp_path) -> None:
    """With contacts between legs, MuJoCo's own collision detection (no code shared
    with our clearance) finds the paper's stated assembly's legs in contact at home and
    none on the default robot."""
    seen = {}
    for name in ("default", "paper-as-stated"):
        out = tmp_path / f"{name}.xml"
        res = CliRunner().invoke(main, ["--robot", name, "robot", "export", "mjcf",
                                        "--contacts", "-o", str(out)])
        assert res.exit_code == 0, res.output
        m = mujoco.MjModel.from_xml_path(str(out))
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        mujoco.mj_forward(m, d)
        seen[name] = d.ncon
    assert seen["default"] == 0 and seen["paper-as-stated"] > 0, seen


def test_one_drive_loop_reads_counts_quantises_and_saturates() -> None:
    """control/drive/loop.py: the encoder reads whole counts, the command beyond the
    drive's limit is applied at the limit in whole torque units, the monitor reads what
    was applied, and the encoder's rate feedback is the difference over the tick."""
    from sixplus3.control.drive.loop import DriveLoop
    from sixplus3.kinematics.robot import home
    from sixplus3.robot_description.robot import Robot

    robot = Robot.default()
    h = home(robot)
    for feedback in ("plant", "encoder"):
        loop = DriveLoop(robot, 1000.0, 300.0, 6.0, torque_noise=0.0,
                         rate_feedback=feedback)
        loop.start(np.asarray(h.q[0]))
        th = loop.encoder()
        counts = th * loop.counts
        np.testing.assert_allclose(counts, np.rint(counts), atol=1e-6)
        assert np.abs(th - loop.true_angles()).max() <= 0.5 / loop.counts + 1e-12
        tick = loop.tick(th + 0.1, np.zeros(9), np.zeros(9))  # 30 N m asked per joint
        np.testing.assert_allclose(tick.command, 30.0, rtol=1e-6)
        np.testing.assert_allclose(np.abs(tick.applied), loop.cap, atol=loop.t_unit)
        assert np.all(np.abs(tick.applied) <= loop.cap + 1e-12)
        units = tick.applied / loop.t_unit
        np.testing.assert_allclose(units, np.rint(units), atol=1e-9)
        np.testing.assert_array_equal(loop.monitor(tick.applied), tick.applied)
        moved = loop.encoder() - th
        assert np.all(moved > 0)  # pushed toward the reference for one tick
        second = loop.tick(th, np.zeros(9), np.zeros(9), advance=False)
        if feedback == "encoder":  # the damping acts on the encoder's difference
            expected = 300.0 * (th - second.theta) - 6.0 * moved * 1000.0
            np.testing.assert_allclose(second.command, expected, rtol=1e-9, atol=1e-9)


def test_run_reads_then_steps_then_applies_and_a_fault_holds_the_drive() -> None:
    """control/drive/loop.run, the one loop: the controller gets the encoder's angles
    and the monitor's reading of the torque applied over the previous tick (the first
    tick: ``initial``); a ``fault`` command holds the drive where it is; ``final`` reads
    the last tick's torque; an ideal drive applies its command as asked."""
    from sixplus3.control.drive.command import DriveCommand, Mode
    from sixplus3.control.drive.loop import DriveLoop, run
    from sixplus3.kinematics.robot import home
    from sixplus3.robot_description.robot import Robot

    robot = Robot.default()
    q0 = np.asarray(home(robot).q[0])

    class Faulty:  # asks for a far reference, then faults with the same far reference
        def __init__(self) -> None:
            self.seen: list[tuple[np.ndarray, np.ndarray]] = []

        def step(self, theta: object, tau: object) -> DriveCommand:
            th, ta = np.array(theta), np.array(tau)
            self.seen.append((th, ta))
            mode = Mode.FAULT if len(self.seen) > 2 else Mode.HOLD
            return DriveCommand(th + 0.01, np.zeros(9), np.full(9, 0.5), mode, False,
                                np.zeros(6))

    loop = DriveLoop(robot, 1000.0, 300.0, 0.0, torque_noise=0.0)
    loop.start(q0)
    c = Faulty()
    out = run(loop, c, 5, initial=np.full(9, 0.25), final=True)
    np.testing.assert_array_equal(c.seen[0][1], np.full(9, 0.25))
    for k in range(1, 5):  # the reading of the previous tick's torque, as applied
        np.testing.assert_array_equal(c.seen[k][1], out.applied[k - 1])
        np.testing.assert_array_equal(c.seen[k][0], out.theta[k])
    np.testing.assert_array_equal(out.readings[5], out.applied[4])
    np.testing.assert_allclose(out.command[:2], 0.5 + 3.0, rtol=1e-9)  # Kp 300 x 0.01
    np.testing.assert_array_equal(out.command[2:], 0.5)  # a fault: the PD holds here
    # no initial torque: row 0 is not a reading; an ideal drive applies what it asks
    ideal = DriveLoop(robot, 1000.0, 300.0, 0.0, torque_noise=0.0, ideal=True)
    ideal.start(q0)
    out = run(ideal, Faulty(), 2)
    assert np.isnan(out.readings[0]).all() and np.isnan(out.readings[2]).all()
    np.testing.assert_array_equal(out.applied, out.command)
    with pytest.raises(InputError, match="ideal drive"):
        DriveLoop(robot, 1000.0, 300.0, 0.0, torque_noise=0.005, ideal=True)
