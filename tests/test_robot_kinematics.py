"""Whole-robot IK / FK / singularity measures, checked against Pinocchio's frames."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from sixplus3.errors import ConvergenceError, InputError, UnreachableError
from sixplus3.kinematics.leg import leg_ik
from sixplus3.kinematics.robot import home, robot_ik, robot_ik_pose
from sixplus3.kinematics.robot_fk import robot_fk
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot

ROBOT_ = Robot.default()


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
GEOM = ROBOT_.geometry


def random_poses(n: int, seed: int, tilt: float = 0.5):
    rng = np.random.default_rng(seed)
    pos = np.c_[rng.uniform(-0.08, 0.08, n), rng.uniform(-0.08, 0.08, n),
                rng.uniform(0.22, 0.45, n)]
    R = Rotation.from_euler("xyz", rng.uniform(-tilt, tilt, (n, 3))).as_matrix()
    psi = rng.uniform(0.6, 2.5, (n, 3))
    return pos, R, psi


def test_ik_closes_all_27_closures_in_pinocchio() -> None:
    clm = closed_loop_model(Robot.default())
    pos, R, psi = random_poses(60, seed=1)
    cfg = robot_ik(pos, R, psi, robot=ROBOT_)
    assert cfg.ok.sum() >= 50
    for k in np.flatnonzero(cfg.ok):
        assert np.abs(clm.residual(cfg.q[k])).max() < 1e-10
        # Pinocchio's platform frames agree with the pose we asked for
        for i in range(3):
            P = clm.frame_position(f"closedloop{3 * i + 2}_B")
            np.testing.assert_allclose(P, cfg.P[k, i], atol=1e-12)
        np.testing.assert_allclose(
            clm.data.oMi[clm.model.getJointId("platform_free")].rotation, R[k], atol=1e-12)


def test_ik_theta_is_each_legs_ik_of_its_sphere_centre() -> None:
    pos, R, psi = random_poses(40, seed=2)
    cfg = robot_ik(pos, R, psi, robot=ROBOT_)
    for i in range(3):
        s = leg_ik(GEOM.to_leg(i, cfg.P[:, i]), GEOM.leg, ROBOT_.mode)
        np.testing.assert_array_equal(s.status != 0, cfg.leg_status[:, i] != 0)
        np.testing.assert_allclose(cfg.theta[cfg.ok, 3 * i:3 * i + 3], s.theta[cfg.ok])


def test_unreachable_pose_names_the_leg_and_chain() -> None:
    with pytest.raises(UnreachableError) as err:
        robot_ik_pose((0.0, 0.0, 1.2), robot=ROBOT_)
    assert err.value.chain.startswith("leg ") and "RU" in err.value.chain
    with pytest.raises(InputError):
        robot_ik_pose((0.0, np.nan, 0.3), robot=ROBOT_)
    with pytest.raises(InputError, match="orthonormal"):
        robot_ik(np.zeros(3) + [0, 0, 0.58], 2 * np.eye(3), Robot.default().home_psi, robot=ROBOT_)


def test_fk_recovers_pose_from_a_perturbed_hint() -> None:
    clm = closed_loop_model(Robot.default())
    pos, R, psi = random_poses(10, seed=3, tilt=0.3)
    cfg = robot_ik(pos, R, psi, robot=ROBOT_)
    rng = np.random.default_rng(3)
    for k in np.flatnonzero(cfg.ok & (cfg.margins.minimum > 0.05))[:6]:
        hint = pin.integrate(clm.model, cfg.q[k], rng.normal(scale=0.02, size=clm.model.nv))
        fk = robot_fk(cfg.theta[k], q_hint=hint, robot=ROBOT_)
        assert fk.residual < 1e-12
        np.testing.assert_allclose(fk.position, pos[k], atol=1e-10)
        np.testing.assert_allclose(fk.rotation, R[k], atol=1e-10)
        np.testing.assert_allclose(fk.psi, psi[k], atol=1e-9)


def test_fk_raises_when_it_cannot_converge() -> None:
    theta = home(ROBOT_).theta[0].copy()
    theta[0] -= 2.5  # leg 0's proximal link folded far away: no assembly near home
    with pytest.raises(ConvergenceError, match="closure residual"):
        robot_fk(theta, max_iter=20, robot=ROBOT_)
    with pytest.raises(InputError):
        robot_fk(np.zeros(8), robot=ROBOT_)


def test_platform_margin_vanishes_with_radial_cranks() -> None:
    psis = np.linspace(0.0, math.pi / 2, 7)
    m = [robot_ik_pose((0, 0, 0.58), (0, 0, 0), (p, p, p), robot=ROBOT_).margins.platform[0]
         for p in psis]
    assert m[0] < 1e-12
    assert all(np.diff(m) > 0)  # monotone towards the 90 deg cranks
    # One radial crank is singular when the other two sit at 90 deg (their crank lines
    # then cannot stop the remaining in-plane motion), but not for generic crank angles.
    half = math.pi / 2
    def platform(psi):
        return robot_ik_pose((0, 0, 0.58), (0, 0, 0), psi, robot=ROBOT_).margins.platform[0]

    assert platform((0, half, half)) < 1e-9
    assert platform((0, 1.2, 1.9)) > 1e-3


def test_platform_margin_is_pose_invariant() -> None:
    a = robot_ik_pose((0, 0, 0.58), (0, 0, 0), (1.2, 1.5, 1.9), robot=ROBOT_).margins.platform[0]
    b = robot_ik_pose((0.03, -0.02, 0.63), (0.3, -0.2, 0.5), (1.2, 1.5, 1.9),
                      robot=ROBOT_).margins.platform[0]
    assert a == pytest.approx(b, rel=1e-9)


def test_home_and_spherical_joint_tilts() -> None:
    h = home(ROBOT_)
    assert h.ok[0] and h.margins.minimum[0] > 0.3
    np.testing.assert_allclose(spherical_tilts(h), 0.0, atol=1e-7)
    # every tilt again from the joints' points: P's axis is D -> P in the body and turns
    # with the platform in the crank; E's (F's) is G -> E (H -> F) along the distal link
    # and turns with the body's frame Q in the leg body (the joint angles are not used)
    g = ROBOT_.geometry

    def unit(v):
        return v / np.linalg.norm(v)

    def angle(a, b):
        return math.acos(min(1.0, max(-1.0, float(unit(a) @ unit(b)))))

    for rpy, psi in (((0.5, 0.0, 0.0), ROBOT_.home_psi), ((0.2, -0.3, 0.4), (1.3, 1.8, 1.5)),
                     ((-0.4, 0.1, -0.7), (1.9, 1.2, 1.6))):
        cfg = robot_ik_pose((0.02, -0.01, 0.57), rpy, psi, robot=ROBOT_)
        R = cfg.rotation[0]
        want = np.zeros((3, 3))
        for i in range(3):
            Rl, o, hs, s = g.leg_rotation(i), g.leg_origin(i), h.legs[i], cfg.legs[i]
            turn = Rl @ s.Q[0] @ hs.Q[0].T @ Rl.T  # the body's rotation from home

            def w(leg, k, i=i, Rl=Rl, o=o):
                return Rl @ getattr(leg, k)[0] + o

            for j, (a, b) in enumerate((("g", "e"), ("h", "f"))):
                want[i, j] = angle(w(s, b) - w(s, a), turn @ (w(hs, b) - w(hs, a)))
            crank = (R @ rot_z(g.crank_axis_angle(i) + psi[i])
                     @ rot_z(g.crank_axis_angle(i) + ROBOT_.home_psi[i]).T)
            want[i, 2] = angle(w(s, "p") - w(s, "d"), crank @ (w(hs, "p") - w(hs, "d")))
        np.testing.assert_allclose(spherical_tilts(cfg)[0], want, atol=1e-9)
        assert want.max() > 0.1


def test_compiled_segment_distance_matches_the_numpy_reference() -> None:
    """kinematics._geometry_kernel.segment_distance (leg_clearance's) against the numpy
    _segment_distance, on random segments and the degenerate ones: parallel, crossing,
    collinear, zero length, end to end."""
    from sixplus3.kinematics._geometry_kernel import min_link_distance, segment_distance
    from sixplus3.kinematics.collision import _segment_distance

    rng = np.random.default_rng(2)
    n = 400
    p1, q1, p2, q2 = (rng.normal(size=(n, 3)) for _ in range(4))
    q2[:40] = p2[:40] + (q1[:40] - p1[:40]) * rng.uniform(0.2, 3.0, (40, 1))  # parallel
    q1[40:60] = p1[40:60]  # a point
    q2[50:70] = p2[50:70]  # a point (50..59: two points)
    p2[70:90] = p1[70:90] + 0.3 * (q1[70:90] - p1[70:90])  # crossing p1 q1
    q2[90:100] = p1[90:100] + 2.0 * (q1[90:100] - p1[90:100])  # collinear, overlapping
    p2[90:100] = q1[90:100]
    p2[100:110] = q1[100:110]  # end to end
    ref = _segment_distance(p1, q1, p2, q2)
    got = np.array([segment_distance(*rows) for rows in zip(p1, q1, p2, q2, strict=True)])
    np.testing.assert_allclose(got, ref, atol=1e-14, rtol=1e-12)
    assert ref[70:100].max() < 1e-12 and ref.max() > 0.5
    # the batched minimum over leg pairs and links
    seg = rng.normal(size=(5, 3, 6, 2, 3))
    links = np.array([0, 1, 3, 5])
    want = np.full(5, np.inf)
    for i in range(3):
        for j in range(i + 1, 3):
            for a in links:
                for b in links:
                    want = np.minimum(want, _segment_distance(seg[:, i, a, 0], seg[:, i, a, 1],
                                                              seg[:, j, b, 0], seg[:, j, b, 1]))
    np.testing.assert_allclose(min_link_distance(seg, links), want, atol=1e-14, rtol=1e-12)
