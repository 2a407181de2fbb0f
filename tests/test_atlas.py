"""The orientation-workspace atlas (sixplus3.design.atlas, ``sixplus3 atlas``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

pytest.importorskip("xarray")
pytest.importorskip("dask.distributed")

from sixplus3.cli import main  # noqa: E402
from sixplus3.design import atlas as at  # noqa: E402
from sixplus3.design import atlas_checks as ac
from sixplus3.design import atlas_data as ad
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics  # noqa: E402
from sixplus3.kinematics.collision import clearance  # noqa: E402
from sixplus3.kinematics.robot import robot_ik  # noqa: E402
from sixplus3.kinematics.rotations import rotvec_from_matrix  # noqa: E402
from sixplus3.kinematics.spherical import spherical_tilts  # noqa: E402
from sixplus3.planner.analysis import largest_tilt, static_feasible  # noqa: E402
from sixplus3.robot_description.robot import Robot  # noqa: E402

ROBOT = Robot.default()
#: largest_tilt's scheme: 5 deg scan, 0.5 deg bisection
LT = ad.AtlasSettings(scan_deg=5.0, resolution_deg=0.5, max_tilt_deg=180.0)
COARSE = ad.AtlasSettings(step=0.08, azimuth_step_deg=60.0, resolution_deg=2.0)


@pytest.fixture(scope="module")
def coarse():
    xs, ys, zs = ad.position_grid(ROBOT, COARSE.step)
    zs = zs[(zs > 0.5) & (zs < 0.7)]  # the default robot: 0.56 and 0.64 m
    return at.compute_atlas(ROBOT, COARSE, scheduler="synchronous", grid=(xs, ys, zs))


def test_agrees_with_largest_tilt_at_home() -> None:
    res = at.largest_tilts(ROBOT, np.asarray(ROBOT.home_position)[None], [0.0, 90.0],
                           (0.0,), LT)
    for k, axis in enumerate("xy"):
        locked = largest_tilt(ROBOT, axis, locked=True, max_deg=180.0)
        free = largest_tilt(ROBOT, axis, locked=False, max_deg=180.0)
        # the same candidate (home cranks) and scheme: the same number
        assert res["max_tilt"][1, 0, k, 0] == pytest.approx(locked.tilt_deg, abs=1e-9)
        # free: a finite search (leg-wise, then equal cranks), a lower bound of the
        # exhaustive 7.5 deg grid.  On the default robot it is equal about y and 23.4 deg
        # below it about x (104.7 against 128.1 deg at cranks (135, 105, 120) deg, which
        # neither the legs' own best values nor equal cranks reach; docs/atlas.md)
        assert res["max_tilt"][0, 0, k, 0] <= free.tilt_deg + LT.resolution_deg
        assert res["max_tilt"][0, 0, k, 0] >= free.tilt_deg - (25.0 if axis == "x" else 1.0)
        assert res["max_tilt"][0, 0, k, 0] >= res["max_tilt"][1, 0, k, 0]


def test_free_is_never_below_locked(coarse) -> None:
    t = coarse["max_tilt"].values
    free, locked = np.nan_to_num(t[0], nan=-1.0), np.nan_to_num(t[1], nan=-1.0)
    assert np.isfinite(t[1]).sum() > 20  # the grid holds a workspace
    assert np.all(free >= locked)
    assert (free > locked).any()  # and the redundancy does something


def _admissible(position, R, psi) -> bool:
    """The full robot checks, independently of the atlas's code path."""
    cfg = robot_ik(position, R, psi, ROBOT)
    lim = ROBOT.limits
    if not cfg.ok[0]:
        return False
    th = cfg.theta[0]
    if np.any(th < lim.theta_min) or np.any(th > lim.theta_max):
        return False
    if spherical_tilts(cfg).max() > lim.spherical or clearance(cfg)[0] < 0:
        return False
    if cfg.margins.minimum[0] < lim.margin:
        return False
    tau = ClosedLoopDynamics(ROBOT).gravity_torques(cfg.q[0])
    return bool(np.abs(tau).max() <= lim.torque)


def test_one_point_per_layer_rechecked(coarse) -> None:
    t = coarse["max_tilt"]
    checked = 0
    for iz in range(coarse.sizes["z"]):
        for mode in ad.CRANKS:
            layer = t.isel(z=iz).sel(cranks=mode, torsion=0.0).values  # (A, x, y)
            ok = np.isfinite(layer) & (layer > 0) & (layer < COARSE.max_tilt_deg)
            if not ok.any():
                continue
            ia, ix, iy = np.argwhere(ok)[len(np.argwhere(ok)) // 2]
            pos = np.array([coarse.x.values[ix], coarse.y.values[iy], coarse.z.values[iz]])
            az, tilt = float(coarse.azimuth.values[ia]), float(layer[ia, ix, iy])
            psi = np.radians(coarse["psi"].isel(z=iz).sel(cranks=mode, torsion=0.0)
                             .values[ia, ix, iy])
            R = at.rotations(az, tilt, 0.0)[0]
            assert _admissible(pos, R, psi), (mode, pos, az, tilt)
            if mode == "locked":  # just beyond: no admissible pose (exact candidate set)
                beyond = at.rotations(az, tilt + COARSE.resolution_deg, 0.0)[0]
                assert not static_feasible(ROBOT, pos, beyond, ROBOT.limits, True)[0]
            checked += 1
    assert checked >= 2 * coarse.sizes["z"] - 1


def test_data_file_round_trips(coarse, tmp_path) -> None:
    path = ad.save(coarse, tmp_path / "atlas.nc")
    back = ad.load(path)
    for name in ("max_tilt", "binding", "psi"):
        np.testing.assert_array_equal(back[name].values, coarse[name].values)
        assert back[name].dims == coarse[name].dims
    assert back["max_tilt"].attrs["units"] == "degree"
    assert back.attrs["robot_hash"] == ROBOT.hash
    assert list(back["cranks"].values) == ["free", "locked"]
    assert ad.volumes(back) == ad.volumes(coarse)


def test_volumes_and_headline(coarse) -> None:
    v = ad.volumes(coarse)
    for mode in ad.CRANKS:
        row = v[mode][0.0]
        seq = [row["zero tilt"]] + [row[float(x)] for x in ad.THRESHOLDS_DEG]
        assert all(a >= b for a, b in zip(seq, seq[1:], strict=False))  # nested volumes
    assert v["free"][0.0][45.0] >= v["locked"][0.0][45.0]
    assert "L of workspace" in ad.headline(coarse)


def test_dask_local_cluster_matches_synchronous(coarse) -> None:
    g = (coarse.x.values[:4], coarse.y.values[3:7], coarse.z.values[:1])
    a = at.compute_atlas(ROBOT, COARSE, scheduler="synchronous", grid=g, chunk=5)
    b = at.compute_atlas(ROBOT, COARSE, workers=1, grid=g, chunk=5)
    np.testing.assert_array_equal(a["max_tilt"].values, b["max_tilt"].values)


def test_cli_atlas_and_bad_input(tmp_path) -> None:
    r = CliRunner().invoke(main, ["atlas", "-o", str(tmp_path), "--step", "0.1",
                                  "--azimuth-step", "120", "--z", "0.3", "0.3",
                                  "--scheduler", "synchronous", "--resolution", "5"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "atlas.nc").stat().st_size > 0
    assert (tmp_path / "atlas_home_polar.png").exists()
    for args in (["--step", "0"], ["--step", "nan"], ["--azimuth-step", "-5"],
                 ["--z", "0.9", "0.1"], ["--workers", "0"], ["--torsion", "inf"],
                 ["--accel-g", "nan"], ["--accel-g", "-1"], ["--accel-g", "50"]):
        r = CliRunner().invoke(main, ["atlas", "-o", str(tmp_path), *args,
                                      "--scheduler", "synchronous"])
        assert r.exit_code == 2, (args, r.output)
        assert "Traceback" not in r.output and len(r.output.strip().splitlines()) == 1


def test_rotation_convention() -> None:
    """Azimuth 0 is a rotation about +x (largest_tilt's 'x'), 90 about +y."""
    Rx = at.rotations(0.0, 30.0, 0.0)[0]
    assert Rx[2, 1] == pytest.approx(math.sin(math.radians(30)))
    Ry = at.rotations(90.0, 30.0, 0.0)[0]
    assert Ry[0, 2] == pytest.approx(math.sin(math.radians(30)))


def _random_poses(n: int, seed: int):
    rng = np.random.default_rng(seed)
    pos = np.asarray(ROBOT.home_position) + rng.uniform(-0.25, 0.25, (n, 3))
    R = at.rotations(rng.uniform(0, 360, n), rng.uniform(0, 120, n), rng.uniform(-60, 60, n))
    return pos, R, rng


def test_compiled_checks_agree_with_the_numpy_robot_functions() -> None:
    """design._atlas_kernel against the public numpy path (robot_ik, spherical_tilts,
    clearance, platform_margin): the same stage for every pose, every stage seen,
    and the same margin where all six checks pass."""
    from sixplus3.design import _atlas_kernel as kern
    from sixplus3.kinematics.robot import platform_margin

    pos, R, rng = _random_poses(3000, 1)
    psi = np.radians(rng.uniform(5, 175, (len(pos), 1, 3)))
    packed = kern.pack(ROBOT)
    pm_psi = kern.platform_margins(psi[:, 0], *packed[:2])[:, None]  # psi only (R = I)
    stage, margin = kern.pose_checks(pos, R, psi, pm_psi, packed)
    lim = ROBOT.limits
    cfg = robot_ik(pos, R, psi[:, 0], ROBOT, platform_margins=False)
    th_ok = cfg.ok & np.all((cfg.theta >= lim.theta_min) & (cfg.theta <= lim.theta_max), 1)
    sph_ok = th_ok & np.all(spherical_tilts(cfg) <= lim.spherical, axis=(1, 2))
    legm = np.minimum(cfg.margins.leg_type1, cfg.margins.leg_type2).min(axis=1)
    leg_ok = sph_ok & (legm >= lim.margin)
    clear_ok = leg_ok & (clearance(cfg) >= 0.0)
    pm = platform_margin(cfg.rotation, cfg.P, cfg.position, ROBOT.geometry)
    plat_ok = clear_ok & (pm >= lim.margin)
    ref = (cfg.ok.astype(int) + th_ok + sph_ok + leg_ok + clear_ok + plat_ok)
    np.testing.assert_array_equal(stage[:, 0], ref)
    assert set(np.unique(ref)) == set(range(7))  # every check binds somewhere
    # the platform margin at the rotated poses is the tabulated one at R = I
    np.testing.assert_allclose(pm_psi[cfg.ok, 0], pm[cfg.ok], rtol=1e-9, atol=1e-13)
    np.testing.assert_allclose(margin[plat_ok, 0], np.minimum(pm, legm)[plat_ok],
                               rtol=1e-9, atol=1e-12)
    assert np.all(margin[~plat_ok, 0] == -np.inf)


def test_compiled_leg_grid_agrees_leg_by_leg() -> None:
    """The free search's per-leg checks 1-4 (design._atlas_kernel.leg_grid) against
    robot_ik with every leg at each grid value, on the rows where all three legs solve
    (spherical_tilts needs the whole robot), and the reach check everywhere."""
    from sixplus3.design import _atlas_kernel as kern

    pos, R, _ = _random_poses(400, 2)
    grid = np.radians(np.arange(45.0, 135.1, 15.0))
    stage, score = kern.leg_grid(pos, R, grid, *kern.pack(ROBOT))
    lim = ROBOT.limits
    seen = set()
    for g, v in enumerate(grid):
        cfg = robot_ik(pos, R, np.full((len(pos), 3), v), ROBOT, platform_margins=False)
        reach = cfg.leg_status == 0
        np.testing.assert_array_equal(stage[:, g] > 0, reach)
        th = cfg.theta.reshape(-1, 3, 3)
        th_ok = reach & np.all((th >= lim.theta_min) & (th <= lim.theta_max), axis=2)
        sph_ok = th_ok & np.all(spherical_tilts(cfg) <= lim.spherical, axis=2)
        m = np.minimum(cfg.margins.leg_type1, cfg.margins.leg_type2)
        ok = sph_ok & (m >= lim.margin)
        ref = reach.astype(int) + th_ok + sph_ok + ok
        rows = cfg.ok
        np.testing.assert_array_equal(stage[rows, g], ref[rows])
        np.testing.assert_allclose(score[rows, g][ok[rows]], m[rows][ok[rows]], rtol=1e-9)
        seen |= set(np.unique(ref[rows])) | set(np.unique(ref[~reach.all(axis=1)]))
    assert seen == set(range(5))  # every check binds somewhere


@pytest.mark.parametrize("payload,gravity", [
    ((0.0, (0.0, 0.0, 0.0)), (0.0, 0.0, -9.81)),
    ((1.5, (0.02, -0.01, 0.06)), (3.0, -2.0, 9.0)),  # a payload, an odd mounting
])
def test_atlas_holding_torque_is_pinocchios(payload, gravity) -> None:
    """Check 7: the compiled symbolic statics (dynamics.symbolic.holding_function, CasADi)
    against Pinocchio's closed-loop statics (dynamics.closed_loop, an independent
    derivation), with the robot's payload and mounting."""
    from sixplus3.robot_description.physical import Payload

    robot = Robot(payload=Payload(mass=payload[0], com=payload[1],
                                  inertia=(0.01, 0.02, 0.015, 0.0, 0.001, 0.0)),
                  gravity=gravity)
    rng = np.random.default_rng(3)
    n = 300
    pos = np.asarray(robot.home_position) + rng.uniform(-0.06, 0.06, (n, 3))
    R = at.rotations(rng.uniform(0, 360, n), rng.uniform(0, 170, n), rng.uniform(-90, 90, n))
    psi = np.radians(rng.uniform(45, 135, (n, 3)))
    cfg = robot_ik(pos, R, psi, robot)
    ok = cfg.ok & (cfg.margins.minimum > 0.02)  # away from singular states
    assert ok.sum() > 30
    chk = ac.PoseChecker(robot, 7.5)
    x = np.c_[pos, rotvec_from_matrix(R), psi][ok].T
    tau = np.asarray(chk.hold.map(x.shape[1])(x, chk.setup)).T  # signed
    ref = ClosedLoopDynamics(robot).holding_torques_batch(cfg.q[ok])
    assert np.abs(ref).max() > 0.3  # torques worth comparing
    np.testing.assert_allclose(tau, ref, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(chk.required_torques(pos[ok], R[ok], psi[ok]),
                                  np.abs(tau))


def test_acceleration_criterion_is_pinocchios_inverse_dynamics() -> None:
    """The optional dynamic check: at rest, tau_0 + A a (dynamics.symbolic.
    acceleration_function, CasADi) against Pinocchio's closed-loop inverse dynamics with
    the actuated accelerations of that platform acceleration (ik_jacobian), motors'
    rotor inertia included; and the worst direction |tau_0| + |a| |A_j| reached."""
    from sixplus3.kinematics.robot_fk import ik_jacobian
    from sixplus3.robot_description.physical import Payload

    robot = Robot(payload=Payload(mass=0.8, com=(0.0, 0.01, 0.04)))
    rng = np.random.default_rng(6)
    n = 200
    pos = np.asarray(robot.home_position) + rng.uniform(-0.06, 0.06, (n, 3))
    R = at.rotations(rng.uniform(0, 360, n), rng.uniform(0, 60, n), 0.0)
    psi = np.radians(rng.uniform(60, 120, (n, 3)))
    cfg = robot_ik(pos, R, psi, robot)
    ok = cfg.ok & (cfg.margins.minimum > 0.05)
    assert ok.sum() > 30
    chk = ac.PoseChecker(robot, 7.5, accel_g=1.0)
    x = np.c_[pos, rotvec_from_matrix(R), psi][ok].T
    tau0, A = chk.hold.map(x.shape[1])(x, chk.setup)
    tau0 = np.asarray(tau0).T
    A = np.asarray(A).reshape(9, -1, 3).transpose(1, 0, 2)  # (m, 9, 3)
    a = rng.normal(size=(int(ok.sum()), 3)) * 9.81
    th_ddot = np.einsum("nij,nj->ni", ik_jacobian(cfg.take(ok))[:, :, 0:3], a)
    ref, _ = ClosedLoopDynamics(robot).actuated_inverse_dynamics_batch(
        cfg.q[ok], np.zeros_like(th_ddot), th_ddot)
    assert np.abs(ref - tau0).max() > 0.1  # the acceleration matters
    np.testing.assert_allclose(tau0 + np.einsum("nij,nj->ni", A, a), ref, rtol=0, atol=1e-8)
    # the worst direction: |tau_0| + g |A_j|, attained at a = g sign(tau_0) A_j / |A_j|
    need = chk.required_torques(pos[ok], R[ok], psi[ok])
    j = 4
    u = np.sign(tau0[:, j])[:, None] * A[:, j] / np.linalg.norm(A[:, j], axis=1)[:, None]
    worst = np.abs(tau0[:, j] + 9.81 * np.einsum("ni,ni->n", A[:, j], u))
    np.testing.assert_allclose(need[:, j], worst, rtol=1e-12)


def test_free_candidates_are_the_leg_grid_then_pose_checks() -> None:
    """design._atlas_kernel.free_candidates (one pass, legs' IK reused) against its
    definition composed of the two tested kernels: leg_grid, the best and second best
    value per leg, then pose_checks on the 4 combinations."""
    from sixplus3.design import _atlas_kernel as kern

    pos, R, _ = _random_poses(1500, 4)
    chk = ac.PoseChecker(ROBOT, 7.5)
    grid, packed = chk.psi_grid, chk.packed
    idx, stage, margin, leg_best = kern.free_candidates(pos, R, grid, chk.platform_grid,
                                                        packed)
    st, score = kern.leg_grid(pos, R, grid, *packed)
    np.testing.assert_array_equal(leg_best, st.max(axis=1))
    live = np.all(leg_best >= 4, axis=1)
    assert 100 < live.sum() < len(pos)  # both kinds
    best = np.argmax(score, axis=1)
    masked = score.copy()
    np.put_along_axis(masked, best[:, None], -np.inf, axis=1)
    second = np.where(np.max(masked, axis=1) > -np.inf, np.argmax(masked, axis=1), best)
    ref_idx = np.stack([best] + [np.where(np.arange(3) == i, second, best)
                                 for i in range(3)], axis=1)
    np.testing.assert_array_equal(idx[live], ref_idx[live])
    pm = chk.platform_grid[ref_idx[..., 0], ref_idx[..., 1], ref_idx[..., 2]]
    s_ref, m_ref = kern.pose_checks(pos, R, grid[ref_idx], pm, packed)
    np.testing.assert_array_equal(stage[live], s_ref[live])
    np.testing.assert_array_equal(margin[live], m_ref[live])
    assert {4, 6} <= set(np.unique(stage[live]).tolist())  # clearance fails and passes
    assert np.all(stage[~live] == 0)


def test_acceleration_criterion_only_shrinks_the_atlas() -> None:
    """A stricter torque check (accelerate at 2 g in every direction) never gives a
    larger tilt, free or locked, and binds somewhere (code 7)."""
    xs, ys, zs = ad.position_grid(ROBOT, COARSE.step)
    grid = (xs[::2], ys[::2], zs[(zs > 0.2) & (zs < 0.5)][:2])
    base = at.compute_atlas(ROBOT, COARSE, scheduler="synchronous", grid=grid)
    st = ad.AtlasSettings(**{**COARSE.__dict__, "accel_g": 2.0})
    dyn = at.compute_atlas(ROBOT, st, scheduler="synchronous", grid=grid)
    a = np.nan_to_num(base["max_tilt"].values, nan=-1.0)
    b = np.nan_to_num(dyn["max_tilt"].values, nan=-1.0)
    assert np.all(b <= a)
    assert np.any(b < a)
    assert (dyn["binding"].values == ad.BINDING.index("torque")).sum() > (
        base["binding"].values == ad.BINDING.index("torque")).sum()
    assert dyn.attrs["accel_g"] == 2.0 and "2 g" in dyn.attrs["torque_check"]


def test_local_cluster_workers_leave_ctrl_c_to_the_command() -> None:
    """Ctrl-C (SIGINT to the terminal's whole process group) must reach only the
    command, which closes the cluster and prints one line: the LocalCluster's workers
    ignore SIGINT, and this process's own handler is back afterwards."""
    import signal

    from dask.distributed import Client

    from sixplus3.design import cluster as dc

    before = signal.getsignal(signal.SIGINT)
    cluster = dc._local_cluster(1)
    try:
        assert signal.getsignal(signal.SIGINT) is before
        with Client(cluster) as client:
            seen = client.run(lambda: int(signal.getsignal(signal.SIGINT)))
        assert list(seen.values()) == [int(signal.SIG_IGN)]
    finally:
        cluster.close()
