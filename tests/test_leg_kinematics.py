"""Leg kinematics (paper §III-IV): behaviour checks against independent recomputation."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sixplus3.errors import ConvergenceError, GeometryError, InputError, UnreachableError
from sixplus3.kinematics.leg import leg_eval, leg_fk, leg_fk_point, leg_ik, leg_ik_point
from sixplus3.robot_description.assembly import DEFAULT_MODE, AssemblyMode
from sixplus3.robot_description.geometry import LegGeometry, LegLoad

GEO = LegGeometry()
ALL_MODES = AssemblyMode.all()


def random_points(n: int, seed: int) -> np.ndarray:
    """Points spread over (and beyond) the torus of the default leg [m]."""
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform(-0.34, 0.34, n), rng.uniform(-0.2, 0.7, n),
                 rng.uniform(-0.4, 0.6, n)]


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


# ----------------------------------------------------------------- geometry
def test_geometry_defaults_are_the_papers() -> None:
    g = LegGeometry()
    assert (g.l1, g.dp, g.l2, g.l3, g.l4, g.l5, g.l6, g.l7) == (
        0.35, 0.35, 0.139, 0.139, 0.35, 0.35, 0.13, 0.13)
    assert (g.ex, g.fx, g.ey, g.fy, g.ez, g.fz) == (0.097, 0.097, 0.02, -0.02, 0.0, 0.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.l1 = 0.3  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "param"),
    [
        ({"l2": -0.1}, "l2"),
        ({"l4": 0.0}, "l4"),
        ({"dp": float("nan")}, "dp"),
        ({"l1": 350.0}, "l1"),  # millimetres by mistake
        ({"ey": -0.03}, "ey"),  # E must be the +y_b side (linked to B)
        ({"l5": 2.0}, "l5"),  # RUS chain at C can never close
        ({"ex": "0.1"}, "ex"),
    ],
)
def test_geometry_rejects_bad_values_naming_the_parameter(kwargs: dict, param: str) -> None:
    with pytest.raises(GeometryError) as err:
        LegGeometry(**kwargs)
    assert err.value.parameter == param
    assert param in str(err.value) and "must be" in str(err.value)


def test_symmetric_constructor() -> None:
    g = LegGeometry.symmetric(l2=0.12, l4=0.3, ex=0.08)
    assert (g.l3, g.l5, g.fx, g.fy) == (0.12, 0.3, 0.08, -g.ey)


# ----------------------------------------------------------------- inverse kinematics
@pytest.mark.parametrize("mode", ALL_MODES, ids=str)
def test_ik_closes_every_chain(mode: AssemblyMode) -> None:
    """Every solved point satisfies the loop equations, recomputed here from the angles."""
    P = random_points(400, seed=1)
    s = leg_ik(P, mode=mode)
    assert 100 < s.ok.sum() < len(P)  # both reachable and unreachable points are present
    for i in np.flatnonzero(s.ok):
        t1, t2, t3 = s.theta[i]
        ts2, ts3 = s.theta_s[i]
        Q = rot_x(t1) @ rot_x(ts2) @ rot_z(ts3 - math.pi / 2)  # paper eq. 1
        d = GEO.l1 * np.array([0, math.cos(t1), math.sin(t1)])
        g = np.array([GEO.l6, GEO.l2 * math.cos(t2), GEO.l2 * math.sin(t2)])
        h = np.array([-GEO.l7, GEO.l3 * math.cos(t3), GEO.l3 * math.sin(t3)])
        e = d + Q @ GEO.e_b
        f = d + Q @ GEO.f_b
        np.testing.assert_allclose(d + Q @ [GEO.dp, 0, 0], P[i], atol=1e-12)
        np.testing.assert_allclose(s.Q[i], Q, atol=1e-12)
        assert abs(np.linalg.norm(e - g) - GEO.l4) < 1e-12
        assert abs(np.linalg.norm(f - h) - GEO.l5) < 1e-12
        np.testing.assert_allclose(s.e[i], e, atol=1e-12)
        # The branch signs are what the mode says.
        assert np.sign(math.cos(ts3)) == mode.signs[1] or abs(math.cos(ts3)) < 1e-9
        assert -math.pi / 2 <= t1 < 1.5 * math.pi


def test_sixteen_branches_are_distinct_solutions() -> None:
    p = np.array([0.05, 0.42, 0.12])
    sols = []
    for mode in ALL_MODES:
        s = leg_ik_point(p, mode=mode)
        sols.append(np.r_[s.theta[0], s.theta_s[0]])
    sols = np.array(sols)
    dist = np.abs(sols[:, None, :] - sols[None, :, :]).max(axis=2)
    assert np.all(dist[~np.eye(16, dtype=bool)] > 1e-3)


def test_default_mode_is_the_papers_assembly() -> None:
    """For points of the design half-plane the default mode keeps D above P and E on B's side."""
    s = leg_ik_point([0.0, 0.35 * math.sqrt(2), 0.0])
    np.testing.assert_allclose(np.degrees(s.theta[0, 0]), 45.0, atol=1e-12)
    assert s.d[0, 2] > 0 and s.e[0, 0] > 0 > s.f[0, 0]
    assert DEFAULT_MODE.name == "++++" and AssemblyMode.parse("default") == DEFAULT_MODE


# ----------------------------------------------------------------- Jacobians
@pytest.mark.parametrize("mode", ALL_MODES, ids=str)
def test_dtheta_dp_matches_finite_differences(mode: AssemblyMode) -> None:
    P = random_points(3000, seed=2)
    s = leg_ik(P, mode=mode)
    keep = np.flatnonzero(s.ok & (s.margin_I > 1e-2) & (s.margin_II > 1e-2))[:250]
    assert len(keep) >= 200
    h = 1e-6
    fd = np.stack([
        (leg_ik(P[keep] + h * np.eye(3)[k], mode=mode).theta
         - leg_ik(P[keep] - h * np.eye(3)[k], mode=mode).theta) / (2 * h)
        for k in range(3)], axis=2)
    analytic = s.dtheta_dp()[keep]
    scale = np.maximum(1.0, np.abs(fd).max(axis=(1, 2)))[:, None, None]
    assert np.all(np.abs(analytic - fd) / scale < 1e-6)


def test_static_torques_do_the_virtual_work_of_the_force() -> None:
    """tau . d(theta) = f . dp for small displacements (FD of the IK, not of J)."""
    rng = np.random.default_rng(3)
    P = random_points(2000, seed=3)
    s = leg_ik(P)
    keep = np.flatnonzero(s.ok & (s.margin_I > 5e-2) & (s.margin_II > 5e-2))[:200]
    f = rng.normal(scale=10.0, size=(len(keep), 3))
    dp = rng.normal(size=(len(keep), 3))
    dp *= 1e-6 / np.linalg.norm(dp, axis=1, keepdims=True)
    dth = (leg_ik(P[keep] + dp).theta - leg_ik(P[keep] - dp).theta) / 2
    forces = np.zeros((len(s), 3))
    forces[keep] = f
    tau = s.torques(forces)[keep]
    work_actuators = np.sum(tau * dth, axis=1)
    work_force = np.sum(f * dp, axis=1)
    np.testing.assert_allclose(work_actuators, work_force, rtol=1e-5, atol=1e-12)


@pytest.mark.parametrize("mode", ALL_MODES[::3], ids=str)
def test_collinear_motors_torque_sum_is_moment_about_axis(mode: AssemblyMode) -> None:
    """tau1 + tau2 + tau3 = ((p - a) x f) . x_f: the three actuated axes are collinear."""
    rng = np.random.default_rng(4)
    P = random_points(1000, seed=4)
    s = leg_ik(P, mode=mode)
    keep = np.flatnonzero(s.ok & (s.margin_II > 1e-3) & (s.margin_I > 1e-3))
    f = rng.normal(scale=20.0, size=(len(keep), 3))
    tau = np.einsum("nij,nj->ni", s.M[keep], f)
    moment = np.cross(P[keep], f)[:, 0]
    np.testing.assert_allclose(tau.sum(axis=1), moment, atol=1e-9 * (1 + np.abs(tau).max()))


def test_tau_ext_closed_form_against_dense_sampling_of_F() -> None:
    """max over F = F_g + 2 m g B^3 of max_j |tau_j|, sampled densely, equals the closed form."""
    load = LegLoad()
    mg = load.mass * load.gravity
    alphas = np.linspace(0, 2 * np.pi, 721)[:-1]
    k = np.arange(20000) + 0.5  # Fibonacci sphere
    phi = np.arccos(1 - 2 * k / k.size)
    th = np.pi * (1 + 5**0.5) * k
    ball = np.c_[np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)]
    s = leg_ik(np.array([[0.0, 0.42, 0.05], [0.1, 0.3, 0.2], [-0.2, 0.45, -0.1]]))
    assert s.ok.all()
    for i in range(len(s)):
        M = s.M[i]
        # max_j |m_j . (u(alpha) + 2 m g v)|: the ball part is separable from alpha.
        grav = mg * (M[:, 1][:, None] * np.cos(alphas) + M[:, 2][:, None] * np.sin(alphas))
        acc = load.accel_g * mg * (M @ ball.T)
        sampled = max(np.max(np.abs(grav[j][:, None] + acc[j][None, :])) for j in range(3))
        assert sampled <= s.tau_ext[i] * (1 + 1e-12)
        assert sampled >= s.tau_ext[i] * (1 - 1e-3)


# ----------------------------------------------------------------- singularities
def _segments_crossing_type2(n_seg: int, n_steps: int, seed: int):
    rng = np.random.default_rng(seed)
    a = random_points(n_seg, seed)
    b = a + rng.normal(scale=0.08, size=a.shape)
    t = np.linspace(0, 1, n_steps)
    for i in range(n_seg):
        pts = a[i] + t[:, None] * (b[i] - a[i])
        s = leg_ik(pts)
        if not s.ok.all() or s.margin_I.min() < 1e-2:
            continue  # stay in the interior: no type I along the segment
        yield s


def test_proposition1_det_J_and_det_J_tilde_change_sign_together() -> None:
    crossings = 0
    for s in _segments_crossing_type2(3000, 200, seed=5):
        flips_j = np.flatnonzero(np.sign(s.det_J[1:]) != np.sign(s.det_J[:-1]))
        flips_jt = np.flatnonzero(np.sign(s.det_J_tilde[1:]) != np.sign(s.det_J_tilde[:-1]))
        assert np.array_equal(flips_j, flips_jt)
        crossings += len(flips_j)
    assert crossings >= 10  # the property was exercised, not vacuously true


def test_type2_margin_vanishes_at_a_det_J_sign_change() -> None:
    for s in _segments_crossing_type2(3000, 200, seed=6):
        flips = np.flatnonzero(np.sign(s.det_J[1:]) != np.sign(s.det_J[:-1]))
        if len(flips):
            i = flips[0]
            # bisect between the two samples down to 1e-12 m
            lo, hi = s.p[i], s.p[i + 1]
            sign_lo = np.sign(s.det_J[i])
            for _ in range(45):
                mid = (lo + hi) / 2
                if np.sign(leg_ik(mid).det_J[0]) == sign_lo:
                    lo = mid
                else:
                    hi = mid
            near = leg_ik(np.array([lo, hi]))
            assert near.margin_II.max() < 1e-6
            assert set(near.singularity()) == {"type2"}
            assert np.all(np.isfinite(near.theta)) and not np.any(np.isnan(near.M))
            return
    pytest.fail("no type II crossing found")


def test_near_singular_and_boundary_points_leak_no_nan() -> None:
    g = GEO
    # On the torus boundary (|k| = r), exactly on the axis, near type I (p - d along
    # x_f), at A, far away, and non-finite input.
    t = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    boundary = np.c_[g.dp * np.cos(t), g.l1 + g.dp * np.sin(t), np.zeros_like(t)]
    d = np.array([0.0, g.l1 * math.cos(0.7), g.l1 * math.sin(0.7)])
    type1 = d + np.array([g.dp, 0, 0]) * np.array([[1.0], [1 - 1e-12], [1 - 1e-8]])
    specials = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [3.0, 3.0, 3.0],
                         [np.nan, 0.3, 0.1], [np.inf, 0.3, 0.1], [0.0, 1e-300, 0.0]])
    pts = np.vstack([boundary, boundary * (1 - 1e-13), type1, specials])
    for mode in ALL_MODES:
        s = leg_ik(pts, mode=mode)
        for name in s.__dataclass_fields__:
            arr = getattr(s, name)
            assert not np.any(np.isnan(arr)), f"NaN in {name} ({mode})"
        assert not np.any(np.isnan(s.J)) and not np.any(np.isnan(s.dtheta_dp()))
        assert s.status[-4] != 0 and s.status[-3] != 0 and s.status[-6] != 0
        failed = ~s.ok
        assert np.all(s.tau_ext[failed] == np.inf)
        assert np.all(s.margin_I[failed] == 0) and np.all(s.margin_II[failed] == 0)
        ev = leg_eval(pts, mode=mode)
        assert not np.any(np.isnan(ev.tau_ext)) and not np.any(np.isnan(ev.theta))
    s = leg_ik(type1[:1])
    assert s.ok[0] and s.singularity()[0] == "type1"


def test_unreachable_point_names_the_chain() -> None:
    with pytest.raises(UnreachableError) as err:
        leg_ik_point([0.0, 1.5, 0.0])
    assert err.value.chain == "RU"
    # A very short distal link at B: the RU chain reaches, the RUS chain at B does not.
    short_b = dataclasses.replace(GEO, l2=0.02, l4=0.05)
    with pytest.raises(UnreachableError) as err:
        leg_ik_point([0.0, 0.45, 0.1], geometry=short_b)
    assert err.value.chain == "RUS-B"
    assert "RUS chain B" in str(err.value)
    with pytest.raises(InputError):
        leg_ik_point([0.0, np.nan, 0.1])
    with pytest.raises(InputError):
        leg_ik_point([0.0, 0.1])


def test_batched_eval_agrees_with_full_ik() -> None:
    P = random_points(5000, seed=7)
    s = leg_ik(P)
    e = leg_eval(P)
    np.testing.assert_array_equal(s.status, e.status)
    for name in ("det_J", "det_K", "margin_I", "margin_II", "tau_ext"):
        np.testing.assert_allclose(getattr(e, name), getattr(s, name), rtol=1e-12, atol=0)
    np.testing.assert_allclose(e.theta, s.theta, atol=1e-14)


# ----------------------------------------------------------------- forward kinematics
def test_fk_round_trip_and_accuracy() -> None:
    P = random_points(3000, seed=8)
    s = leg_ik(P)
    ok = s.ok & (s.margin_I > 1e-3) & (s.margin_II > 1e-3)
    # From the IK's own configuration (the trajectory use case) FK lands on P to 1e-12 m.
    tracked = leg_fk(s.theta[ok], hint_theta_s=s.theta_s[ok])
    assert tracked.ok.all()
    assert np.abs(tracked.p - P[ok]).max() < 1e-12
    # From a small perturbation of it, too (away from type II where assemblies merge).
    well = s.ok & (s.margin_I > 5e-2) & (s.margin_II > 5e-2)
    rng = np.random.default_rng(8)
    near = leg_fk(s.theta[well], hint_theta_s=s.theta_s[well]
                  + rng.normal(scale=1e-2, size=(well.sum(), 2)))
    assert near.ok.all() and np.abs(near.p - P[well]).max() < 1e-12
    # Without a hint FK returns *an* assembly of the same mode: IK(FK(theta)) = theta.
    free = leg_fk(s.theta[ok])
    assert free.ok.all()
    again = leg_ik(free.p)
    assert np.abs(np.angle(np.exp(1j * (again.theta - s.theta[ok])))).max() < 1e-10
    # ... and it is the IK's own point for the great majority of them.
    assert np.mean(np.abs(free.p - P[ok]).max(axis=1) < 1e-12) > 0.97


def test_fk_reports_failure() -> None:
    with pytest.raises(ConvergenceError):
        leg_fk_point([0.0, -1.4, -1.4])  # cranks pointing down into the base: no assembly
    with pytest.raises(InputError):
        leg_fk_point([0.0, np.nan, 1.0])
