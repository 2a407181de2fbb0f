"""Constrained dynamics: each result checked against an independent derivation."""

from __future__ import annotations

import numpy as np
import pytest

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InputError, SingularityError
from sixplus3.kinematics.leg import leg_ik
from sixplus3.kinematics.robot import home, robot_ik_pose
from sixplus3.kinematics.robot_fk import robot_fk
from sixplus3.robot_description.masses import POINT_MASS
from sixplus3.robot_description.physical import MotorModel
from sixplus3.robot_description.robot import Robot

ROBOT_ = Robot.default()
GEOM = ROBOT_.geometry


@pytest.fixture(scope="module")
def dyn() -> ClosedLoopDynamics:
    return ClosedLoopDynamics(ROBOT_)


def sample_configs():
    return [
        home(ROBOT_).q[0],
        robot_ik_pose((0.04, -0.03, 0.61), (0.3, -0.2, 0.4), (1.2, 1.8, 1.4), robot=ROBOT_).q[0],
        robot_ik_pose((-0.05, 0.02, 0.55), (-0.4, 0.1, -0.6), (1.9, 1.3, 1.6), robot=ROBOT_).q[0],
    ]


def test_unactuated_drop_conserves_energy_and_closures() -> None:
    """Without friction the energy (rotor inertia included) is conserved; with the
    default friction it only decreases.  (The default robot's 2 s fall reaches 12 J; the
    drift is 1.6 % at dt = 1 ms, 0.13 % at 0.5 ms and 0.006 % at 0.25 ms: it converges.)"""
    frictionless = Robot.default().replace(motors=MotorModel(viscous=0.0, coulomb=0.0))
    dyn = ClosedLoopDynamics(frictionless)
    tr = dyn.simulate(home(ROBOT_).q[0], np.zeros(dyn.model.nv), duration=2.0, dt=5e-4)
    e = tr.energy
    assert tr.kinetic.max() > 1.0  # it really fell and swung (J)
    assert np.abs(e - e[0]).max() <= 0.01 * abs(e[0])
    assert tr.residual.max() < 1e-6
    lossy = ClosedLoopDynamics(ROBOT_).simulate(home(ROBOT_).q[0], np.zeros(36), 0.5, 1e-3)
    assert np.all(np.diff(lossy.energy) <= 1e-6 * abs(lossy.energy[0]))
    assert lossy.energy[-1] < lossy.energy[0] - 0.01  # friction took some


def test_gravity_torques_are_the_virtual_work_of_the_potential(dyn) -> None:
    """tau_k = dU/dtheta_k by central differences of the energy along each motor."""
    h = 1e-6
    for q in sample_configs():
        tau = dyn.gravity_torques(q)
        theta = q[dyn.clm.idx_q_act]
        fd = np.zeros(9)
        for k in range(9):
            u = []
            for sgn in (1, -1):
                th = theta.copy()
                th[k] += sgn * h
                qk = robot_fk(th, q_hint=q, robot=ROBOT_).q
                u.append(dyn.energy(qk, np.zeros(dyn.model.nv))[1])
            fd[k] = (u[0] - u[1]) / (2 * h)
        np.testing.assert_allclose(tau, fd, rtol=1e-6, atol=1e-7)
        assert np.abs(tau).max() > 0.1


def test_forward_dynamics_reproduces_the_commanded_acceleration(dyn) -> None:
    rng = np.random.default_rng(0)
    for q in sample_configs():
        th_d, th_dd = rng.normal(size=9), rng.normal(scale=5.0, size=9)
        v, a = dyn.consistent_state(q, th_d, th_dd)
        tau = dyn.inverse_dynamics(q, v, a)
        a_fd = dyn.forward_dynamics(q, v, tau).a
        np.testing.assert_allclose(a_fd[dyn.clm.idx_v_act], th_dd, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(a_fd, a, rtol=1e-7, atol=1e-7)
        # the commanded motion is consistent: Jc v = 0 and Jc a + gamma = 0
        Jc = dyn.clm.constraint_jacobian(q)
        assert np.abs(Jc @ v).max() < 1e-12
        assert np.abs(Jc @ a + dyn.clm.drift(q, v)).max() < 1e-10


def test_point_mass_variant_matches_the_leg_jacobian(dyn) -> None:
    """Massless links, 0.5 kg at P: torques are the leg's tau = K^T J^-T f, leg by leg."""
    pm = ClosedLoopDynamics(Robot.default().replace(masses=POINT_MASS))
    rng = np.random.default_rng(1)
    m, g = POINT_MASS.point_mass_value, 9.81
    for q in sample_configs():
        assert np.abs(pm.clm.residual(q)).max() < 1e-10  # also updates the frames
        P = [pm.clm.frame_position(f"leg{i}_P") for i in range(3)]
        leg_M = [leg_ik(GEOM.to_leg(i, P[i]), GEOM.leg, ROBOT_.mode).M[0] for i in range(3)]
        R = [GEOM.leg_rotation(i) for i in range(3)]
        # gravity: each actuator set holds its own point mass (f = +m g up, at P_i)
        tau_g = pm.gravity_torques(q)
        expect = np.concatenate([leg_M[i] @ (R[i].T @ [0, 0, m * g]) for i in range(3)])
        np.testing.assert_allclose(tau_g, expect, rtol=1e-9, atol=1e-10)
        # an external force on leg 1's P: only leg 1's motors react, with -M f
        f = rng.normal(scale=10.0, size=3)
        z = np.zeros(pm.model.nv)
        tau_f = pm.inverse_dynamics(q, z, z, f_ext={"leg1_P": f}) - tau_g
        expect = np.zeros(9)
        expect[3:6] = -leg_M[1] @ (R[1].T @ f)
        np.testing.assert_allclose(tau_f, expect, rtol=1e-9, atol=1e-10)


def test_singular_configuration_raises(dyn) -> None:
    half = np.pi / 2
    q = robot_ik_pose((0, 0, 0.58), (0, 0, 0), (0.0, half, half), robot=ROBOT_).q[0]
    z = np.zeros(dyn.model.nv)
    with pytest.raises(SingularityError, match="parallel singularity"):
        dyn.inverse_dynamics(q, z, z)
    with pytest.raises(InputError):
        dyn.inverse_dynamics(q[:-1], z, z)
    with pytest.raises(InputError):
        dyn.simulate(q, z, duration=1.0, dt=-1e-3)


def test_batched_holding_torques_match_the_static_inverse_dynamics() -> None:
    """holding_torques_batch (one solve per state; the Pinocchio reference of the atlas's
    compiled statics) against gravity_torques (the full constrained inverse dynamics at
    v = a = 0), with a payload and ceiling."""
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.kinematics.robot import robot_ik
    from sixplus3.kinematics.rotations import matrix_from_rotvec
    from sixplus3.robot_description.physical import Payload
    from sixplus3.robot_description.robot import Robot

    for robot in (Robot.default(),
                  Robot.default().replace(payload=Payload(mass=0.5, com=(0.0, 0.01, 0.03)),
                                          gravity=(0.0, 0.0, 9.81))):
        rng = np.random.default_rng(3)
        n = 12
        pos = np.c_[rng.uniform(-0.05, 0.05, (n, 2)), rng.uniform(0.56, 0.62, n)]
        R = matrix_from_rotvec(np.c_[rng.normal(scale=0.2, size=(n, 2)), np.zeros(n)])
        cfg = robot_ik(pos, R, np.tile(robot.home_psi, (n, 1)), robot)
        q = cfg.q[cfg.ok]
        assert len(q) >= 8
        dyn = ClosedLoopDynamics(robot)
        batch = dyn.holding_torques_batch(q)
        one = np.array([dyn.gravity_torques(qk) for qk in q])
        assert np.abs(one).max() > 0.1  # gravity loads the motors
        np.testing.assert_allclose(batch, one, atol=1e-9, rtol=0)


def test_batched_closure_jacobian_and_drift_match_pinocchio_per_state(dyn) -> None:
    """constraint_jacobian_batch / drift_batch (world-frame Jacobians and their time
    variation, the closure rows formed in numpy) against Pinocchio's per-state constraint
    Jacobian and frame classical accelerations, at consistent and arbitrary velocities."""
    clm = dyn.clm
    q = np.array(sample_configs())
    Jc, kin = clm.constraint_jacobian_batch(q)
    for k, qk in enumerate(q):
        np.testing.assert_allclose(Jc[k], clm.constraint_jacobian(qk), atol=1e-13, rtol=0)
    rng = np.random.default_rng(5)
    v = rng.normal(scale=2.0, size=(len(q), dyn.model.nv))
    v[0] = dyn.consistent_state(q[0], rng.normal(size=9), np.zeros(9))[0]
    gamma = clm.drift_batch(q, v, kin)
    ref = np.array([clm.drift(qk, vk) for qk, vk in zip(q, v, strict=True)])
    assert np.abs(ref).max() > 1.0  # the quadratic velocity terms are exercised
    np.testing.assert_allclose(gamma, ref, atol=1e-12, rtol=0)
    rows = np.array([True, False, True])
    part = clm.drift_batch(q, v, kin, rows=rows)
    np.testing.assert_array_equal(part[rows], gamma[rows])
    assert not part[~rows].any()


def test_batched_inverse_dynamics_matches_the_per_state_one() -> None:
    """actuated_inverse_dynamics_batch (the validator's and the dense check's) against
    actuated_inverse_dynamics and consistent_state + inverse_dynamics,
    state by state, moving and at rest, with a payload and the motor model."""
    from sixplus3.robot_description.physical import Payload

    robot = Robot.default().replace(payload=Payload(mass=0.4, com=(0.01, 0.0, 0.02)))
    dyn = ClosedLoopDynamics(robot)
    rng = np.random.default_rng(11)
    q = np.array(sample_configs() * 2)
    th_d = rng.normal(scale=2.0, size=(len(q), 9))
    th_dd = rng.normal(scale=20.0, size=(len(q), 9))
    th_d[1] = 0.0  # at rest: no drift is computed for this row
    tau, rcond = dyn.actuated_inverse_dynamics_batch(q, th_d, th_dd)
    for k in range(len(q)):
        one, rc = dyn.actuated_inverse_dynamics(q[k], th_d[k], th_dd[k])
        np.testing.assert_allclose(tau[k], one, atol=1e-10, rtol=0)
        # and the tree's consistent state, then RNEA through G (the other route)
        v, a = dyn.consistent_state(q[k], th_d[k], th_dd[k])
        np.testing.assert_allclose(tau[k], dyn.inverse_dynamics(q[k], v, a), atol=1e-10,
                                   rtol=0)
        assert rcond[k] > 0 and rc > 0
    assert np.abs(tau).max() > 0.5
