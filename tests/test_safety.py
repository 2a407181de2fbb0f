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
    from sixplus3.control.drive.simulation import MujocoRobot
    from sixplus3.robot_description.robot import Tool

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
