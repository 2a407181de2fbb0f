"""Robot description: generated URDF + closures, loading in yourdfpy and Pinocchio."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yourdfpy

from sixplus3.errors import GeometryError, InputError
from sixplus3.motion import Motion
from sixplus3.robot_description import generated
from sixplus3.robot_description import urdf as gen
from sixplus3.robot_description.masses import POINT_MASS, MassModel
from sixplus3.robot_description.model import closed_loop_model, load_model_from, parse_closures
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.robot_geometry import RobotGeometry
from sixplus3.robot_description.urdf import robot_urdf


def test_committed_files_match_the_generator() -> None:
    assert generated.check() == [], "run: python -m sixplus3.robot_description.generated"
    assert generated.main(["--check"]) == 0


def test_generated_numbers_do_not_depend_on_the_last_bit() -> None:
    """A fresh machine's numpy wrote 0.07059999999999998 where the committed file has
    0.0706: the generator writes a stated precision and the check compares numbers."""
    assert gen._f(0.07059999999999998) == gen._f(0.0706) == "0.0706"
    assert gen._f(-0.0) == "0" and gen._f(1e-20) == "1e-20"
    text = gen.URDF_PATH.read_text()
    nudged = text.replace('"0.0706"', '"0.07059999999999998"')
    assert nudged != text and generated.same_text(text, nudged)
    # a real change is still seen: a number, a name, a missing number
    assert not generated.same_text(text, text.replace('"0.0706"', '"0.0707"'))
    assert not generated.same_text(text, text.replace("leg0_A", "leg0_X"))
    assert not generated.same_text('xyz="1 2 3"', 'xyz="1 2"')


def test_urdf_validates_in_yourdfpy() -> None:
    for path in (gen.URDF_PATH, gen.POINT_MASS_URDF_PATH):
        robot = yourdfpy.URDF.load(str(path))
        assert robot.validate()
        names = {j.name for j in robot.robot.joints}
        assert set(gen.actuated_joint_names()) <= names
        # 27 leg revolute joints + 3 platform cranks + the floating platform
        assert len(robot.actuated_joints) == 31
        for name in gen.actuated_joint_names():
            lim = robot.joint_map[name].limit
            assert (lim.lower, lim.upper, lim.effort) == (0.0, 1.5 * math.pi, 10.0)


def test_pybullet_and_mujoco_importers_get_the_robots_mass() -> None:
    """Other tools' URDF importers weigh the robot as Pinocchio does (1.89 kg with the
    default masses): every massless link states a zero <inertial>, so PyBullet does not
    give it its default 1 kg (the 22 frame links once made it 23.9 kg there)."""
    import mujoco
    import pybullet

    want = closed_loop_model(Robot.default()).total_mass()
    assert want == pytest.approx(1.89, abs=1e-9)
    cid = pybullet.connect(pybullet.DIRECT)
    try:
        body = pybullet.loadURDF(str(gen.URDF_PATH), useFixedBase=True, physicsClientId=cid)
        links = range(-1, pybullet.getNumJoints(body, physicsClientId=cid))
        masses = [pybullet.getDynamicsInfo(body, j, physicsClientId=cid)[0] for j in links]
    finally:
        pybullet.disconnect(cid)
    assert len(masses) == 54 and 1.0 not in masses
    assert sum(masses) == pytest.approx(want, abs=1e-9)
    model = mujoco.MjModel.from_xml_path(str(gen.URDF_PATH))
    assert model.body_mass.sum() == pytest.approx(want, abs=1e-9)


def test_pinocchio_model_dimensions_and_closures() -> None:
    clm = closed_loop_model(Robot.default())
    m = clm.model
    assert (m.nq, m.nv) == (37, 36)  # free-flyer platform (7/6) + 30 revolute joints
    assert clm.actuated_names == gen.actuated_joint_names()
    assert len(clm.constraint_models) == 9
    assert all(cm.residualSize() == 3 for cm in clm.constraint_models)
    assert clm.n_constraints == 27 and clm.mobility == 9
    pairs, types, mot = parse_closures(gen.CLOSURES_PATH)
    assert pairs == gen.closure_pairs() and types == ["3d"] * 9 and len(mot) == 9


def test_masses_match_the_mass_model() -> None:
    total = closed_loop_model(Robot.default()).total_mass()
    assert total == pytest.approx(MassModel().total, abs=1e-9)
    assert MassModel().leg_total == pytest.approx(0.5)
    pm = closed_loop_model(Robot.default().replace(masses=POINT_MASS))
    assert pm.total_mass() == pytest.approx(1.5)
    leg_bodies = [pm.model.inertias[pm.model.getJointId(f"leg{i}_Ds3")] for i in range(3)]
    for inertia in leg_bodies:
        assert inertia.mass == pytest.approx(POINT_MASS.point_mass_value)
        np.testing.assert_allclose(inertia.lever, [RobotGeometry().leg.dp, 0, 0])


def test_layout_matches_the_spec() -> None:
    g = RobotGeometry()
    A = np.array([g.leg_origin(i) for i in range(3)])
    for i in range(3):
        for j in range(i + 1, 3):
            assert np.linalg.norm(A[i] - A[j]) == pytest.approx(0.143)
        R = g.leg_rotation(i)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
        # y points to the centre, x is tangent
        np.testing.assert_allclose(R[:, 1], -A[i] / np.linalg.norm(A[i]), atol=1e-15)
    # cranks at 90 deg to the radius: the P_i form the paper's triangle of side 0.173 m
    P = np.array([g.crank_tip(i, math.pi / 2) for i in range(3)])
    assert np.linalg.norm(P[0] - P[1]) == pytest.approx(0.173, abs=5e-4)


def test_bad_inputs_are_named() -> None:
    with pytest.raises(GeometryError) as err:
        RobotGeometry(platform_crank=-0.1)
    assert err.value.parameter == "platform_crank"
    with pytest.raises(GeometryError):
        MassModel(body=-1.0)


def test_malformed_closures_file_is_refused(tmp_path) -> None:
    bad = tmp_path / "c.yaml"
    bad.write_text("closed_loop: [['a', 'b']]\ntype: ['6d']\nname_mot: []\n")
    with pytest.raises(InputError, match="only '3d'"):
        parse_closures(bad)
    bad.write_text("closed_loop: [['a']]\ntype: ['3d']\nname_mot: []\n")
    with pytest.raises(InputError, match="two frame names"):
        parse_closures(bad)
    bad.write_text(": not yaml : [")
    with pytest.raises(InputError):
        parse_closures(bad)
    text = gen.build_closures_yaml().replace("closedloop4_B", "nowhere")
    bad.write_text(text)
    with pytest.raises(InputError, match="nowhere"):
        load_model_from(gen.URDF_PATH, bad)


def test_base_plate_is_where_the_cranks_may_not_go_and_links_collide() -> None:
    """The drawn base (three beams, visual = collision) lies in the quadrant the actuated
    range forbids: no crank or proximal link at theta in [0, 270] deg enters it, and the
    proximal link at 315 or 345 deg (the base-collision quadrant) does.  Every body of
    the collision model is a collision cylinder of its radius."""
    import xml.etree.ElementTree as ET

    from sixplus3.kinematics.collision import N_BODIES, radii
    from sixplus3.robot_description.robot import Robot
    from sixplus3.robot_description.urdf import ROD_RADIUS

    robot = Robot.default()
    root = ET.fromstring(robot_urdf(robot))
    base = root.find("link[@name='base_link']")
    assert base is not None
    g = robot.geometry
    boxes = []
    for c in base.findall("collision"):
        box = c.find("geometry/box")
        if box is None:  # the pulley stacks (the collision model's hubs)
            assert c.find("geometry/cylinder") is not None
            continue
        size = np.array([float(v) for v in box.get("size").split()])
        xyz = np.array([float(v) for v in c.find("origin").get("xyz").split()])
        yaw = float(c.find("origin").get("rpy").split()[2])
        boxes.append((xyz, yaw, size / 2))
    vis = [v.find("geometry/box").get("size") for v in base.findall("visual")
           if v.find("geometry/box") is not None]
    assert len(boxes) == 3 and len(vis) == 3

    def in_base(pts: np.ndarray) -> bool:
        for xyz, yaw, half in boxes:
            c, s_ = np.cos(yaw), np.sin(yaw)
            d = pts - xyz
            local = np.c_[c * d[:, 0] + s_ * d[:, 1], -s_ * d[:, 0] + c * d[:, 1], d[:, 2]]
            if np.all(np.abs(local) <= half + ROD_RADIUS, axis=1).any():
                return True
        return False

    def enters(i: int, offset: float, length: float, theta_deg: float) -> bool:
        th = np.radians(theta_deg)
        R = g.leg_rotation(i)
        start = g.leg_origin(i) + offset * R[:, 0]
        tip = start + R @ np.array([0.0, length * np.cos(th), length * np.sin(th)])
        return in_base(start + np.linspace(0, 1, 400)[:, None] * (tip - start))

    leg = g.leg
    for i in range(3):
        for off, length in ((0.0, leg.l1), (leg.l6, leg.l2), (-leg.l7, leg.l3)):
            for th in np.arange(0.0, 270.0 + 1e-9, 5.0):
                assert not enters(i, off, length, th), (i, off, th)
        # the proximal link (mid-axis) in the forbidden quadrant meets the base
        assert enters(i, 0.0, leg.l1, 315.0) and enters(i, 0.0, leg.l1, 345.0)
    cyl = [c for c in root.iter("collision") if c.find("geometry/cylinder") is not None]
    found = sorted({float(c.find("geometry/cylinder").get("radius")) for c in cyl})
    assert len(cyl) == N_BODIES  # 6 links and a hub per leg, the platform's 9 bodies
    assert sorted(set(radii(robot).tolist())) == found


def test_yourdfpy_posed_at_a_closed_configuration_closes_the_loops() -> None:
    """pose_yourdfpy (the platform's floating joint through its origin, which
    yourdfpy's update_cfg ignores): at an IK configuration, every closure frame pair
    coincides in yourdfpy's own forward kinematics, and every frame is where Pinocchio
    puts it."""
    import pinocchio as pin

    from sixplus3.kinematics.robot import robot_ik_pose
    from sixplus3.robot_description.model import pose_yourdfpy

    robot = Robot.default()
    clm = closed_loop_model(robot)
    model = yourdfpy.URDF.load(str(gen.URDF_PATH))
    for pose in (((0.03, -0.02, 0.59), (0.3, -0.2, 0.5)), ((-0.04, 0.02, 0.56), (-0.4, 0.1, 1.0))):
        q = robot_ik_pose(*pose, robot=robot).q[0]
        pose_yourdfpy(model, clm, q)
        pin.framesForwardKinematics(clm.model, clm.data, q)
        for a, b in gen.closure_pairs():
            pa, pb = model.get_transform(a)[:3, 3], model.get_transform(b)[:3, 3]
            assert np.abs(pa - pb).max() < 1e-9, (a, b)
        for name in ("platform", "tcp", "leg1_P", "closedloop4_B"):
            np.testing.assert_allclose(model.get_transform(name),
                                       clm.data.oMf[clm.model.getFrameId(name)].homogeneous,
                                       atol=1e-9)
        # the platform really moved: not the file's identity origin
        assert np.abs(model.get_transform("platform")[:3, 3]).max() > 0.2


def test_export_urdf_writes_its_closures_and_a_ros2_control_block(tmp_path) -> None:
    """`robot export urdf --ros2-control -o FILE` writes FILE and the closures file it
    names beside it; the pair loads in Pinocchio as the robot (27 closure rows, the
    same tree), yourdfpy reads the URDF, and the ros2_control block has an effort
    interface within the torque limit, the rotor inertia and a 72/34 transmission for
    each of the nine actuated joints."""
    import xml.etree.ElementTree as ET

    from click.testing import CliRunner

    from sixplus3.cli import main

    robot = Robot.default()
    out = tmp_path / "robot.urdf"
    res = CliRunner().invoke(main, ["robot", "export", "urdf", "--ros2-control", "-o",
                                    str(out)])
    assert res.exit_code == 0, res.output
    closures = tmp_path / "sixplus3_closures.yaml"
    assert closures.read_text() == gen.build_closures_yaml()
    clm = load_model_from(out, closures)
    ref = closed_loop_model(robot)
    assert clm.model.nq == ref.model.nq and clm.n_constraints == ref.n_constraints == 27
    assert len(yourdfpy.URDF.load(str(out), load_meshes=False).actuated_joint_names) > 9
    block = ET.parse(out).getroot().find("ros2_control")
    assert block is not None
    joints = block.findall("joint")
    assert [j.get("name") for j in joints] == gen.actuated_joint_names()
    from sixplus3.kinematics.robot import home
    from sixplus3.robot_description.ros2_control import ros2_control_block

    start = home(robot).theta[0]
    for jk, j in enumerate(joints):
        # mock hardware starts at the robot's home, not at 0 rad (issue 53.3)
        states = {s.get("name"): float(s.find("param[@name='initial_value']").text)
                  for s in j.findall("state_interface")}
        assert states["position"] == pytest.approx(start[jk], abs=1e-14)
        assert states["velocity"] == states["effort"] == 0.0
        cmd = j.find("command_interface")
        assert cmd.get("name") == "effort"
        lo, hi = (float(p.text) for p in cmd.findall("param"))
        assert (lo, hi) == (-robot.limits.torque, robot.limits.torque)
        params = {p.get("name"): float(p.text) for p in j.findall("param")}
        assert params["rotor_inertia_at_joint_kg_m2"] == pytest.approx(robot.motors.armature)
    trs = block.findall("transmission")
    assert len(trs) == 9
    for tr in trs:
        assert float(tr.find("joint/mechanical_reduction").text) == pytest.approx(72 / 34)
    plain = CliRunner().invoke(main, ["robot", "export", "urdf", "--contacts"])
    assert plain.exit_code == 2
    assert "initial_value" not in gen.robot_urdf(robot)
    with pytest.raises(ValueError, match="9 finite angles"):
        ros2_control_block(robot, initial=[0.0] * 8)


def test_ros2_control_starts_at_a_trajectory_files_first_sample(tmp_path) -> None:
    """`--start FILE`: the initial values are the file's first sample (here a hold at a
    pose away from home, written by the gate's writer)."""
    import xml.etree.ElementTree as ET

    from click.testing import CliRunner

    from sixplus3.cli import main
    from sixplus3.control.gate.validation import validate_and_write
    from sixplus3.kinematics.robot import robot_ik_pose
    from sixplus3.kinematics.rotations import rotvec_from_matrix

    robot = Robot.default()
    cfg = robot_ik_pose(np.add(robot.home_position, [0.02, 0.0, 0.01]), (0.1, 0.0, 0.0),
                        robot.home_psi, robot=robot)
    n = 50
    t = np.arange(n) / 1000.0
    theta = np.tile(cfg.theta[0], (n, 1))
    zeros = np.zeros_like(theta)
    x = np.r_[cfg.position[0], np.reshape(rotvec_from_matrix(cfg.rotation[0]), -1), cfg.psi[0]]
    path, _ = validate_and_write(tmp_path / "hold.csv", Motion(t, theta, zeros, zeros, 1000.0),
                                 robot, np.tile(x, (n, 1)))
    out = tmp_path / "r.urdf"
    res = CliRunner().invoke(main, ["robot", "export", "urdf", "--ros2-control", "--start",
                                    str(path), "-o", str(out)])
    assert res.exit_code == 0, res.output
    block = ET.parse(out).getroot().find("ros2_control")
    got = [float(j.find("state_interface[@name='position']/param").text)
           for j in block.findall("joint")]
    np.testing.assert_allclose(got, cfg.theta[0], atol=1e-14)
    bad = CliRunner().invoke(main, ["robot", "export", "urdf", "--start", str(path)])
    assert bad.exit_code == 2 and "--start goes with --ros2-control" in bad.output
