"""The explicit Robot: one frozen value that every part takes (and nothing else).

A non-default robot (l2 + 5 mm, a heavier platform) is pushed through every part: leg
and robot kinematics, the Pinocchio closed-loop model, the CasADi model (torques against
Pinocchio's), the validator and the trajectory files (refused for another robot).
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from sixplus3.cli import main as cli
from sixplus3.control.file.trajectory_file import write_trajectory
from sixplus3.control.file.trajectory_read import read_trajectory
from sixplus3.control.gate.validation import validate_file, validate_joint_trajectory
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.symbolic import symbolic_robot
from sixplus3.errors import GeometryError, LimitError, TrajectoryFileError
from sixplus3.kinematics.leg import leg_ik
from sixplus3.kinematics.robot import home, robot_ik
from sixplus3.kinematics.robot_fk import robot_fk
from sixplus3.motion import Motion
from sixplus3.robot_description import Limits, MassModel, Robot
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.urdf import robot_urdf

DEFAULT = Robot.default()
OTHER = DEFAULT.replace(
    geometry=replace(DEFAULT.geometry, leg=replace(DEFAULT.leg, l2=DEFAULT.leg.l2 + 0.005,
                                                    l3=DEFAULT.leg.l3 + 0.005)),
    masses=replace(DEFAULT.masses, platform=DEFAULT.masses.platform + 0.4),
    name="l2+5mm, heavy platform")


def test_robot_is_a_frozen_validated_value_with_a_stable_hash() -> None:
    r = Robot.default()
    assert r == DEFAULT and r.hash == DEFAULT.hash and len(r.hash) == 64
    with pytest.raises(AttributeError):
        r.mode = "----"  # type: ignore[misc]
    # the hash follows every parameter but the label
    assert OTHER.hash != DEFAULT.hash
    assert DEFAULT.replace(name="x").hash == DEFAULT.hash
    assert DEFAULT.replace(gravity=(0, 0, 9.81)).hash != DEFAULT.hash
    assert DEFAULT.replace(limits=Limits(torque=9.0)).hash != DEFAULT.hash
    assert DEFAULT.replace(mode="++++").hash != DEFAULT.hash
    assert DEFAULT.replace(geometry=replace(DEFAULT.geometry, axis_turn=0.0)).hash \
        != DEFAULT.hash
    assert DEFAULT.replace(collision=replace(DEFAULT.collision, hub_radius=0.02)).hash \
        != DEFAULT.hash
    # parameters round-trip through plain JSON
    doc = json.loads(json.dumps(OTHER.as_dict()))
    assert Robot.from_dict(doc) == OTHER and Robot.from_dict(doc).hash == OTHER.hash
    for bad, name in (({"geometry": {"leg": {"l2": -0.1}}}, "l2"),
                      ({"geometry": {"leg": {"l22": 0.1}}}, "l22"),
                      ({"masses": {"platform": float("nan")}}, "platform"),
                      ({"gravity": [0, 0, "down"]}, "gravity"),
                      ({"home_psi": [0, 90, 90]}, "home_psi"),
                      ({"limits": {"torque": float("inf")}}, "torque"),
                      ({"speed": 3}, "speed")):
        with pytest.raises((GeometryError, LimitError)) as err:
            Robot.from_dict(bad)
        assert name in str(err.value)


def test_limits_validate_themselves_and_only_tighten() -> None:
    for kw in ({"torque": float("nan")}, {"torque": 0.0}, {"velocity": -1.0},
               {"margin": 1.5}, {"theta_min": 2.0, "theta_max": 1.0}, {"torque": True}):
        with pytest.raises(LimitError):
            Limits(**kw)
    hw = DEFAULT.limits
    assert hw.tightened(torque=8.5).torque == 8.5 and hw.tightened(margin=0.1).margin == 0.1
    for kw in ({"torque": 10.5}, {"velocity": float("nan")}, {"acceleration": 0.0},
               {"margin": 0.01}, {"theta_max": 5.0}, {"spin": 1.0}):
        with pytest.raises(LimitError) as err:
            hw.tightened(**kw)
        name = next(iter(kw))
        assert err.value.name == name and err.value.valid


def test_every_cache_is_keyed_by_the_robot() -> None:
    assert symbolic_robot(DEFAULT) is symbolic_robot(Robot.default())
    assert symbolic_robot(OTHER) is not symbolic_robot(DEFAULT)
    assert robot_urdf(OTHER) != robot_urdf(DEFAULT)
    # the committed URDF is the default robot's
    from sixplus3.robot_description.generated import same_text
    from sixplus3.robot_description.urdf import URDF_PATH

    assert same_text(URDF_PATH.read_text(), robot_urdf(DEFAULT))


def test_the_caller_owns_its_pinocchio_objects() -> None:
    """Two ClosedLoopDynamics with different settings do not affect each other."""
    a = ClosedLoopDynamics(DEFAULT)
    q = home(DEFAULT).q[0]
    v = np.zeros(a.model.nv)
    tau = np.full(9, 0.5)
    before = a.forward_dynamics(q, v, tau).a
    b = ClosedLoopDynamics(DEFAULT, kp=1.0, kd=2.0)
    assert b.model is not a.model and b.data is not a.data and b.clm is not a.clm
    for cm_a, cm_b in zip(a.cmodels, b.cmodels, strict=True):
        assert (cm_a.m_baumgarte_parameters.Kp, cm_b.m_baumgarte_parameters.Kp) == (400, 1)
        assert (cm_a.m_baumgarte_parameters.Kd, cm_b.m_baumgarte_parameters.Kd) == (40, 2)
    b.model.armature[:] = 1.0  # mutating one model leaves the other alone
    np.testing.assert_array_equal(a.forward_dynamics(q, v, tau).a, before)
    arm = np.zeros(a.model.nv)
    arm[a.clm.idx_v_act] = DEFAULT.motors.armature  # the rotors, on the actuated joints
    np.testing.assert_array_equal(a.model.armature, arm)
    np.testing.assert_array_equal(closed_loop_model(DEFAULT).model.armature, arm)


def test_a_non_default_robot_reaches_every_part() -> None:
    # leg kinematics: the same P gives other crank angles with a longer crank
    cfg_o = home(OTHER)
    p_leg = OTHER.geometry.to_leg(0, cfg_o.P[0, 0])
    th_o = leg_ik(p_leg[None], OTHER.leg, OTHER.mode).theta[0]
    th_d = leg_ik(p_leg[None], DEFAULT.leg, DEFAULT.mode).theta[0]
    assert abs(th_o[1] - th_d[1]) > 1e-3
    np.testing.assert_allclose(cfg_o.theta[0, :3], th_o, atol=1e-12)
    # robot IK closes the loops of *its* model, not the default one
    clm_o, clm_d = closed_loop_model(OTHER), closed_loop_model(DEFAULT)
    assert np.abs(clm_o.residual(cfg_o.q[0])).max() < 1e-12
    assert np.abs(clm_d.residual(cfg_o.q[0])).max() > 1e-3
    assert clm_o.total_mass() == pytest.approx(clm_d.total_mass() + 0.4, abs=1e-12)
    # FK with its model recovers the pose
    fk = robot_fk(cfg_o.theta[0] + 0.01, OTHER)
    assert fk.residual < 1e-12 and not np.allclose(fk.position, cfg_o.position[0])
    # Pinocchio and CasADi torques agree for this robot, and differ from the default's
    sr = symbolic_robot(OTHER)
    dyn = ClosedLoopDynamics(OTHER)
    rng = np.random.default_rng(3)
    for _ in range(3):
        x = np.r_[rng.uniform(-0.04, 0.04, 2), rng.uniform(0.55, 0.62),
                  rng.uniform(-0.3, 0.3, 3), rng.uniform(1.2, 1.9, 3)]
        xd, xdd = rng.normal(scale=0.5, size=9), rng.normal(scale=5.0, size=9)
        cfg = robot_ik(x[0:3], Rotation.from_rotvec(x[3:6]).as_matrix(), x[6:9], OTHER)
        thd = np.array(sr.theta_dot(x, xd)).ravel()
        thdd = np.array(sr.theta_ddot(x, xd, xdd)).ravel()
        v, a = dyn.consistent_state(cfg.q[0], thd, thdd)
        tau_pin = dyn.inverse_dynamics(cfg.q[0], v, a)
        tau_cas = np.array(sr.tau(x, xd, xdd)).ravel()
        assert np.abs(tau_pin - tau_cas).max() < 1e-6
        tau_def = np.array(symbolic_robot(DEFAULT).tau(x, xd, xdd)).ravel()
        assert np.abs(tau_def - tau_cas).max() > 1e-3


def _slow_motion(robot: Robot, rate: float = 1000.0, duration: float = 0.4):
    """A rest-to-rest quintic from home to a small tilt and back, in minimal coordinates,
    sampled at ``rate``; actuated angles, rates and accelerations from robot's model."""
    sr = symbolic_robot(robot)
    t = np.arange(0.0, duration + 0.5 / rate, 1.0 / rate)
    s = t / duration
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    dblend = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    ddblend = (60 * s - 180 * s**2 + 120 * s**3) / duration**2
    x0 = np.r_[robot.home_position, 0.0, 0.0, 0.0, robot.home_psi]
    dx = np.r_[0.02, 0.0, 0.01, 0.15, 0.0, 0.0, 0.1, 0.0, 0.0]
    x = x0 + blend[:, None] * dx
    xd, xdd = dblend[:, None] * dx, ddblend[:, None] * dx
    n = len(t)
    th = np.array(sr.theta.map(n)(x.T)).T
    thd = np.array(sr.theta_dot.map(n)(x.T, xd.T)).T
    thdd = np.array(sr.theta_ddot.map(n)(x.T, xd.T, xdd.T)).T
    return t, th, thd, thdd, x


def test_a_file_for_one_robot_is_refused_for_another(tmp_path) -> None:
    t, th, thd, thdd, x = _slow_motion(OTHER)
    rep = validate_joint_trajectory(Motion(t, th, thd, thdd, 1000.0), OTHER, x)
    assert rep.ok, rep.violations
    csv = write_trajectory(tmp_path / "other.csv", Motion(t, th, thd, thdd, rep.rate_hz), rep,
                           OTHER, OTHER.limits, {"rate_hz": 1000.0})
    header, _ = read_trajectory(csv, OTHER)
    assert header["robot"]["hash"] == OTHER.hash
    assert Robot.from_dict(header["robot"]["parameters"]) == OTHER
    assert validate_file(csv, OTHER).ok
    with pytest.raises(TrajectoryFileError, match="robot mismatch") as err:
        validate_file(csv, DEFAULT)
    assert "l2" in str(err.value) or "l3" in str(err.value)
    # the command line: refused for the default robot (2), accepted with --robot (0)
    r = CliRunner().invoke(cli, ["validate", str(csv)])
    assert r.exit_code == 2 and "robot mismatch" in r.output
    robot_file = tmp_path / "robot.json"
    robot_file.write_text(json.dumps(OTHER.as_dict()))
    r = CliRunner().invoke(cli, ["--robot", str(robot_file), "validate", str(csv)])
    assert r.exit_code == 0, r.output
    # the validator uses the robot it is given: the motion is checked with its dynamics
    heavy = OTHER.replace(masses=MassModel(platform=30.0))
    rep_heavy = validate_joint_trajectory(Motion(t, th, thd, thdd, 1000.0), heavy, x)
    assert rep_heavy.max_torque_ratio > 1.5 * rep.max_torque_ratio


def test_ceiling_mounting_flips_the_gravity_torques() -> None:
    """Static torques are linear in gravity: a ceiling mount (gravity +z in the robot
    frame) holds the same configuration with exactly the opposite torques, in Pinocchio
    and in the CasADi model."""
    ceiling = Robot.mounted("ceiling")
    assert ceiling.gravity == (0.0, 0.0, 9.81) and ceiling.hash != DEFAULT.hash
    q = robot_ik((0.02, -0.01, 0.59), Rotation.from_euler("x", 0.2).as_matrix(),
                 None, DEFAULT).q[0]
    tau_floor = ClosedLoopDynamics(DEFAULT).gravity_torques(q)
    tau_ceiling = ClosedLoopDynamics(ceiling).gravity_torques(q)
    assert np.abs(tau_floor).max() > 0.1
    np.testing.assert_allclose(tau_ceiling, -tau_floor, atol=1e-12)
    x = np.r_[0.02, -0.01, 0.31, 0.2, 0, 0, np.array(DEFAULT.home_psi)]
    z = np.zeros(9)
    np.testing.assert_allclose(np.array(symbolic_robot(ceiling).tau(x, z, z)).ravel(),
                               -np.array(symbolic_robot(DEFAULT).tau(x, z, z)).ravel(),
                               atol=1e-9)
    with pytest.raises(GeometryError):
        Robot.mounted("wall")


def test_robot_show_output_is_the_robot_file_format(tmp_path) -> None:
    path = tmp_path / "robot.json"
    r = CliRunner().invoke(cli, ["robot", "show", "--json"])
    assert r.exit_code == 0
    doc = json.loads(r.output)
    doc_hash = doc.pop("hash")
    assert doc_hash == DEFAULT.hash
    doc["limits"]["torque"] = 8.0
    path.write_text(json.dumps(doc))
    r = CliRunner().invoke(cli, ["--robot", str(path), "robot", "check", "--json"])
    checked = json.loads(r.output)
    # a lower torque limit shrinks the 2 g COW (20.6 L at 10 N m); exit 1 only when home
    # is outside it
    at10 = json.loads(CliRunner().invoke(cli, ["robot", "check", "--json"]).output)
    assert 0.0 < checked["home_in_cow"]["volume_l"] < at10["home_in_cow"]["volume_l"]
    assert r.exit_code == (0 if checked["home_in_cow"]["inside"] else 1), r.output
    assert checked["robot_hash"] == DEFAULT.replace(limits=Limits(torque=8.0)).hash
    path.write_text('{"geometry": {"leg": {"l2": "long"}}}')
    r = CliRunner().invoke(cli, ["--robot", str(path), "robot", "check"])
    assert r.exit_code == 2 and "l2" in r.output and "Traceback" not in r.output
    # the refused file changed nothing: the default robot is the one read back above
    assert Robot.default().hash == DEFAULT.hash == doc_hash


def test_a_plan_for_a_non_default_robot_is_refused_for_the_default(tmp_path,
                                                                    monkeypatch) -> None:
    """Planned end to end for OTHER (interpreted: no compile for a one-off robot), the
    file validates for OTHER and is refused for the default robot."""
    from sixplus3.cache import BoundedCache
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner import solvers
    from sixplus3.planner.options import PlannerOptions
    from sixplus3.planner.task import task_from_dict

    monkeypatch.setenv("SIXPLUS3_NO_CODEGEN", "1")
    monkeypatch.setattr(solvers, "SOLVERS", BoundedCache(4))
    home_p = list(OTHER.home_position)
    task = task_from_dict({"name": "other", "nodes_per_segment": 4, "waypoints": [
        {"position": home_p}, {"position": [home_p[0] + 0.02, home_p[1], home_p[2]]}]})
    res = run_plan(task, tmp_path, OTHER, html=False, plots=False,
                   options=PlannerOptions(lock_redundancy=True))
    assert res.solution.robot == OTHER and validate_file(res.csv, OTHER).ok
    with pytest.raises(TrajectoryFileError, match="robot mismatch"):
        validate_file(res.csv, DEFAULT)
