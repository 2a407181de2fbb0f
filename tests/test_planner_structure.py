"""The planner's structure (issue: planner v2): an immutable Problem, a frozen Solution,
the transcription's families against the exact cubic motion, and the bounded caches."""

from __future__ import annotations

import dataclasses
import threading
import time
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from sixplus3.cache import BoundedCache
from sixplus3.errors import InputError
from sixplus3.planner import transcription
from sixplus3.planner.ocp import plan
from sixplus3.planner.problem import Problem
from sixplus3.planner.solution import sample_cubic
from sixplus3.planner.solvers import ipopt_solver
from sixplus3.planner.strategy import solve
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()
TWO = {"name": "two", "nodes_per_segment": 6, "waypoints": [
    {"position": [0, 0, 0.58]}, {"position": [0.02, 0.0, 0.59], "rpy": [5, 0, 0]}]}


def test_the_problem_is_immutable_and_unchanged_by_a_solve() -> None:
    problem = Problem(task_from_dict(TWO), ROBOT)
    with pytest.raises(AttributeError, match="immutable"):
        problem.limits = ROBOT.limits  # type: ignore[misc]
    before = dict(vars(problem))
    sol = solve(problem)
    assert sol.is_feasible()
    after = vars(problem)
    assert after.keys() == before.keys()
    assert all(after[k] is before[k] for k in before)


def test_the_robot_is_required_below_the_top_level_helper() -> None:
    with pytest.raises(InputError, match="robot must be a Robot"):
        Problem(task_from_dict(TWO), None)  # type: ignore[arg-type]


def test_a_solution_is_frozen() -> None:
    sol = plan(task_from_dict(TWO), ROBOT)
    with pytest.raises(dataclasses.FrozenInstanceError):
        sol.final_time = 0.0  # type: ignore[misc]
    slower = sol.replace(final_time=2 * sol.final_time)
    assert slower.final_time == 2 * sol.final_time and slower.x is sol.x


def test_the_integration_and_midpoint_rows_are_exact_on_piecewise_cubics() -> None:
    """A motion whose acceleration is linear between nodes meets the integration rows
    with zero residual, and the midpoint states are the cubic's at the midpoints; a
    perturbed node does not."""
    rng = np.random.default_rng(3)
    N, n = 7, 9
    h = rng.uniform(0.005, 0.02, N)
    t = np.r_[0.0, np.cumsum(h)]
    u = rng.normal(0, 50, (N + 1, n))
    x0, v0 = rng.normal(0, 1, n), rng.normal(0, 1, n)
    x, xd = [x0], [v0]
    for k in range(N):
        x.append(x[-1] + h[k] * xd[-1] + h[k] ** 2 * (2 * u[k] + u[k + 1]) / 6)
        xd.append(xd[-1] + h[k] * (u[k] + u[k + 1]) / 2)
    # the states so integrated are the cubic's: sampled from each interval's start,
    # the cubic reaches the next node (the sampler starts every interval afresh)
    ends = sample_cubic(t, np.array(x), np.array(xd), u, t[1:] - 1e-15)
    np.testing.assert_allclose(ends[0], np.array(x)[1:], atol=1e-9)
    np.testing.assert_allclose(ends[1], np.array(xd)[1:], atol=1e-9)
    X, XD, U = (ca.DM(np.array(a).T) for a in (x, xd, u))
    Hm = ca.DM(np.tile(h, (n, 1)))
    res = np.array(transcription.integration_rows(X, XD, U, Hm))
    assert np.abs(res).max() < 1e-12
    xm, xdm, um = (np.array(a).T for a in transcription.midpoint_states(X, XD, U, Hm))
    ref = sample_cubic(t, np.array(x), np.array(xd), u, (t[:-1] + t[1:]) / 2)
    for a, b in zip((xm, xdm, um), ref, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-10)
    bad = np.array(x)
    bad[3, 0] += 1e-6
    res = np.array(transcription.integration_rows(ca.DM(bad.T), XD, U, Hm))
    assert np.abs(res).max() >= 1e-6 - 1e-12


def test_the_type2_rows_bound_is_the_weakest_that_guarantees_the_margin() -> None:
    """det J-hat >= g(m) = m (3 - m^2) / 2 implies sigma_min >= m for every matrix with
    unit rows, and no weaker bound does (a matrix with sigma_1 = sigma_2 has |det| =
    g(sigma_min)).  On the robot: the CasADi det J-hat of each leg and the numeric
    kinematics' type II margin (sigma_min) obey |det| <= g(margin)."""
    from scipy.spatial.transform import Rotation

    from sixplus3.dynamics.symbolic import symbolic_robot
    from sixplus3.kinematics.robot import robot_ik

    g = transcription.type2_det_bound
    rng = np.random.default_rng(7)
    for _ in range(5000):
        A = rng.normal(size=(3, 3))
        A[2] = A[1] + rng.normal(scale=10 ** rng.uniform(-3, 0), size=3)
        A /= np.linalg.norm(A, axis=1, keepdims=True)
        s_min = np.linalg.svd(A, compute_uv=False)[-1]
        assert abs(np.linalg.det(A)) <= g(s_min) + 1e-12
    for m in (0.02, 0.05, 0.2):
        # tight: three unit rows at 120 deg about z, each at phi from it, have singular
        # values sqrt(1.5) sin(phi) (twice) and sqrt(3) cos(phi)
        phi = np.arccos(m / np.sqrt(3))
        az = np.radians([0, 120, 240])
        A = np.c_[np.sin(phi) * np.cos(az), np.sin(phi) * np.sin(az), np.full(3, np.cos(phi))]
        assert np.linalg.svd(A, compute_uv=False)[-1] == pytest.approx(m)
        assert abs(np.linalg.det(A)) == pytest.approx(g(m), rel=1e-12)
    sr = symbolic_robot(ROBOT)
    n = 200
    pos = np.asarray(ROBOT.home_position) + rng.uniform(-0.06, 0.06, (n, 3))
    R = Rotation.from_rotvec(rng.uniform(-0.6, 0.6, (n, 3))).as_matrix()
    psi = rng.uniform(np.radians(50), np.radians(130), (n, 3))
    cfg = robot_ik(pos, R, psi, ROBOT)
    ok = cfg.ok
    assert ok.sum() > 50
    x = np.c_[pos, Rotation.from_matrix(R).as_rotvec(), psi][ok]
    det = np.abs(np.array(sr.margins.map(len(x))(x.T)[1])).T  # (n, 3)
    margin = cfg.margins.leg_type2[ok]
    assert np.all(det <= g(margin) + 1e-9)
    assert np.max(det / g(margin)) > 0.5  # the bound is not loose on the robot either


def test_a_built_solver_is_shared_by_tasks_of_one_size_only() -> None:
    a = Problem(task_from_dict(TWO), ROBOT)
    other = {**TWO, "waypoints": [{"position": [0, 0, 0.58]},
                                  {"position": [-0.01, 0.01, 0.57]}]}
    b = Problem(task_from_dict(other), ROBOT)
    c = Problem(task_from_dict({**TWO, "nodes_per_segment": 7}), ROBOT)
    assert ipopt_solver(a) is ipopt_solver(b)
    assert ipopt_solver(c) is not ipopt_solver(a)


def test_the_bounded_cache_evicts_the_least_recently_used() -> None:
    cache: BoundedCache[int] = BoundedCache(2)
    made: list[str] = []

    def make(key: str) -> int:
        made.append(key)
        return len(made)

    assert cache.get("a", lambda: make("a")) == 1
    assert cache.get("b", lambda: make("b")) == 2
    assert cache.get("a", lambda: make("a")) == 1  # a hit: "a" is now the newest
    cache.get("c", lambda: make("c"))  # evicts "b"
    assert "a" in cache and "c" in cache and "b" not in cache and len(cache) == 2
    assert made == ["a", "b", "c"]
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="positive integer"):
            BoundedCache(bad)  # type: ignore[arg-type]


def test_the_bounded_cache_builds_a_product_once_under_concurrency() -> None:
    cache: BoundedCache[object] = BoundedCache(4)
    calls = []

    def slow() -> object:
        calls.append(1)
        time.sleep(0.05)
        return object()

    out: list[object] = []
    threads = [threading.Thread(target=lambda: out.append(cache.get("k", slow)))
               for _ in range(6)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert len(calls) == 1 and len(out) == 6 and all(o is out[0] for o in out)


def test_no_planner_module_is_over_400_lines() -> None:
    planner = Path(__file__).resolve().parents[1] / "planner"
    sizes = {p.name: len(p.read_text().splitlines()) for p in planner.glob("*.py")}
    assert len(sizes) >= 10
    assert {k: v for k, v in sizes.items() if v > 400} == {}


def test_the_projects_errors_leave_these_functions_with_value_and_valid() -> None:
    """Bad input to these library functions raises the project's errors (an InputError
    is still a ValueError), naming the value and the valid range."""
    from sixplus3 import progress
    from sixplus3.design.search import check_steps, optimize
    from sixplus3.design.workspace import halfplane_grid
    from sixplus3.errors import Sixplus3Error
    from sixplus3.planner.certificate import retime_path
    from sixplus3.robot_description.geometry import LegGeometry

    calls = [
        (lambda: check_steps(0.01, 0.001, 0.0), "ws_step"),
        (lambda: optimize(seed_tolerance=1.5), "seed_tolerance"),
        (lambda: optimize(max_seeds=0), "max_seeds"),
        (lambda: halfplane_grid(LegGeometry(), 0.5), "workspace step"),
        (lambda: retime_path(ROBOT, ROBOT.limits, np.array([0.0, 1.0]), lambda s: s),
         "increasing"),
        (lambda: progress.set_level(7), "reporting level"),
    ]
    for call, words in calls:
        with pytest.raises(InputError, match=words) as err:
            call()
        assert isinstance(err.value, Sixplus3Error) and err.value.valid is not None


def test_toppra_failure_is_named_and_the_baseline_catches_only_it(monkeypatch) -> None:
    """TOPP-RA with no feasible parametrisation raises InfeasibleTaskError (limit
    "toppra"), which the baseline turns into "no baseline"; any other error (a bug) is
    not swallowed."""
    from sixplus3.errors import InfeasibleTaskError
    from sixplus3.planner import baseline
    from sixplus3.planner.statics import choose_static_psi
    from sixplus3.planner.toppra_baseline import toppra_trajectory

    problem = Problem(task_from_dict(TWO), ROBOT)
    psi = choose_static_psi(problem.task, ROBOT, problem.limits, False, {0, 1})
    wx = problem.waypoint_states(psi)
    line = wx[0] + np.linspace(0.0, 1.0, 11)[:, None] * (wx[1] - wx[0])
    weak = ROBOT.limits.tightened(torque=0.01)  # below the holding torque
    with pytest.raises(InfeasibleTaskError, match="TOPP-RA found no") as err:
        toppra_trajectory(ROBOT, line, weak, gridpoints=50)
    assert err.value.limit == "toppra"

    def refuse(*args, **kwargs):
        raise InfeasibleTaskError("TOPP-RA found no feasible parametrisation", None, "toppra")

    monkeypatch.setattr(baseline, "toppra_trajectory", refuse)
    base, why = baseline.baseline_plan(problem, psi)
    assert base is None and "TOPP-RA found no" in why

    def bug(*args, **kwargs):
        raise RuntimeError("a bug")

    monkeypatch.setattr(baseline, "toppra_trajectory", bug)
    with pytest.raises(RuntimeError, match="a bug"):
        baseline.baseline_plan(problem, psi)


def test_the_lifted_torque_balance_is_todays_where_its_closures_hold() -> None:
    """dynamics.lifted (the planner-v2 study): with the legs' joint values, rates and
    accelerations from the closed forms, the closure rows vanish and the lifted balance
    equals today's torque rows (node_p rows 0-9) to rounding; a lifted value off its
    closed form shows in its closure row."""
    from sixplus3.dynamics.lifted import lifted_functions
    from sixplus3.dynamics.symbolic import home_x, setup_parameters, symbolic_robot
    from sixplus3.robot_description.robot import Robot

    robot = Robot.default()
    F, sr, p = lifted_functions(robot), symbolic_robot(robot), setup_parameters(robot)
    rng = np.random.default_rng(3)
    for _ in range(4):
        x = home_x(robot) + np.r_[rng.normal(0, 0.02, 3), rng.normal(0, 0.2, 6)]
        xd, xdd, tau = rng.normal(0, 0.5, 9), rng.normal(0, 20, 9), rng.normal(0, 3, 9)
        qv, qd, qdd = (np.array(v).ravel() for v in F["lift"](x, xd, xdd))
        assert np.abs(np.array(F["closure"](x, xd, xdd, qv, qd, qdd))).max() < 1e-12
        lifted = np.array(F["balance"](x, xd, xdd, tau, qv, qd, qdd, p)).ravel()
        today = np.array(sr.node_p(x, xd, xdd, tau, p)).ravel()[0:9]
        np.testing.assert_allclose(lifted, today, atol=1e-9 * max(1.0, np.abs(today).max()))
        off = qd.copy()
        off[4] += 1e-3
        rows = np.array(F["closure"](x, xd, xdd, qv, off, qdd)).ravel()
        assert rows[27 + 4] == pytest.approx(1e-3) and np.abs(np.delete(rows, 31)).max() == 0


def test_the_implicit_closures_reproduce_todays_torques() -> None:
    """dynamics.lifted.implicit_functions: at a state from the closed forms, the tree's 27
    loop-closure rows and their rates vanish, and its 36 equations of motion (linear in
    the torques and the 27 closure forces) give today's torques; a joint value off the
    closed form breaks a closure."""
    from sixplus3.dynamics.lifted import NQ, implicit_functions, lifted_functions
    from sixplus3.dynamics.symbolic import home_x, setup_parameters, symbolic_robot
    from sixplus3.robot_description.robot import Robot

    robot = Robot.default()
    L, G = lifted_functions(robot), implicit_functions(robot)
    sr, p = symbolic_robot(robot), setup_parameters(robot)
    rng = np.random.default_rng(4)
    for _ in range(3):
        x = home_x(robot) + np.r_[rng.normal(0, 0.02, 3), rng.normal(0, 0.2, 6)]
        xd, xdd = rng.normal(0, 0.5, 9), rng.normal(0, 20, 9)
        qv, qd, qdd = (np.array(v).ravel() for v in L["lift"](x, xd, xdd))
        assert np.abs(np.array(G["closure"](x, xd, xdd, qv, qd, qdd))).max() < 1e-12
        f0 = np.array(G["dynamics"](x, xd, xdd, np.zeros(9), qv, qd, qdd, np.zeros(NQ), p))
        A = np.hstack([np.array(G["dynamics"](x, xd, xdd, e[:9], qv, qd, qdd, e[9:], p)) - f0
                       for e in np.eye(36)])
        tau_lam = np.linalg.solve(A, -f0.ravel())
        np.testing.assert_allclose(tau_lam[:9], np.array(sr.tau(x, xd, xdd)).ravel(),
                                   atol=1e-10)
        off = qv.copy()
        off[1] += 1e-3  # leg 0's theta_s2
        assert np.abs(np.array(G["closure"](x, xd, xdd, off, qd, qdd))[:27]).max() > 1e-5
