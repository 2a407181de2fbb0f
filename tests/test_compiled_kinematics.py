"""The compiled forward kinematics of a sequence (dynamics/compiled_kinematics.py) that
identification, the wrench estimate, commissioning and teach stand on: the same poses as
the batched Newton (kinematics.robot.robot_fk_batch), the same failures, faster."""

from __future__ import annotations

import time

import numpy as np

from sixplus3.dynamics.compiled_kinematics import CompiledKinematics
from sixplus3.identification.base import configurations, poses_batched, poses_of
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()


def _motion(n: int = 1500, rate: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """(theta (n, 9), x (n, 9)) of a smooth motion known by its poses: a circle of 4 cm,
    a tilt of up to 15 deg and the cranks swinging by 0.4 rad, in 1.5 s."""
    t = np.arange(n) / rate
    w = 2 * np.pi / 1.5
    pos = np.asarray(ROBOT.home_position) + np.c_[0.04 * np.sin(w * t),
                                                  0.04 * (1 - np.cos(w * t)), 0.01 * t]
    rv = np.c_[0.26 * np.sin(w * t), 0.1 * np.sin(2 * w * t), 0.2 * t]
    psi = np.asarray(ROBOT.home_psi) + 0.4 * np.sin(w * t)[:, None] * np.array([1, -1, 0.5])
    cfg = robot_ik(pos, rot.matrix_from_rotvec(rv), psi, ROBOT, platform_margins=False)
    assert np.all(cfg.ok)
    return cfg.theta, np.c_[pos, rv, psi]


def test_the_compiled_follower_finds_the_motions_poses() -> None:
    theta, x = _motion()
    xs, ok = poses_of(ROBOT, theta)
    assert ok.all()
    np.testing.assert_allclose(xs, x, atol=1e-8)
    xb, okb = poses_batched(ROBOT, theta)
    assert okb.all()
    np.testing.assert_allclose(xs, xb, atol=1e-8)
    # the configurations of the compiled model are Pinocchio's
    ck = CompiledKinematics(ROBOT)
    q_batch = np.concatenate([c.q for _, c, _ in configurations(ROBOT, theta[:200], xs[:200])])
    np.testing.assert_allclose(ck.configurations(xs[:200]), q_batch, atol=1e-8)


def test_a_sample_without_a_pose_is_left_unsolved_and_the_rest_followed() -> None:
    """A corrupt sample (a 1 rad spike on one joint: no pose near its neighbours) stops the
    compiled run there; the batched method marks it, and the rest is followed again."""
    theta, x = _motion(600)
    bad = theta.copy()
    bad[300, 4] += 1.0
    ck = CompiledKinematics(ROBOT)
    out = np.zeros_like(bad)
    assert ck.follow(bad, x[0], out) == 300  # the run ends at the spike
    xs, ok = poses_of(ROBOT, bad)
    xb, okb = poses_batched(ROBOT, bad)
    np.testing.assert_array_equal(ok, okb)
    assert not ok[300] and ok[:300].all() and ok[301:].all()
    np.testing.assert_allclose(xs[ok], x[ok], atol=1e-8)
    # give_up: nothing after the first sample without a pose
    _, ok_g = poses_of(ROBOT, bad, give_up=True)
    assert ok_g[:300].all() and not ok_g[300:].any()


def test_the_compiled_follower_is_faster_than_the_batched_newton() -> None:
    """The ratio of the two, measured in one run (no absolute time: the machine is
    shared). On this smooth 1 kHz motion the batched Newton keeps whole chunks, and the
    compiled one was 1.8-6x faster here depending on the machine's load (on a
    decimated identification log, where the batched method splits its chunks, 6x):
    asserted only that it is faster."""
    theta, _ = _motion(1500)
    poses_of(ROBOT, theta[:10])  # compiled and cached
    t0 = time.perf_counter()
    poses_of(ROBOT, theta)
    t1 = time.perf_counter()
    poses_batched(ROBOT, theta)
    t2 = time.perf_counter()
    assert (t1 - t0) < (t2 - t1), (t1 - t0, t2 - t1)


def test_a_small_library_is_found_by_its_key_without_the_symbolic_model(tmp_path,
                                                                        monkeypatch) -> None:
    """compiled_small with a maker: the first call builds and records the library; a
    new process (the per-process cache cleared) loads it through the index and never
    calls the maker, which would build the symbolic model (2.5 s of a command's start)."""
    import casadi as ca

    from sixplus3.cache import PRODUCTS
    from sixplus3.dynamics import codegen

    monkeypatch.setenv("SIXPLUS3_CACHE", str(tmp_path))
    if not codegen.codegen_enabled():
        return
    x = ca.SX.sym("x", 2)
    calls: list[int] = []

    def make() -> ca.Function:
        calls.append(1)
        return ca.Function("small_t", [x], [ca.vertcat(x[0] * x[1], ca.sin(x[0]))])

    f1 = codegen.compiled_small(make, "key-a", "small_t")
    assert calls == [1] and "External" in str(f1)
    PRODUCTS.clear()
    f2 = codegen.compiled_small(make, "key-a", "small_t")
    assert calls == [1] and "External" in str(f2)
    np.testing.assert_allclose(np.asarray(f2([0.3, 2.0])).ravel(), [0.6, np.sin(0.3)])
    PRODUCTS.clear()
    codegen.compiled_small(make, "key-b", "small_t")  # another key: built again
    assert calls == [1, 1]
