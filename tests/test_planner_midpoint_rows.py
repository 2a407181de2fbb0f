"""The midpoint rows (``PlannerOptions.midpoint_rows``): "motion" imposes the geometric
path rows at the nodes only; "all" (the earlier formulation) at the midpoints too.  The
two are the same NLP but for those rows, plan the same motions, and a geometric limit
the dense check finds violated between the nodes is re-solved with every row."""

from __future__ import annotations

import dataclasses
import types

import casadi as ca
import numpy as np
import pytest

from sixplus3.dynamics.symbolic import home_x, symbolic_robot
from sixplus3.errors import InputError
from sixplus3.planner import solution, strategy
from sixplus3.planner.nlp import Bounds
from sixplus3.planner.ocp import PlannerOptions, Problem
from sixplus3.planner.task import task_from_dict
from sixplus3.planner.transcription import MIDPOINT_ROWS, NODE_ROWS, build_nlp, layout
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()

#: three small tasks of one segment: a tilt and lift, a translation, a torsion
TASKS = [
    {"name": "lift_tilt", "nodes_per_segment": 10,
     "waypoints": [{"position": [0, 0, 0.58]},
                   {"position": [0.03, 0.0, 0.61], "rpy": [10, 0, 0]}]},
    {"name": "slide", "nodes_per_segment": 10,
     "waypoints": [{"position": [-0.03, 0.02, 0.59]},
                   {"position": [0.03, -0.01, 0.59], "rpy": [0, -8, 0]}]},
    {"name": "twist", "nodes_per_segment": 10,
     "waypoints": [{"position": [0, 0, 0.59], "rpy": [0, 0, -15]},
                   {"position": [0, 0.02, 0.60], "rpy": [5, 0, 20]}]},
]


def test_the_motion_rows_are_the_same_rows_less_the_geometric_ones_at_the_midpoints(
        ) -> None:
    """Both NLPs evaluated at one point: the same integration, node, smoothness and
    duration rows, and at every midpoint exactly the chosen rows of the full set."""
    node = symbolic_robot(ROBOT).node
    segments = (4,)
    full = build_nlp(node, 1, segments, 1e-4)
    part = build_nlp(node, 1, segments, 1e-4, MIDPOINT_ROWS["motion"])
    N, S = full.N, full.S
    kept = MIDPOINT_ROWS["motion"]
    assert set(kept) < set(MIDPOINT_ROWS["all"]) == set(range(NODE_ROWS))
    assert full.ng - part.ng == (NODE_ROWS - len(kept)) * N == 30 * N
    rng = np.random.default_rng(3)
    o_taum, o_acc, o_T, nw = layout(N, S)
    w = rng.normal(scale=0.1, size=nw)
    for k in range(N + 1):  # states near home, so that every leg's IK is real
        w[36 * k:36 * k + 9] = home_x(ROBOT) + rng.normal(scale=0.01, size=9)
    w[o_T:] = 0.2
    p = np.r_[np.ones(nw), 2e5, 2000.0, 1.0, 0.0, np.full(N, 1.0 / N)]
    g_full = np.array(ca.Function("g", [full.nlp["x"], full.nlp["p"]],
                                  [full.nlp["g"]])(w, p)).ravel()
    g_part = np.array(ca.Function("g", [part.nlp["x"], part.nlp["p"]],
                                  [part.nlp["g"]])(w, p)).ravel()
    assert np.all(np.isfinite(g_full))
    head = 18 * N + NODE_ROWS * (N + 1)  # integration rows, then every node's rows
    np.testing.assert_array_equal(g_part[:head], g_full[:head])
    mids_full = g_full[head:head + NODE_ROWS * N].reshape(N, NODE_ROWS)
    mids_part = g_part[head:head + len(kept) * N].reshape(N, len(kept))
    np.testing.assert_array_equal(mids_part, mids_full[:, list(kept)])
    np.testing.assert_array_equal(g_part[head + len(kept) * N:],
                                  g_full[head + NODE_ROWS * N:])


def test_an_unknown_midpoint_row_choice_is_refused() -> None:
    with pytest.raises(InputError, match="midpoint_rows"):
        PlannerOptions(midpoint_rows="some")


def check(*violations: str) -> types.SimpleNamespace:
    """A dense check's result with these violations (the fields ``tightened`` reads)."""
    return types.SimpleNamespace(violations=list(violations), max_torque_ratio=1.03,
                                 max_velocity_ratio=0.9, max_acceleration_ratio=0.9,
                                 max_spherical_tilt=2.65, min_clearance=-1e-5)


@pytest.mark.parametrize("violation", ["spherical joint at 151.8 deg > 150 deg",
                                       "interference: bodies of the collision model "
                                       "overlap by 0.0 mm",
                                       "an actuated angle leaves [0, 270] deg",
                                       "unreachable at 3 samples"])
def test_a_geometric_violation_first_brings_every_row_back(violation) -> None:
    """With the geometric rows at the nodes only, such a violation re-solves with every
    row at the midpoints too, nothing else changed; with every row there already, the
    limit itself is tightened as before (or, for reach and range, nothing can be)."""
    new, fixable = strategy.tightened(Bounds(midpoint_rows="motion"), check(violation),
                                      2.618)
    assert fixable and new == Bounds(midpoint_rows="all")
    old, fixable = strategy.tightened(Bounds(midpoint_rows="all"), check(violation), 2.618)
    assert old.midpoint_rows == "all"
    if violation.startswith(("spherical", "interference")):
        assert fixable and old != Bounds(midpoint_rows="all")
    else:
        assert not fixable


def test_a_rate_violation_tightens_the_rate_whatever_the_midpoint_rows() -> None:
    new, fixable = strategy.tightened(Bounds(midpoint_rows="motion"),
                                      check("torque 10.300 N m > 10 N m"), 2.618)
    assert fixable and new.midpoint_rows == "motion"
    assert new.safety["torque"] == pytest.approx(0.98 * 0.985 / 1.03)


@pytest.fixture(scope="module")
def side_by_side():
    out = []
    for doc in TASKS:
        pair = {rows: Problem(task_from_dict(doc), ROBOT,
                              PlannerOptions(midpoint_rows=rows)).solve()
                for rows in ("all", "motion")}
        out.append((doc["name"], pair))
    return out


def test_both_formulations_plan_the_same_durations_within_1_percent(side_by_side) -> None:
    """The issue's side-by-side: three tasks, each planned by the NLP with every row at
    the midpoints and with the motion rows only; both pass the dense check and their
    durations agree within 1 %."""
    for name, pair in side_by_side:
        for rows, sol in pair.items():
            assert sol.is_feasible() and sol.check.ok, (name, rows)
            assert sol.source == "ocp", (name, rows)  # planned by the NLP, not the baseline
        ratio = pair["motion"].final_time / pair["all"].final_time
        assert abs(ratio - 1.0) <= 0.01, (name, ratio)


def test_a_geometric_violation_between_nodes_re_solves_with_every_row(monkeypatch) -> None:
    """The chain new -> old: a plan of the motion rows whose dense check finds a spherical
    joint over its limit between the nodes is re-solved with every row at the
    midpoints, from that plan, and nothing else is tightened."""
    real = solution.dense_check
    faked = []

    def first_fails(sol, factor=10):
        chk = real(sol, factor)
        if sol.source == "ocp" and not faked:
            faked.append(True)
            return dataclasses.replace(chk, ok=False, violations=[
                "spherical joint at 150.2 deg > 150 deg"])
        return chk

    monkeypatch.setattr(solution, "dense_check", first_fails)
    seen = []
    solve_nlp = strategy.solve_nlp

    def spy(problem, psi_wp, bounds, warm=None, **kw):
        seen.append((bounds.midpoint_rows, bounds.spherical_reserve,
                     None if warm is None else warm.source))
        return solve_nlp(problem, psi_wp, bounds, warm=warm, **kw)

    monkeypatch.setattr(strategy, "solve_nlp", spy)
    sol = Problem(task_from_dict(TASKS[0]), ROBOT,
                  PlannerOptions(midpoint_rows="motion")).solve()
    assert faked and sol.is_feasible() and sol.check.ok and sol.source == "ocp"
    assert seen[0] == ("motion", 0.0, "baseline")
    assert seen[1] == ("all", 0.0, "ocp")  # every row, from the first plan, nothing tightened
