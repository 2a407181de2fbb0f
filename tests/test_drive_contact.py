"""The drive's position loop in a transient contact (issue 70, dynamics/drive_contact.py):
the model against the two-body closed form (torques held) and against an ODE solver's
solution of the same sampled loop; the site's declaration; the gate's and the rows'
judgement with it.  MuJoCo's measurements of the same contacts are
benchmarks/bench_drive_contact.py's (BENCHMARKS.md)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.drive_contact import DriveCase, contact_peaks, drive_ratio
from sixplus3.dynamics.leg_points import vertex_jacobians
from sixplus3.errors import GeometryError
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.planner.pfl import pfl_matrices, pfl_points
from sixplus3.robot_description import hardware
from sixplus3.robot_description.body_regions import REGIONS, regions
from sixplus3.robot_description.hardware import PositionLoop
from sixplus3.robot_description.leg_links import link_names
from sixplus3.robot_description.robot import Robot

HAND = REGIONS["hand"]


def _case(seed: int, speed: float = 1.0, tau_scale: float = 5.0) -> tuple[DriveCase, float]:
    """A random contact (an inertia like the robot's, a point's Jacobian) and its
    two-body reduced mass with a hand."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(9, 9))
    M = X @ X.T * 0.002 + np.eye(9) * 0.01
    ju = rng.normal(size=9) * 0.1
    Minv = np.linalg.inv(M)
    m = 1.0 / (ju @ Minv @ ju)
    thd = rng.normal(size=9)
    thd *= speed / (ju @ thd)  # the point at ``speed`` along u
    case = DriveCase(Minv[None], ju[None], np.array([speed]),
                     rng.uniform(-tau_scale, tau_scale, (1, 9)), np.full(9, 10.0),
                     np.array([HAND.mass]), np.array([HAND.stiffness]), thd[None])
    return case, m * HAND.mass / (m + HAND.mass)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_with_the_torques_held_the_peak_is_the_two_body_models(seed: int) -> None:
    case, mu = _case(seed, speed=1.3)
    got = contact_peaks(case, PositionLoop(0.0, 0.0), 1000.0)[0]
    assert got == pytest.approx(1.3 * np.sqrt(mu * HAND.stiffness), rel=2e-3)
    # no torque to spare (a cap of zero): the loop cannot push, the torques are held
    held = case._replace(cap=np.zeros(9), tau=np.zeros((1, 9)))
    assert contact_peaks(held, PositionLoop(3000.0, 30.0), 1000.0)[0] == pytest.approx(
        got, rel=1e-12)


def _ode_peak(case: DriveCase, loop: PositionLoop, rate: float, phase: float,
              stop: float = np.inf) -> float:
    """The same contact by scipy's solver: the loop's command sampled each tick from the
    error and the encoder's difference, clipped to the cap, held over the tick; the
    reference standing from ``stop`` on (a tick's boundary: a drive's update)."""
    Minv, ju, v = case.Minv[0], case.ju[0], float(case.speed[0])
    tau, cap = case.tau[0], case.cap
    mH, kH = float(case.mass[0]), float(case.stiffness[0])
    tick = 1.0 / rate
    state = np.zeros(20)  # e (9), e' (9), y, y'
    e_prev, dtau = np.zeros(9), np.zeros(9)
    t0, peak = 0.0, 0.0

    def force(t: float, s: np.ndarray) -> float:
        return kH * max(v * min(t, stop) + ju @ s[:9] - s[18], 0.0)

    def rhs(t: float, s: np.ndarray) -> np.ndarray:
        f = force(t, s)
        return np.r_[s[9:18], Minv @ (dtau - ju * f), s[19], f / mH]

    t1 = (1.0 - phase) * tick
    while t0 < min(0.02, stop + 0.01):
        if abs(t0 - stop) < 1e-9:
            state[9:18] += case.rates[0]  # the reference stands: e' = theta'
        sol = solve_ivp(rhs, (t0, t1), state, rtol=1e-10, atol=1e-14, max_step=tick / 50,
                        dense_output=True)
        ts = np.linspace(t0, t1, 200)
        f = [force(t, sol.sol(t)) for t in ts]
        peak = max(peak, *f)
        state = sol.y[:, -1]
        if peak > 0 and f[-1] == 0.0 and np.isfinite(mH):
            break
        e = state[:9]
        dtau = np.clip(-loop.kp * e - loop.kd * (e - e_prev) * rate, -cap - tau, cap - tau)
        e_prev = e.copy()
        t0, t1 = t1, t1 + tick
    return peak


@pytest.mark.parametrize("seed,loop,rate", [(3, PositionLoop(3000.0, 30.0), 1000.0),
                                            (4, PositionLoop(300.0, 6.0), 1000.0),
                                            (8, PositionLoop(3000.0, 30.0), 10000.0)])
def test_the_sampled_loop_agrees_with_an_ode_solver(seed: int, loop: PositionLoop,
                                                    rate: float) -> None:
    case, _ = _case(seed, speed=0.8)
    for phase in (0.0, 0.5):
        got = contact_peaks(case, loop, rate, phases=(phase,))[0]
        assert got == pytest.approx(_ode_peak(case, loop, rate, phase), rel=3e-3)


def test_a_stiffer_loop_meets_harder_and_the_cap_bounds_its_push() -> None:
    case, _ = _case(5, speed=1.0, tau_scale=0.0)
    held, soft, stiff = (contact_peaks(case, PositionLoop(kp, kd), 1000.0)[0]
                         for kp, kd in ((0, 0), (300, 6), (3000, 30)))
    assert held < soft < stiff
    small = contact_peaks(case._replace(cap=np.full(9, 0.5)), PositionLoop(3000, 30),
                          1000.0)[0]
    assert held < small < stiff


def test_a_broken_case_is_unsafe_not_silent() -> None:
    case, _ = _case(6)
    bad = case._replace(Minv=np.full((1, 9, 9), np.nan))
    assert contact_peaks(bad, PositionLoop(3000, 30), 1000.0)[0] == np.inf


@pytest.mark.parametrize("phase", [0.0, 0.5])
def test_a_clamp_with_its_reference_stopped_agrees_with_an_ode_solver(phase: float) -> None:
    """A clamp (m_H infinite): the loop presses on until the reference stands (here at
    the drive's fourth update after the onset), then toward the standing reference."""
    case, _ = _case(7, speed=0.6)
    case = case._replace(mass=np.array([np.inf]))
    loop = PositionLoop(3000.0, 30.0)
    stop = (1.0 - phase) * 1e-3 + 3e-3
    got = contact_peaks(case, loop, 1000.0, phases=(phase,), stop=stop)[0]
    assert got == pytest.approx(_ode_peak(case, loop, 1000.0, phase, stop), rel=3e-3)
    # a guard never: the same as one after the horizon (where a slower guard meets more:
    # test_the_rows_take_the_loop)
    assert contact_peaks(case, loop, 1000.0, phases=(phase,), stop=1.0)[0] == \
        contact_peaks(case, loop, 1000.0, phases=(phase,))[0]


def test_a_site_declares_its_position_loop(tmp_path) -> None:
    ok = tmp_path / "site.yaml"
    ok.write_text("position_loop: {kp: 3000, kd: 30}\n")
    hw = hardware.load_hardware(ok)
    assert hw.position_loop == PositionLoop(3000.0, 30.0)
    assert hardware.envelope_record(hw)["position_loop"] == {"kp": 3000.0, "kd": 30.0}
    assert hw.guard_detection == hardware.GUARD_DETECTION
    assert hardware.Hardware().position_loop is None
    for bad in ("{kp: 3000}", "{kp: .nan, kd: 1}", "{kp: -1, kd: 1}", "{kp: 1, kd: true}",
                "{kp: 1, kd: 1, ki: 2}", "[3000, 30]"):
        f = tmp_path / "bad.yaml"
        f.write_text(f"position_loop: {bad}\n")
        with pytest.raises(GeometryError, match="position_loop"):
            hardware.load_hardware(f)
    for bad in ("0.002", ".nan", "2", "fast"):  # a faster guard than measured: refused
        f.write_text(f"guard_detection: {bad}\n")
        with pytest.raises(GeometryError, match="guard_detection"):
            hardware.load_hardware(f)
    f.write_text("guard_detection: 0.02\n")
    assert hardware.load_hardware(f).guard_detection == 0.02


ROBOT = Robot.default()


def _states() -> tuple[np.ndarray, object, np.ndarray]:
    rng = np.random.default_rng(11)
    x = np.r_[np.add(ROBOT.home_position, [0.01, -0.02, 0.01]), [0.1, -0.05, 0.08],
              np.add(ROBOT.home_psi, [0.2, -0.1, 0.3])][None]
    cfg = robot_ik(x[:, 0:3], rot.matrix_from_rotvec(x[:, 3:6]), x[:, 6:9], ROBOT,
                   platform_margins=False)
    assert cfg.ok[0]
    return x, cfg, rng.normal(size=(1, 9)) * 3.0


def test_the_gates_drive_ratio_is_at_least_the_held_ones_and_grows_with_the_loop() -> None:
    """At a leg vertex of a real pose: the held loop's ratio is the two-body model's
    along the same normal; a soft and a stiff loop give more."""
    _, cfg, thd = _states()
    Jth, M = vertex_jacobians(ClosedLoopDynamics(ROBOT), cfg.q, ((0, "D"),))[1:]
    Jp = Jth[:, 0]
    v = np.einsum("nij,nj->ni", Jp, thd)
    u = v / np.linalg.norm(v)
    args = (Jp, M, thd, np.zeros((1, 9)), np.full(9, 10.0), HAND)
    held, soft, stiff = (drive_ratio(*args, PositionLoop(kp, kd), 1000.0, [u])[0]
                         for kp, kd in ((0, 0), (300, 6), (3000, 30)))
    A = Jp[0] @ np.linalg.solve(M[0], Jp[0].T)
    m = 1.0 / (u[0] @ A @ u[0])
    mu = m * HAND.mass / (m + HAND.mass)
    two_body = float(u[0] @ v[0]) ** 2 * mu * HAND.stiffness / HAND.transient_force ** 2
    assert held == pytest.approx(two_body, rel=4e-3)
    assert held < soft < stiff


def test_the_rows_take_the_loop() -> None:
    """The NLP's C with a declared loop: the two-body C with a loop of zero gains (and a
    clamp's then too, its reference standing), larger with a stiff loop, for a clamp
    larger still with a slower guard."""
    x, _, _ = _states()
    point = pfl_points(ROBOT, link_names(["legs"]))[1]  # leg0's vertices
    free, clamp = regions(["hand"]), regions(["hand-clamped"])
    C0, K0 = pfl_matrices(ROBOT, x, free, point), pfl_matrices(ROBOT, x, clamp, point)
    hardware.use(hardware.Hardware(position_loop=PositionLoop(0.0, 0.0)))
    np.testing.assert_allclose(pfl_matrices(ROBOT, x, free, point), C0, rtol=4e-3,
                               atol=1e-12)
    np.testing.assert_allclose(pfl_matrices(ROBOT, x, clamp, point), K0, rtol=4e-3,
                               atol=1e-12)
    hardware.use(hardware.Hardware(position_loop=PositionLoop(3000.0, 30.0)))
    C1, K1 = pfl_matrices(ROBOT, x, free, point), pfl_matrices(ROBOT, x, clamp, point)
    hardware.use(hardware.Hardware(position_loop=PositionLoop(3000.0, 30.0),
                                   guard_detection=0.05))
    K2 = pfl_matrices(ROBOT, x, clamp, point)

    def trace(C: np.ndarray) -> np.ndarray:
        return np.trace(C, axis1=-2, axis2=-1)

    assert np.all(trace(C1) > trace(C0))
    assert np.all(trace(K1) > trace(K0))
    # a slower guard: never less, more where the press outlasts the first impact
    assert np.all(trace(K2) >= trace(K1)) and np.any(trace(K2) > 1.05 * trace(K1))


def test_the_simulated_drive_defaults_to_the_sites_loop(tmp_path) -> None:
    """`simulate` and `validate --simulate` run the site's declared loop unless --kp or
    --kd is given; without a declaration the default drive (300 / 6)."""
    import click
    from click.testing import CliRunner

    from sixplus3.cli.app import drive_gains

    @click.command()
    @drive_gains
    def show(kp: float, kd: float) -> None:
        click.echo(f"{kp:g} {kd:g}")

    runner = CliRunner()
    assert runner.invoke(show, []).output.strip() == "300 6"
    hardware.use(hardware.Hardware(position_loop=PositionLoop(3000.0, 30.0)))
    assert runner.invoke(show, []).output.strip() == "3000 30"
    assert runner.invoke(show, ["--kp", "500"]).output.strip() == "500 30"


def test_a_person_met_on_a_stiffer_drive_than_judged_is_told(capsys) -> None:
    """`simulate --contact` on a drive stiffer than the loop the gate judged with (the
    site's, else the default drive) says so on stderr; as stiff or softer: silent."""
    from sixplus3.cli.contact import _stiffer_than_judged

    _stiffer_than_judged(300.0, 6.0, True)
    assert capsys.readouterr().err == ""
    _stiffer_than_judged(3000.0, 30.0, True)
    assert "stiffer than the loop" in capsys.readouterr().err
    _stiffer_than_judged(3000.0, 30.0, False)  # nobody in the way
    assert capsys.readouterr().err == ""
    hardware.use(hardware.Hardware(position_loop=PositionLoop(3000.0, 30.0)))
    _stiffer_than_judged(3000.0, 30.0, True)
    assert capsys.readouterr().err == ""
