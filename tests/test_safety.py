"""Power and force limiting (docs/safety.md): ISO/TS 15066's body regions as data, the
robot's effective mass at the platform point cross-checked against MuJoCo, the worst
direction's contact energy in closed form against a search over directions."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.effective_mass import (
    contact_energy,
    effective_mass,
    pfl_ratio,
    point_inverse_mass,
    worst_speed,
)
from sixplus3.errors import InputError
from sixplus3.kinematics.robot import home, robot_ik_pose
from sixplus3.robot_description.body_regions import REGIONS, regions
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()


def test_the_regions_of_the_standard() -> None:
    assert list(REGIONS) == ["skull", "face", "neck", "back", "chest", "abdomen", "pelvis",
                             "upper_arm", "lower_arm", "hand", "thigh", "lower_leg"]
    hand = REGIONS["hand"]
    assert (hand.mass, hand.stiffness, hand.force, hand.transient_force) == (
        0.6, 75e3, 140.0, 280.0)
    assert REGIONS["face"].transient_force == REGIONS["face"].force == 65.0
    assert [r.name for r in regions("chest, hand")] == ["chest", "hand"]
    assert [r.name for r in regions(["hand", "hand"])] == ["hand"]
    assert regions(None) == () and regions("") == ()
    with pytest.raises(InputError, match="unknown body region 'elbow'"):
        regions("hand,elbow")
    with pytest.raises(InputError, match="list of body region names"):
        regions(3)  # type: ignore[arg-type]
    # a clamped region: backed by a wall, its mass infinite (the robot's alone remains)
    (hc,) = regions("hand-clamped")
    assert hc.name == "hand-clamped" and hc.mass == np.inf and hc.force == hand.force
    assert hc.speed_limit(0.7) == pytest.approx(280 / np.sqrt(0.7 * 75e3))
    assert [r.name for r in regions("hand-clamped,hand")] == ["hand", "hand-clamped"]
    # the two-body model's speed: F / sqrt(mu k); the energy F^2 / 2k is what it holds
    mu = 1 / (1 / 0.7 + 1 / 0.6)
    assert hand.speed_limit(0.7) == pytest.approx(280 / np.sqrt(mu * 75e3))
    assert 0.5 * mu * hand.speed_limit(0.7) ** 2 == pytest.approx(hand.energy)


def _poses(robot: Robot):
    return [home(robot),
            robot_ik_pose(np.add(robot.home_position, [0.03, -0.02, 0.02]), (0.2, -0.1, 0.3),
                          robot.home_psi, robot=robot),
            robot_ik_pose(np.add(robot.home_position, [-0.04, 0.03, -0.03]),
                          (-0.25, 0.15, -0.2), np.add(robot.home_psi, [0.4, -0.3, 0.2]),
                          robot=robot)]


@pytest.mark.parametrize("tool", [(0.0, 0.0, 0.0), (0.03, -0.02, 0.08)], ids=["centre", "tcp"])
def test_the_effective_mass_equals_mujocos_impulse_response(tool) -> None:
    """An impulse at the platform point in MuJoCo (its own mass matrix and closures; the
    motors' torques held at gravity's; no friction, which would hold the joints, not be
    part of the mass): m = impulse / dv along u, at three poses, along x, y, z and a
    skew direction, against 1 / (u^T A u) from Pinocchio and the IK Jacobian."""
    mujoco = pytest.importorskip("mujoco")
    from sixplus3.control.drive.mujoco_model import MujocoRobot
    from sixplus3.robot_description.physical import Tool

    robot = ROBOT.replace(tool=Tool(xyz=tool)) if any(tool) else ROBOT
    dyn = ClosedLoopDynamics(robot)
    frictionless = robot.replace(motors=replace(robot.motors, viscous=0.0, coulomb=0.0))
    sim = MujocoRobot(frictionless)
    m, d = sim.model, sim.data
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "platform_free")
    assert body >= 0
    impulse, T = 0.02, 0.002
    steps = int(round(T / m.opt.timestep))

    def measured(q: np.ndarray, u: np.ndarray) -> float:
        vel = []
        for push in (0.0, 2 * impulse / T):  # the force acts over the first half
            sim.set_state(q, np.zeros(9))
            d.ctrl[:] = dyn.gravity_torques(q)
            for k in range(steps):
                point = d.xpos[body] + d.xmat[body].reshape(3, 3) @ np.asarray(tool)
                d.xfrc_applied[:] = 0.0
                if k < steps // 2:
                    f = push * u
                    d.xfrc_applied[body, :3] = f
                    d.xfrc_applied[body, 3:] = np.cross(point - d.xipos[body], f)
                mujoco.mj_step(m, d)
            point = d.xpos[body] + d.xmat[body].reshape(3, 3) @ np.asarray(tool)
            jac = np.zeros((3, m.nv))
            mujoco.mj_jac(m, d, jac, None, point, body)
            vel.append(jac @ d.qvel)
        d.xfrc_applied[:] = 0.0
        return impulse / float((vel[1] - vel[0]) @ u)

    dirs = [*np.eye(3), np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])]
    for cfg in _poses(robot):
        A = point_inverse_mass(dyn, cfg)
        for u in dirs:
            ours = float(effective_mass(A, u)[0])
            assert measured(cfg.q[0], u) == pytest.approx(ours, rel=0.01), (u, ours)
    # at home: 0.70 kg horizontally, 1.47 kg vertically, rotors included
    if not any(tool):
        A = point_inverse_mass(dyn, home(robot))
        assert effective_mass(A, [1, 0, 0])[0] == pytest.approx(0.698, abs=0.002)
        assert effective_mass(A, [0, 0, 1])[0] == pytest.approx(1.472, abs=0.002)


def test_the_worst_direction_in_closed_form() -> None:
    """1/2 v^T (A + I/m_H)^-1 v is the largest energy over every contact normal: a dense
    search over directions never exceeds it and comes within 0.1 % of it; a hand's
    worst-direction speed at home is the vertical one (1.57 m/s: the heavier axis)."""
    dyn = ClosedLoopDynamics(ROBOT)
    rng = np.random.default_rng(3)
    n = rng.normal(size=(20000, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    for cfg in _poses(ROBOT):
        A = point_inverse_mass(dyn, cfg)
        for region in (REGIONS["hand"], REGIONS["chest"], REGIONS["face"]):
            v = rng.normal(size=3)
            m_n = effective_mass(np.broadcast_to(A[0], (len(n), 3, 3)), n)
            mu = 1 / (1 / m_n + 1 / region.mass)
            search = (0.5 * mu * (n @ v) ** 2).max()
            closed = float(contact_energy(A, v[None], region)[0])
            assert search <= closed * (1 + 1e-12) and search >= closed * 0.999
            # at the worst speed along the worst direction the ratio is exactly 1
            w, vec = np.linalg.eigh(A[0] + np.eye(3) / region.mass)
            s = float(worst_speed(A, region)[0])
            ratio, _ = pfl_ratio(A, (s * vec[:, 0])[None], [region])
            assert ratio[0] == pytest.approx(1.0, rel=1e-9)
    A = point_inverse_mass(dyn, home(ROBOT))
    assert worst_speed(A, REGIONS["hand"])[0] == pytest.approx(1.566, abs=0.002)


# ----------------------------------------------------------------- PFL in plans and the gate
@pytest.fixture(scope="module")
def plans(tmp_path_factory):
    """A 12 cm move along x, planned free, for a hand and for the face (nodes kept few:
    fast)."""
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.task import task_from_dict

    out = tmp_path_factory.mktemp("pfl")
    doc = {"name": "move", "nodes_per_segment": 6, "waypoints": [
        {"position": [-0.06, 0.0, 0.58]}, {"position": [0.06, 0.0, 0.58]}]}
    free = run_plan(task_from_dict(doc), out / "free", ROBOT, html=False, plots=False)
    hand = run_plan(task_from_dict({**doc, "pfl": ["hand"]}), out / "hand", ROBOT,
                    html=False, plots=False)
    face = run_plan(task_from_dict({**doc, "pfl": ["face"]}), out / "face", ROBOT,
                    html=False, plots=False)
    # along y, for the platform only: a leg's spherical joint moves too fast for a hand
    along_y = {**doc, "name": "move_y", "pfl": ["hand"], "pfl_links": [], "waypoints": [
        {"position": [0.0, -0.06, 0.58]}, {"position": [0.0, 0.06, 0.58]}]}
    platform = run_plan(task_from_dict(along_y), out / "platform", ROBOT, html=False,
                        plots=False)
    return free.csv, hand.csv, face.csv, platform.csv


def test_the_legs_are_judged_unless_a_task_drops_them_and_a_site_can_require_them(
        plans, tmp_path) -> None:
    """The hand plan holds at every reachable leg link's vertices too (the default); a
    plan for the platform only (``pfl_links: []``) moves a leg too fast for a hand.  Its
    file passes for what it says, but the gate refuses its motion when written for a
    hand without naming links, and the file itself under a site that requires the
    legs (issue 70: the gate refuses a file whose leg speed breaks a required region)."""
    from click.testing import CliRunner

    from sixplus3.cli import main as cli
    from sixplus3.control.file.trajectory_read import read_trajectory
    from sixplus3.control.gate.validation import validate_and_write, validate_file
    from sixplus3.errors import ValidationFailed
    from sixplus3.kinematics.rotations import rotvec_from_quat

    hand, platform = validate_file(plans[1], ROBOT), validate_file(plans[3], ROBOT)
    assert hand.ok and len(hand.pfl_links) == 18 and hand.header["pfl_links"][0] == \
        "leg0_proximal"
    assert platform.ok and platform.pfl_links == () and platform.header["pfl_links"] == []
    assert platform.max_pfl_where in ("tcp", "centre")
    tr = read_trajectory(plans[3], ROBOT)
    x = np.c_[tr.platform_position, rotvec_from_quat(tr.platform_quaternion), tr.psi]
    with pytest.raises(ValidationFailed) as err:
        validate_and_write(tmp_path / "x.csv", tr.motion, ROBOT, x, meta={"pfl": ["hand"]})
    rep = err.value.report
    assert err.value.exit_code == 1 and rep.max_pfl_ratio > 1.0
    assert rep.max_pfl_where.startswith("leg") and not (tmp_path / "x.csv").exists()
    site = tmp_path / "site.yaml"
    site.write_text("pfl_links: [legs]\n")
    res = CliRunner().invoke(cli, ["--hardware", str(site), "validate", str(plans[3])])
    assert res.exit_code == 1 and "pfl hand" in res.output and " on leg" in res.output, \
        res.output
    ok = CliRunner().invoke(cli, ["--hardware", str(site), "validate", str(plans[1])])
    assert ok.exit_code == 0, ok.output


def test_a_pfl_plan_holds_the_limit_and_says_so(plans) -> None:
    from sixplus3.control.gate.validation import validate_file

    free, hand, face = (validate_file(p, ROBOT) for p in plans[:3])
    assert free.ok and free.pfl == () and free.max_pfl_ratio is None
    assert hand.ok and hand.pfl == ("hand",) and hand.max_pfl_ratio <= 1.0
    assert face.ok and face.pfl == ("face",) and face.max_pfl_ratio <= 1.0
    assert hand.header["pfl"] == ["hand"] and face.header["pfl"] == ["face"]
    # the face (65 N, no transient contact) needs a far slower plan than the hand
    assert face.duration > 2.0 * hand.duration >= 2.0 * free.duration
    # the free plan is faster than a hand allows (the next tests: its file breaks it)
    assert free.max_tcp_speed > 1.8 > hand.max_tcp_speed


def test_the_gate_refuses_a_file_that_names_a_set_and_breaks_it(plans, tmp_path) -> None:
    from sixplus3.control.file.trajectory_read import read_trajectory
    from sixplus3.control.gate.validation import validate_and_write
    from sixplus3.errors import ValidationFailed
    from sixplus3.kinematics.rotations import rotvec_from_quat

    tr = read_trajectory(plans[0], ROBOT)
    x = np.c_[tr.platform_position, rotvec_from_quat(tr.platform_quaternion), tr.psi]
    args = (tr.motion, ROBOT, x)
    with pytest.raises(ValidationFailed) as err:
        validate_and_write(tmp_path / "x.csv", *args, meta={"pfl": ["hand"]})
    assert err.value.exit_code == 1 and "pfl hand" in str(err.value)
    assert not (tmp_path / "x.csv").exists()
    path, rep = validate_and_write(tmp_path / "y.csv", *args)  # names no set: written
    assert rep.ok and path.exists()


def test_a_site_requires_regions_no_file_can_drop(plans, tmp_path) -> None:
    from click.testing import CliRunner

    from sixplus3.cli import main as cli
    from sixplus3.robot_description import hardware

    site = tmp_path / "site.yaml"
    site.write_text("pfl: [face]\n")
    try:
        res = CliRunner().invoke(cli, ["--hardware", str(site), "validate", str(plans[1])])
        assert res.exit_code == 1 and "pfl face" in res.output, res.output
        ok = CliRunner().invoke(cli, ["--hardware", str(site), "validate", str(plans[2])])
        assert ok.exit_code == 0, ok.output
        bad = tmp_path / "bad.yaml"
        bad.write_text("pfl: [elbow]\n")
        res = CliRunner().invoke(cli, ["--hardware", str(bad), "validate", str(plans[2])])
        assert res.exit_code == 2 and "hardware.pfl" in res.output
    finally:
        hardware.use(None)


def test_a_site_that_declares_its_loop_is_judged_and_planned_with_it(plans, tmp_path
                                                                   ) -> None:
    """A site with a stiff position loop (docs/safety.md, "The drive in the contact"):
    the hand plan made without it is judged harder; planned for the site, the plan is
    no faster and holds the limit with the loop in it; validate --json names the loop."""
    import json

    from click.testing import CliRunner

    from sixplus3.cli import main as cli
    from sixplus3.control.gate.validation import validate_file
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.task import task_from_dict
    from sixplus3.robot_description import hardware

    held = validate_file(plans[1], ROBOT)
    site = tmp_path / "stiff.yaml"
    site.write_text("position_loop: {kp: 3000, kd: 30}\n")
    try:
        hardware.use(hardware.load_hardware(site))
        stiff = validate_file(plans[1], ROBOT)
        assert stiff.max_pfl_ratio > held.max_pfl_ratio
        doc = {"name": "move", "nodes_per_segment": 6, "pfl": ["hand"], "waypoints": [
            {"position": [-0.06, 0.0, 0.58]}, {"position": [0.06, 0.0, 0.58]}]}
        out = run_plan(task_from_dict(doc), tmp_path / "stiff", ROBOT, html=False,
                       plots=False)
        mine = validate_file(out.csv, ROBOT)
        assert mine.ok and mine.max_pfl_ratio <= 1.0
        assert mine.duration >= held.duration
        res = CliRunner().invoke(cli, ["--hardware", str(site), "validate", "--json",
                                       str(out.csv)])
        assert res.exit_code == 0, res.output
        assert json.loads(res.output)["envelope"]["position_loop"] == {"kp": 3000.0,
                                                                       "kd": 30.0}
    finally:
        hardware.use(None)


def test_the_gates_ratio_is_bounded_by_the_directional_and_isotropic_forms(plans) -> None:
    """The gate's worst-direction ratio, recomputed here sample by sample, lies between
    the two-body model along the direction of motion (a lower bound: one direction of
    all) and the isotropic bound |v|^2 / v_worst^2 (an upper bound: the worst direction
    at the worst speed)."""
    from sixplus3.control.file.file_format import columns
    from sixplus3.control.gate.validation import validate_file
    from sixplus3.kinematics.robot import robot_ik
    from sixplus3.kinematics.rotations import matrix_from_quat
    from sixplus3.kinematics.tcp import tcp_velocity

    rep = validate_file(plans[0], ROBOT)
    tr_v = columns(rep.data, "vel")
    cfg = robot_ik(rep.position, matrix_from_quat(rep.quaternion), rep.psi, ROBOT,
                   platform_margins=False)
    A = point_inverse_mass(ClosedLoopDynamics(ROBOT), cfg)
    v = tcp_velocity(cfg, tr_v)
    hand = REGIONS["hand"]
    ratio, _ = pfl_ratio(A, v, [hand])
    speed = np.linalg.norm(v, axis=1)
    moving = speed > 1e-3
    m_v = effective_mass(A[moving], v[moving])
    directional = (speed[moving] / np.array([hand.speed_limit(m) for m in m_v])) ** 2
    isotropic = (speed / worst_speed(A, hand)) ** 2
    assert np.all(ratio[moving] >= directional * (1 - 1e-9))
    assert np.all(ratio <= isotropic * (1 + 1e-9))
    assert ratio.max() > 1.0  # the free plan is too fast for a hand


def test_the_nlp_rows_matrix_is_the_gates_worst_direction_energy() -> None:
    """The planner's C_k (planner/pfl.py: from the eigenvectors of A) against the gate's
    closed form (dynamics/effective_mass.py: a linear solve), independently: for one
    region v^T C v is the contact energy over its limit exactly; for a set it bounds every
    region's and equals the worst one along A's principal directions.  At the TCP of a
    tool too."""
    from sixplus3.kinematics.rotations import rotvec_from_matrix
    from sixplus3.planner.pfl import pfl_matrices

    rng = np.random.default_rng(5)
    for robot in (ROBOT, ROBOT.replace(tool=ROBOT.tool.__class__(xyz=(0.02, -0.03, 0.12)))):
        dyn = ClosedLoopDynamics(robot)
        for cfg in _poses(robot):
            x = np.c_[cfg.position, rotvec_from_matrix(cfg.rotation), cfg.psi]
            A = point_inverse_mass(dyn, cfg)
            v = rng.normal(size=(1, 3))
            for name in ("hand", "chest", "face", "hand-clamped"):
                r = regions([name])[0]
                C = pfl_matrices(robot, x, (r,))
                got = float(v[0] @ C[0] @ v[0])
                want = float(contact_energy(A, v, r)[0]) / r.energy
                assert got == pytest.approx(want, rel=1e-9)
            regs = regions(["hand", "chest", "lower_arm"])
            C = pfl_matrices(robot, x, regs)
            each, _ = pfl_ratio(A, v, list(regs))
            assert float(v[0] @ C[0] @ v[0]) >= each[0] * (1 - 1e-12)
            for u in np.linalg.eigh(A[0])[1].T:
                each, _ = pfl_ratio(A, u[None], list(regs))
                assert float(u @ C[0] @ u) == pytest.approx(each[0], rel=1e-9)


def test_pfl_rows_plan_as_fast_as_the_limit_allows(plans) -> None:
    """The rows are direction-aware: the hand plan's gate ratio comes close to 1 (the
    rows bind, at their share 0.9025 of the limit), and its top speed exceeds what an
    isotropic speed bound (the worst direction's speed, at the plan's own poses) allows."""
    from sixplus3.control.gate.validation import validate_file
    from sixplus3.kinematics.robot import robot_ik
    from sixplus3.kinematics.rotations import matrix_from_quat

    rep = validate_file(plans[1], ROBOT)
    assert 0.85 <= rep.max_pfl_ratio <= 1.0
    cfg = robot_ik(rep.position, matrix_from_quat(rep.quaternion), rep.psi, ROBOT,
                   platform_margins=False)
    isotropic = float(worst_speed(point_inverse_mass(ClosedLoopDynamics(ROBOT), cfg),
                                  REGIONS["hand"]).min())
    assert rep.max_tcp_speed > 1.03 * isotropic


def test_under_a_tool_the_rows_and_the_gate_hold_the_centre_too(tmp_path) -> None:
    """A tool 12 cm off the centre: a person can meet the platform's body as well as the
    tool.  The NLP has rows at both points (planner/pfl.py: pfl_points) and the gate
    judges both; here the gate's ratio is recomputed point by point, independently (the
    platform twist from the IK Jacobian, A at each point), and both are within the
    limit, the gate's the larger of the two."""
    from sixplus3.control.file.file_format import columns
    from sixplus3.control.pipeline import run_plan
    from sixplus3.kinematics.robot import robot_ik
    from sixplus3.kinematics.robot_fk import ik_jacobian
    from sixplus3.kinematics.rotations import matrix_from_quat
    from sixplus3.planner.pfl import pfl_points
    from sixplus3.planner.task import task_from_dict

    doc = {"name": "tool", "nodes_per_segment": 6, "pfl": ["hand"],
           "setup": {"tool": {"xyz": [0.0, 0.0, 0.12], "rpy": [0, 0, 0]}},
           "waypoints": [{"position": [-0.05, 0.0, 0.58]},
                         {"position": [0.05, 0.0, 0.58], "rpy": [0, 15, 0]}]}
    task = task_from_dict(doc)
    res = run_plan(task, tmp_path, ROBOT, html=False, plots=False)
    robot = task.robot_for(ROBOT)
    assert len(pfl_points(robot)) == 2
    from sixplus3.control.gate.validation import validate_file

    rep = validate_file(res.csv, robot)
    assert rep.ok and rep.max_pfl_ratio is not None and rep.max_pfl_ratio <= 1.0
    cfg = robot_ik(rep.position, matrix_from_quat(rep.quaternion), rep.psi, robot,
                   platform_margins=False)
    twist = np.linalg.solve(ik_jacobian(cfg), columns(rep.data, "vel")[:, :, None])[:, :, 0]
    dyn = ClosedLoopDynamics(robot)
    each = []
    for point in ((0.0, 0.0, 0.12), (0.0, 0.0, 0.0)):
        r = np.einsum("nij,j->ni", cfg.rotation, np.asarray(point))
        v = twist[:, 0:3] + np.cross(twist[:, 3:6], r)
        ratio, _ = pfl_ratio(point_inverse_mass(dyn, cfg, point=point), v, [REGIONS["hand"]])
        each.append(float(ratio.max()))
    assert max(each) <= 1.0
    assert rep.max_pfl_ratio == pytest.approx(max(each), rel=1e-9)


def test_a_leg_links_effective_mass_is_mujocos_impulse_response() -> None:
    """Issue 70, item 2: a leg link's effective mass with the motors' torques held
    (dynamics/effective_mass.link_inverse_mass: Pinocchio's joint Jacobian shifted to
    the point, the closures' G, the reduced inertia with rotors) against MuJoCo's: a
    force held 0.5 ms at the link's centre of mass, the motors at gravity's torques, the
    velocity change minus the same run without the force.  MuJoCo's joint friction is
    off for this (dry friction resists a small push: with it on, 5 N met 10-40 % more
    mass). Three poses, four links (a crank, the RU chain, the RUS rods), three
    directions each: within 0.5 %."""
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.mujoco_model import MujocoRobot
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.dynamics.effective_mass import link_inverse_mass
    from sixplus3.kinematics import rotations as rot
    from sixplus3.kinematics.robot import robot_ik

    robot = Robot.default()
    dyn = ClosedLoopDynamics(robot)
    h, steps, force = 1e-4, 5, 5.0
    sim = MujocoRobot(robot, h)
    mj, m, d = sim.mj, sim.model, sim.data
    m.dof_frictionloss[:] = 0.0
    m.dof_damping[:] = 0.0
    rng = np.random.default_rng(70)
    poses = [(np.zeros(3), np.zeros(3), np.zeros(3))] + [
        (rng.uniform(-0.04, 0.04, 3), rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.4, 0.4, 3))
        for _ in range(2)]
    for dp, rv, dpsi in poses:
        cfg = robot_ik(np.asarray(robot.home_position) + dp, rot.matrix_from_rotvec(rv),
                       np.asarray(robot.home_psi) + dpsi, robot)
        assert cfg.ok.all()
        q = cfg.q[0]
        g = dyn.gravity_torques(q)
        for link in ("leg0_Ds2", "leg0_Gb", "leg1_A", "leg2_Hb"):
            body = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, link)
            sim.set_state(q, np.zeros(9))
            A = link_inverse_mass(dyn, q, link, np.array(d.xipos[body]))
            for u in np.eye(3):
                vel = []
                for f in (np.zeros(3), force * u):
                    sim.set_state(q, np.zeros(9))
                    d.ctrl[:] = g
                    for _ in range(steps):
                        d.xfrc_applied[body, :3] = f
                        d.xfrc_applied[body, 3:] = 0.0
                        mj.mj_step(m, d)
                    d.xfrc_applied[body] = 0.0
                    jac = np.zeros((3, m.nv))
                    mj.mj_jac(m, d, jac, None, np.array(d.xipos[body]), body)
                    vel.append(jac @ d.qvel)
                m_mujoco = force * h * steps / float(u @ (vel[1] - vel[0]))
                m_pin = 1.0 / float(u @ A @ u)
                assert m_mujoco == pytest.approx(m_pin, rel=5e-3), (link, u, m_pin, m_mujoco)


def test_a_forged_header_cannot_drop_the_legs_or_name_a_knee(plans, tmp_path) -> None:
    """The platform-only plan's header, forged with its digest recomputed: without its
    ``pfl_links`` the file is judged at every leg link (exit 1, at a leg); with a link
    that does not exist, or not a list, it is refused as a file (exit 2)."""
    from sixplus3.control.file.trajectory_file import encode
    from sixplus3.control.file.trajectory_parse import parse
    from sixplus3.control.file.trajectory_read import read_bytes
    from sixplus3.control.gate.validation import validate_file
    from sixplus3.errors import TrajectoryFileError

    header, data = parse(read_bytes(plans[3]), "platform")
    dropped = {k: v for k, v in header.items() if k not in ("pfl_links", "digest")}
    path = tmp_path / "dropped.csv"
    path.write_bytes(encode(dropped, data))
    rep = validate_file(path, ROBOT)
    assert rep.exit_code == 1 and rep.max_pfl_where.startswith("leg"), rep.messages()
    for bad in (["knee"], "legs", [3]):
        forged = tmp_path / "bad.csv"
        forged.write_bytes(encode({**dropped, "pfl_links": bad}, data))
        with pytest.raises(TrajectoryFileError, match="pfl_links"):
            validate_file(forged, ROBOT)
