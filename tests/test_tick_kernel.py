"""The per-tick kernels against independent derivations: the 9 x 9 LU
(interaction/observer/_tick_kernel.py) against LAPACK's (scipy), the envelope against its closed
form, the walls' slacks (interaction/lead/_walls_kernel.py) against the gate's own checks.  The
observer's state built on them is checked against Pinocchio's in
tests/test_leadthrough.py.  The slow update's pieces: the 9 x 9 extreme eigenvalues
against LAPACK's, the exp map against kinematics.rotations, its scalars against
walls.crank_score and the tests written out in numpy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import lu_factor as scipy_lu_factor
from scipy.linalg import lu_solve as scipy_lu_solve

from sixplus3.interaction.lead import _lead_kernel as lead_kern
from sixplus3.interaction.lead import _walls_kernel as wk
from sixplus3.interaction.lead import walls
from sixplus3.interaction.observer._tick_kernel import envelope, lu_factor, lu_solve, lu_solve_t
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.checks import actuated_bounds
from sixplus3.kinematics.collision import clearance
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.spherical import spherical_tilts
from sixplus3.robot_description.robot import Robot


@pytest.mark.parametrize("seed", range(5))
def test_lu_solves_agree_with_lapack(seed: int) -> None:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(9, 9)) * np.logspace(0, 3, 9)  # badly scaled columns
    b = rng.normal(size=9)
    lu, piv = np.empty((9, 9)), np.empty(9, dtype=np.int64)
    assert lu_factor(A, lu, piv) == 0
    ref = scipy_lu_factor(A)
    out = np.empty(9)
    lu_solve(lu, piv, b, out)
    np.testing.assert_allclose(out, scipy_lu_solve(ref, b), rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(A @ out, b, atol=1e-10)
    lu_solve_t(lu, piv, b, out)
    np.testing.assert_allclose(out, scipy_lu_solve(ref, b, trans=1), rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(A.T @ out, b, atol=1e-10)


def test_a_singular_matrix_is_reported() -> None:
    A = np.eye(9)
    A[4] = A[2]
    lu, piv = np.empty((9, 9)), np.empty(9, dtype=np.int64)
    assert lu_factor(A, lu, piv) != 0


def _random_command(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """(tau_ff, ref, vref, theta, vel, Kp, Kd): a drive's command and state at random,
    Kp = 0 on about a third of the joints."""
    ff = rng.uniform(-12, 12, 9)
    ref, vref = rng.normal(0, 0.02, 9), rng.normal(0, 1.0, 9)
    theta, vel = rng.normal(0, 0.02, 9), rng.normal(0, 1.0, 9)
    kp = np.where(rng.random(9) < 0.3, 0.0, rng.uniform(100, 3000, 9))
    return ff, ref, vref, theta, vel, kp, rng.uniform(1, 30, 9)


def test_the_envelope_is_the_closed_form() -> None:
    """Each joint's total tau_ff + PD within +-cap after the move, unchanged where it
    was, and the reference moved exactly to the cap's edge where it was not (Kp > 0:
    the angle; Kp = 0 < Kd: the rate)."""
    rng = np.random.default_rng(3)
    cap = 9.7
    for _ in range(200):
        ff, ref, vref, theta, vel, kp, kd = _random_command(rng)
        f2, r2, v2 = ff.copy(), ref.copy(), vref.copy()
        wanted, moved = envelope(f2, r2, v2, kp, kd, theta, vel, np.zeros(9), cap)
        pd0 = kp * (ref - theta) + kd * (vref - vel)
        assert wanted == pytest.approx(np.abs(ff + pd0).max())
        np.testing.assert_array_equal(f2, np.clip(ff, -cap, cap))
        total = f2 + kp * (r2 - theta) + kd * (v2 - vel)
        assert np.all(np.abs(total) <= cap + 1e-9)
        inside = np.abs(f2 + pd0) <= cap
        np.testing.assert_array_equal(r2[inside], ref[inside])
        np.testing.assert_array_equal(v2[inside], vref[inside])
        out = ~inside
        np.testing.assert_allclose(np.abs(total[out]), cap, rtol=1e-9)
        assert moved == bool(out.any() or np.any(np.abs(ff) > cap))


def test_the_walls_kernel_is_the_gates_checks_composed() -> None:
    """interaction/lead/_walls_kernel.py against robot_ik's margins, spherical_tilts, the
    actuated range and the collision model's clearance (the gate's own functions), on
    random poses around home (some without an assembly), clearance on some rows."""
    robot = Robot.default()
    rng = np.random.default_rng(11)
    n = 120
    pos = robot.home_position + rng.normal(0, 0.06, (n, 3))
    R = rot.matrix_from_rotvec(rng.normal(0, 0.4, (n, 3)))
    psi = robot.home_psi + rng.normal(0, 0.8, (n, 3))
    sel = rng.random(n) < 0.6
    sl, theta, ok = walls.slacks_and_angles(robot, pos, R, psi, sel)
    cfg = robot_ik(pos, R, psi, robot)
    lim, o = robot.limits, cfg.ok
    assert 0 < o.sum() < n
    np.testing.assert_array_equal(ok, o)
    ref = np.full((n, 4), -1.0)
    ref[o, 0] = cfg.margins.minimum[o] - (lim.margin + walls.MARGIN_GUARD)
    ref[o, 1] = (lim.spherical - walls.TILT_GUARD) - spherical_tilts(cfg).max(axis=(1, 2))[o]
    lo, hi = actuated_bounds(lim)
    ref[o, 2] = np.minimum(cfg.theta - lo, hi - cfg.theta).min(axis=1)[o] - walls.RANGE_GUARD
    ref[:, 3] = np.where(o, np.inf, -1.0)
    both = o & sel
    ref[both, 3] = (clearance(cfg, both)[both] - walls.CLEARANCE_GUARD) / 0.01
    np.testing.assert_array_equal(np.isinf(sl), np.isinf(ref))
    fin = np.isfinite(ref)
    np.testing.assert_allclose(sl[fin], ref[fin], rtol=0, atol=1e-10)
    np.testing.assert_allclose(theta[o], cfg.theta[o], rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_extreme_eigenvalues_agree_with_lapack(seed: int) -> None:
    """The walls kernel's eigenvalues (Householder + implicit QL) against LAPACK's
    eigvalsh, on Gram matrices J^T J, some nearly singular or badly scaled: each to a
    few eps of the largest."""
    rng = np.random.default_rng(seed)
    d, e, v, p = (np.empty(9) for _ in range(4))
    for t in range(300):
        J = rng.normal(size=(9, 9))
        if t % 3 == 0:
            J[:, 0] = J[:, 1] + 10.0 ** rng.uniform(-6, -1) * rng.normal(size=9)
        if t % 4 == 0:
            J[:, 3:6] *= 10.0 ** rng.uniform(-3, 3)
        G = J.T @ J
        ev = np.linalg.eigvalsh(G)
        lo, hi = wk.sym_extremes(G.copy(), d, e, v, p)
        assert abs(lo - ev[0]) <= 1e-14 * ev[-1]
        assert abs(hi - ev[-1]) <= 1e-14 * ev[-1]
    # a diagonal matrix (already tridiagonal, every off-diagonal zero) and a multiple of I
    diag = np.diag(np.arange(9.0, 0.0, -1.0))
    assert wk.sym_extremes(diag.copy(), d, e, v, p) == (1.0, 9.0)
    assert wk.sym_extremes(3.0 * np.eye(9), d, e, v, p) == (3.0, 3.0)


def test_moved_poses_are_rodrigues() -> None:
    """The compiled exp map of the slow update's poses against
    kinematics.rotations.matrix_from_rotvec (large and tiny rotations)."""
    rng = np.random.default_rng(5)
    tw = rng.normal(size=(40, 6)) * np.r_[np.ones(20), np.full(20, 1e-5)][:, None]
    p, R = rng.normal(size=3), rot.matrix_from_rotvec(rng.normal(size=3))[0]
    pos, rotm = np.empty((40, 3)), np.empty((40, 3, 3))
    wk.moved(p, R, tw, pos, rotm)
    np.testing.assert_allclose(pos, p + tw[:, :3], rtol=0, atol=1e-15)
    np.testing.assert_allclose(rotm, rot.matrix_from_rotvec(tw[:, 3:]) @ R, rtol=0,
                               atol=1e-14)


def test_the_slow_updates_scalars_are_the_walls_functions() -> None:
    """_lead_kernel.slow_scalars against walls.crank_score's central gradient, the
    probes' test and the walls near, written out in numpy."""
    rng = np.random.default_rng(9)
    grad, active, inside = np.empty(3), np.empty(4, dtype=np.bool_), np.empty(3, dtype=bool)
    for t in range(200):
        sl = rng.uniform(-0.3, 0.5, (10, 4))
        if t % 5 == 0:
            sl[rng.integers(7, 10)] = -1.0  # a probe without an assembly
        solved = sl[:, 0] > -1.0
        prev = sl[0] + rng.uniform(-0.1, 0.1, 4)
        dt = 0.0 if t % 7 == 0 else 0.01
        gn, n = lead_kern.slow_scalars(sl, solved, 3, 0.02, walls.WALL_BAND, prev, dt, 0.3,
                                       grad, active, inside)
        score = walls.crank_score(sl[:7])
        ref = (score[1:4] - score[4:7]) / 0.04
        np.testing.assert_allclose(grad, ref, rtol=0, atol=1e-12)
        assert gn == pytest.approx(np.linalg.norm(ref), abs=1e-12)
        floor = min(sl[0].min(), 0.0)
        np.testing.assert_array_equal(inside, solved[7:] & (sl[7:].min(axis=1) >= floor))
        rate = (sl[0] - prev) / dt if dt > 0 else np.zeros(4)
        ahead = sl[0] + np.minimum(rate, 0.0) * 0.3
        near = np.minimum(sl[0], ahead) < walls.WALL_BAND
        np.testing.assert_array_equal(active, near)
        assert n == near.sum()


def test_the_envelope_holds_for_every_rate_within_the_spread() -> None:
    """With a spread s of the drive's rate about the controller's, the total stays within
    +-cap at both ends v = vel -+ s (the PD is affine in v, so every rate between holds);
    where Kd s alone exceeds the cap, the PD cancels the feed-forward (worst Kd s)."""
    rng = np.random.default_rng(5)
    cap = 9.7
    for _ in range(300):
        ff, ref, vref, theta, vel, kp, kd = _random_command(rng)
        spread = rng.uniform(0.0, 0.5, 9)
        f2, r2, v2 = ff.copy(), ref.copy(), vref.copy()
        wanted, _ = envelope(f2, r2, v2, kp, kd, theta, vel, spread, cap)
        pd0 = kp * (ref - theta) + kd * (vref - vel)
        assert wanted == pytest.approx(np.abs(ff + pd0).max())
        for v in (vel - spread, vel + spread):
            total = f2 + kp * (r2 - theta) + kd * (v2 - v)
            assert np.all(np.abs(total) <= np.maximum(cap, kd * spread) + 1e-9)
        over = kd * spread > cap
        centre = f2 + kp * (r2 - theta) + kd * (v2 - vel)
        np.testing.assert_allclose(centre[over], 0.0, atol=1e-9)


def test_the_drive_rate_model_is_the_drives_filter() -> None:
    """envelope.DriveRate against the simulated drive's own rate feedbacks
    (control/drive/loop.py's arithmetic), on encoder differences of a random motion: the
    encoder's difference and a 1 ms filter from rest are modelled exactly; the true rate
    (the motion's derivative at the tick) stays within the model's spread."""
    from sixplus3.control.drive.loop import FILTER_TAU
    from sixplus3.interaction.envelope import DriveRate

    robot = Robot.default()
    rate = 1000.0
    dt = 1.0 / rate
    t = np.arange(400) * dt
    f = np.array([2.0, 3.0, 5.0, 7.0, 1.5, 2.5, 4.0, 6.0, 9.0])
    theta = 0.3 * np.sin(np.outer(t, f))  # smooth: accelerations up to 24 rad/s^2
    true = 0.3 * f * np.cos(np.outer(t, f))
    vel = np.diff(theta, axis=0) * rate
    for kind in ("encoder", "filtered", "true"):
        m = DriveRate(rate, robot, kind, FILTER_TAU)
        filt = np.zeros(9)
        for k in range(len(vel)):
            m.update(vel[k])
            filt += dt / (FILTER_TAU + dt) * (vel[k] - filt)
            drive = {"encoder": vel[k], "filtered": filt, "true": true[k + 1]}[kind]
            if kind == "true":
                if k > 2:
                    assert np.all(np.abs(drive - m.rate) <= m.spread), k
            else:
                np.testing.assert_allclose(m.rate, drive, rtol=1e-12, atol=1e-12)
                assert not m.spread.any()
