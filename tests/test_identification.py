"""Identification (docs/identification.md): the closed-loop regressor, base parameters,
per-body inertials and per-joint motors in every model, logs, estimators, and the whole
loop on virtual prototypes of seeds the estimator was not tuned on."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sixplus3.cli import main as cli
from sixplus3.control.file.drive_log import (
    DriveLog,
    kinematic_hash,
    parse_log,
    read_log,
    write_log,
)
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.regressor import layout, parameters, regressor_batch
from sixplus3.errors import GeometryError, InputError
from sixplus3.identification.base import base_parameters, random_states
from sixplus3.identification.estimate import (
    check_consistent,
    consistent,
    least_squares,
    pseudo_inertia,
)
from sixplus3.identification.plants import perturbed_plant, robot_with_parameters
from sixplus3.motion import Motion
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()


# ----------------------------------------------------------------- the regressor
@pytest.mark.parametrize("robot", [ROBOT, perturbed_plant(ROBOT, 5)], ids=["nominal", "plant"])
def test_the_regressor_equals_the_inverse_dynamics(robot) -> None:
    dyn = ClosedLoopDynamics(robot)
    q, v, a = random_states(robot, 20, seed=3)
    Y, _ = regressor_batch(dyn, q, v, a)
    tau = Y @ parameters(dyn)
    ref, _ = dyn.actuated_inverse_dynamics_batch(q, v, a)
    assert np.abs(tau - ref).max() < 1e-9
    # and one state through the unbatched path
    vv, aa = dyn.consistent_state(q[0], v[0], a[0])
    assert np.abs(tau[0] - dyn.inverse_dynamics(q[0], vv, aa)).max() < 1e-9


def test_the_regressor_against_finite_differences_of_the_parameters() -> None:
    """Linear in pi: the torque of pi + d pi minus that of pi is Y d pi (a second robot,
    built from the perturbed parameters through its URDF, checks the column mapping)."""
    dyn = ClosedLoopDynamics(ROBOT)
    lay = layout(dyn)
    q, v, a = random_states(ROBOT, 5, seed=8)
    Y, _ = regressor_batch(dyn, q, v, a)
    other = perturbed_plant(ROBOT, 11)
    dyn2 = ClosedLoopDynamics(other)
    tau2, _ = dyn2.actuated_inverse_dynamics_batch(q, v, a)
    assert np.abs(Y @ parameters(dyn2) - tau2).max() < 1e-9
    # the parameters written back into a robot are the ones it then has
    back = robot_with_parameters(ROBOT, parameters(dyn2), lay)
    assert np.abs(parameters(ClosedLoopDynamics(back)) - parameters(dyn2)).max() < 1e-12


def test_base_parameters() -> None:
    base = base_parameters(ROBOT)
    assert 100 < base.rank < base.layout.size
    dyn = ClosedLoopDynamics(ROBOT)
    q, v, a = random_states(ROBOT, 30, seed=21)  # states the QR did not see
    Y, _ = regressor_batch(dyn, q, v, a)
    pi = parameters(ClosedLoopDynamics(perturbed_plant(ROBOT, 2)))
    # the torques depend on pi only through beta
    assert np.abs(base.reduce(Y) @ base.beta(pi) - Y @ pi).max() < 1e-8
    assert np.allclose(base.matrix @ pi, base.beta(pi))
    # the rotor inertia of A and the proximal link's inertia about the same axis are one
    names = base.layout.names
    assert not any(names[i].endswith(".Ia") for i in base.index)
    # the docs list them (scripts/base_parameters.py)
    from pathlib import Path

    doc = (Path(__file__).parents[1] / "docs" / "base_parameters.md").read_text()
    assert f"finds **{base.rank}** independent" in doc


# ----------------------------------------------------------------- the robot's bodies
def test_per_body_inertials_and_per_joint_motors_reach_every_model() -> None:
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.simulation import mujoco_inverse_dynamics
    from sixplus3.dynamics.symbolic import home_x, setup_parameters, structure, symbolic_robot

    plant = perturbed_plant(ROBOT, 4)
    assert structure(plant).hash == structure(ROBOT).hash  # one compiled model for both
    assert plant.hash != ROBOT.hash
    doc = plant.as_dict()
    assert Robot.from_dict(yaml.safe_load(yaml.safe_dump(doc))).hash == plant.hash
    # CasADi (setup parameters) against Pinocchio (URDF) against MuJoCo (MJCF)
    sr = symbolic_robot(plant)
    dyn = ClosedLoopDynamics(plant)
    rng = np.random.default_rng(1)
    x = home_x(plant) + rng.normal(0, 0.02, 9)
    xd, xdd = rng.normal(0, 0.5, 9), rng.normal(0, 5, 9)
    q = np.array(sr.q(x)).ravel()
    thd = np.array(sr.theta_dot(x, xd)).ravel()
    thdd = np.array(sr.theta_ddot(x, xd, xdd)).ravel()
    v, a = dyn.consistent_state(q, thd, thdd)
    tau_pin = dyn.inverse_dynamics(q, v, a)
    assert np.abs(np.array(sr.tau(x, xd, xdd)).ravel() - tau_pin).max() < 1e-9
    tau_mj, _ = mujoco_inverse_dynamics(plant, q[None], thd[None], thdd[None])
    assert np.abs(tau_mj[0] - tau_pin).max() < 1e-6
    assert not np.allclose(setup_parameters(plant), setup_parameters(ROBOT))


def test_inertials_are_checked() -> None:
    for bad in ({"nolink": {"mass": 1, "com": [0, 0, 0], "inertia": [1, 1, 1, 0, 0, 0]}},
                {"platform": {"mass": -1, "com": [0, 0, 0], "inertia": [1, 1, 1, 0, 0, 0]}},
                {"platform": {"mass": 1, "com": [0, 0, 0], "inertia": [1, 1, 3, 0, 0, 0]}},
                {"platform": {"mass": 1, "com": [0, 0], "inertia": [1, 1, 1, 0, 0, 0]}}):
        with pytest.raises(GeometryError):
            Robot.from_dict({"inertials": bad})
    with pytest.raises(GeometryError):
        Robot.from_dict({"motors": {"joint_armature": [0.01] * 8}})
    with pytest.raises(GeometryError):
        Robot.from_dict({"motors": {"joint_coulomb": [-0.1] + [0.1] * 8}})


# ----------------------------------------------------------------- estimators
def test_least_squares_recovers_beta_and_its_spread() -> None:
    rng = np.random.default_rng(0)
    W = rng.normal(size=(900, 12))
    beta = rng.normal(size=12)
    y = W @ beta + rng.normal(0, 0.01, 900)
    ls = least_squares(W, y, robust=False)
    assert np.abs(ls.beta - beta).max() < 5 * ls.std.max()
    assert 0.005 < ls.std.max() / 0.01 * math.sqrt(900) < 3
    # an outlier block: the Huber weights keep the estimate
    y2 = y.copy()
    y2[:20] += 5.0
    assert np.abs(least_squares(W, y2).beta - beta).max() < 0.02


def test_the_consistent_estimate_is_physical() -> None:
    """Noiseless data of a perturbed plant: the SDP returns a physically consistent set
    that reproduces the torques, even from a start (nominal) that is not the plant."""
    base = base_parameters(ROBOT)
    plant = perturbed_plant(ROBOT, 9)
    dyn_p = ClosedLoopDynamics(plant)
    q, v, a = random_states(ROBOT, 120, seed=30)
    Y, _ = regressor_batch(dyn_p, q, v, a)
    tau = (Y @ parameters(dyn_p)).reshape(-1)
    Wb = base.reduce(Y).reshape(-1, base.rank)
    pi0 = parameters(ClosedLoopDynamics(ROBOT))
    c = consistent(Wb, tau, np.ones(len(tau)), base, pi0)
    check_consistent(c.pi, base.layout, tol=1e-12)
    assert np.sqrt(np.mean((Wb @ base.beta(c.pi) - tau) ** 2)) < 1e-3
    assert np.linalg.eigvalsh(pseudo_inertia(c.pi[:10]))[0] >= 0


# ----------------------------------------------------------------- logs
def _log_text(n: int = 300, rate: float = 1000.0, extra: str = "") -> str:
    cols = ["t"] + [f"leg{i}_{s}_pos" for i in range(3) for s in "ABC"] + \
        [f"leg{i}_{s}_tau" for i in range(3) for s in "ABC"]
    rows = [",".join(cols)]
    for k in range(n):
        rows.append(",".join([repr(k / rate)] + ["1.5"] * 9 + ["0.25"] * 9))
    return extra + "\n".join(rows) + "\n"


def test_a_log_reads_and_its_bad_forms_are_refused() -> None:
    log = parse_log(_log_text().encode(), ROBOT)
    assert log.theta.shape == (300, 9) and log.rate == pytest.approx(1000.0)
    good = _log_text()
    cases = {
        "nan": good.replace("1.5", "nan", 1).replace("0.001,nan", "0.001,nan"),
        "gap": good.replace("\n0.1,", "\n0.1015,", 1),
        "backwards": good.replace("\n0.002,", "\n0.0005,", 1),
        "joints": good.replace(",leg2_C_tau", "", 1),
        "unknown": good.replace("leg2_C_tau", "leg2_D_tau", 1),
        "short": _log_text(50),
        "robot": _log_text(extra='# sixplus3-log/1 {"robot_kinematics": "0123456789abcdef"}\n'),
        # the header read one way only, as a trajectory file's
        "duplicate key": _log_text(extra='# sixplus3-log/1 {"rate_hz": 1000.0, '
                                         '"rate_hz": 500.0}\n'),
        "NaN in the header": _log_text(extra='# sixplus3-log/1 {"rate_hz": NaN}\n'),
        "deep header": _log_text(extra="# sixplus3-log/1 " + "[" * 5000 + "]" * 5000 + "\n"),
    }
    for what, text in cases.items():
        with pytest.raises(InputError):
            parse_log(text.encode(), ROBOT)
        assert what
    assert "nan" in cases["nan"]


def test_logs_round_trip_in_joint_and_drive_units(tmp_path) -> None:
    from sixplus3.control.formats.drive_csv import drive_table

    rng = np.random.default_rng(2)
    t = np.arange(400) / 1000.0
    th = 1.5 + 0.1 * np.sin(t[:, None] * np.arange(1, 10))
    tau = rng.normal(0, 1, (400, 9))
    path = write_log(tmp_path / "l.csv", DriveLog(t, th, tau), ROBOT)
    back = read_log(path, ROBOT)
    assert np.array_equal(back.theta, th) and np.array_equal(back.tau, tau)
    assert back.meta["robot_kinematics"] == kinematic_hash(ROBOT)
    zero = np.zeros_like(th)
    counts, vel, torque = drive_table(ROBOT, Motion(t, th, zero, zero, 1000.0), tau)
    names = [f"leg{i}_{s}" for i in range(3) for s in "ABC"]
    text = ",".join(["t"] + [f"{n}_counts" for n in names] + [f"{n}_torque_0p1pct"
                                                                for n in names]) + "\n"
    for k in range(400):
        text += ",".join([repr(float(t[k]))] + [str(c) for c in counts[k]] +
                         [str(c) for c in torque[k]]) + "\n"
    drv = parse_log(text.encode(), ROBOT)
    k = ROBOT.motors.gear_ratio * 2 ** 20 / (2 * math.pi)
    assert np.abs(drv.theta - th).max() <= 0.5 / k + 1e-12
    assert np.abs(drv.tau - tau).max() <= 0.5 * 5.0 * 72 / 34 / 1000 + 1e-12


def test_a_slow_log_is_refused_for_the_filter() -> None:
    from sixplus3.identification.signals import filter_log

    log = parse_log(_log_text(400, rate=30.0).encode(), ROBOT)
    with pytest.raises(InputError, match="below what the filter needs"):
        filter_log(log)


# ----------------------------------------------------------------- the loop
@pytest.fixture(scope="module")
def excitation(tmp_path_factory):
    from sixplus3.identification.excite import ExcitationSettings, excite

    out = tmp_path_factory.mktemp("excite")
    return excite(ROBOT, out, ExcitationSettings(duration=3.0, candidates=4))


@pytest.fixture(scope="module")
def validation_plan(tmp_path_factory):
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.task import task_from_dict

    out = tmp_path_factory.mktemp("val")
    task = task_from_dict({"name": "val", "waypoints": [
        {"position": [0.0, 0.0, 0.58]},
        {"position": [0.02, -0.01, 0.60], "rpy": [20, -10, 5]},
        {"position": [0.0, 0.0, 0.58]}],
        "limits": {"jerk": 3000, "torque_rate": 60}, "torque_fraction": 0.6})
    return run_plan(task, out, ROBOT, html=False, plots=False).csv


@pytest.fixture(scope="module")
def fast_tour():
    """Tour 7 of the default settings (seed 0): a fast tour (cranks at ~24 rad/s) whose
    200 Hz scoring samples a forward kinematics search from a log could not follow, which
    once ended `sixplus3 identify excite` with its defaults (issue 53)."""
    from sixplus3.identification.excite import ExcitationSettings, _tour_task
    from sixplus3.planner.ocp import plan
    from sixplus3.planner.smoothing import smooth
    from sixplus3.planner.task import task_from_dict

    st = ExcitationSettings()
    rng = np.random.default_rng(st.seed)
    docs = [_tour_task(ROBOT, rng, st, k) for k in range(8)]
    return docs[7], smooth(plan(task_from_dict(docs[7]), ROBOT), rate=st.rate)


def test_a_fast_tour_is_scored_from_its_own_states(fast_tour) -> None:
    from sixplus3.identification.excite import base_regressor

    _, sm = fast_tour
    base = base_parameters(ROBOT)
    W = base_regressor(ClosedLoopDynamics(ROBOT), base, sm.theta, sm.theta_dot,
                       sm.theta_ddot, 1000.0, sm.x_guess)
    assert W.shape == (9 * len(range(0, len(sm.t), 5)), base.rank)
    assert np.all(np.isfinite(W)) and np.abs(W).max() > 0


def test_a_tour_that_cannot_be_scored_is_skipped_and_said(fast_tour, monkeypatch) -> None:
    """A candidate whose scoring fails is skipped with its reason; the others go on."""
    import sixplus3.identification.excite as ex

    doc, sm = fast_tour
    monkeypatch.setattr(ex, "plan", lambda task, robot: None)
    monkeypatch.setattr(ex, "smooth", lambda sol, rate: sm)
    real, calls = ex.base_regressor, []

    def flaky(*args, **kw):
        calls.append(1)
        if len(calls) == 1:
            raise InputError("the planned state 3 has no pose", value=3, valid="x")
        return real(*args, **kw)

    monkeypatch.setattr(ex, "base_regressor", flaky)
    said: list[str] = []
    tours, refused = ex.plan_tours(ROBOT, ex.ExcitationSettings(candidates=2),
                                   base_parameters(ROBOT), said.append)
    assert (len(tours), refused) == (1, 1)
    assert "tour 0: planned but not scored, skipped" in said[0] and "no pose" in said[0]
    assert "tour 1:" in said[1] and "condition" in said[1]


def test_the_excitation_is_a_valid_file(excitation) -> None:
    res = CliRunner().invoke(cli, ["validate", str(excitation.path)])
    assert res.exit_code == 0, res.output
    assert excitation.duration >= 3.0 and math.isfinite(excitation.condition)


@pytest.mark.parametrize("seed", [13, 29])
def test_identified_plants_predict_unseen_plans(excitation, validation_plan, seed,
                                                tmp_path) -> None:
    """Plants of seeds the estimator was never tuned on: the identified robot predicts
    the torques of an unseen plan within 1.5x the noise injected into the logged torque
    (the torque monitor's noise and the 0.1 % quantisation), where the nominal model is
    far off; the identified robot file plans at once (the same compiled model)."""
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.loop import TORQUE_NOISE
    from sixplus3.control.drive.plant import run_on_plant
    from sixplus3.identification.identify import check, identify

    plant = perturbed_plant(ROBOT, seed)
    exc = run_on_plant(excitation.path, ROBOT, plant, seed=seed)
    idf = identify([exc.log], ROBOT)
    val = run_on_plant(validation_plan, ROBOT, plant, seed=seed + 1, hold=1.0)
    unit = ROBOT.motors.gear_ratio * ROBOT.motors.rated_torque / 1000.0
    sigma = math.sqrt(TORQUE_NOISE ** 2 + unit ** 2 / 12.0)
    e_id, e_nom = check(val.log, idf.robot), check(val.log, ROBOT)
    assert e_id.rms_all <= 1.5 * sigma, (e_id.rms_all, sigma)
    assert e_nom.rms_all > 5 * e_id.rms_all
    check_consistent(parameters(ClosedLoopDynamics(idf.robot)), idf.base.layout)
    # the identified robot file is a robot file like any other
    path = tmp_path / "identified.yaml"
    from sixplus3.identification.report import write_robot

    write_robot(path, idf, ["exc"])
    from sixplus3.robot_description.robot import load_robot

    assert load_robot(path).hash == idf.robot.hash


def test_the_identified_robot_plans_within_the_limit_on_the_plant(excitation, tmp_path) -> None:
    """A plan on the nominal model exceeds the hardware limit on a plant with more
    inertia; the same task re-planned on the identified robot stays within it, with no
    compilation (the identified robot shares the nominal one's compiled model)."""
    pytest.importorskip("mujoco")
    from sixplus3 import examples
    from sixplus3.control.drive.plant import run_on_plant
    from sixplus3.control.pipeline import run_plan
    from sixplus3.dynamics import codegen
    from sixplus3.identification.identify import identify

    plant = perturbed_plant(ROBOT, 1)  # heavier where tilt60_x needs it (measured: 10.4)
    task = examples.load("tilt30_x")
    nominal = run_plan(task, tmp_path / "nom", ROBOT, html=False, plots=False).csv
    a = run_on_plant(nominal, ROBOT, plant, seed=1)
    assert a.peak_torque > ROBOT.limits.torque, a.peak_torque
    idf = identify([run_on_plant(excitation.path, ROBOT, plant, seed=2).log], ROBOT)
    libs = codegen.loaded_libraries(ROBOT)
    again = run_plan(task, tmp_path / "id", idf.robot, html=False, plots=False)
    assert codegen.loaded_libraries(idf.robot) == libs  # nothing compiled for it
    c = run_on_plant(again.csv, idf.robot, plant, seed=1)
    assert c.peak_torque <= ROBOT.limits.torque, c.peak_torque


def test_cli_identify_estimate_and_check(excitation, validation_plan, tmp_path) -> None:
    pytest.importorskip("mujoco")
    run = CliRunner()
    plant = tmp_path / "plant.yaml"
    r = run.invoke(cli, ["identify", "plant", "-o", str(plant), "--seed", "41"])
    assert r.exit_code == 0, r.output
    log = tmp_path / "exc.csv"
    r = run.invoke(cli, ["simulate", str(excitation.path), "--plant", str(plant), "--log",
                         str(log), "--seed", "41"])
    assert r.exit_code == 0, r.output
    val = tmp_path / "val.csv"
    r = run.invoke(cli, ["simulate", str(validation_plan), "--plant", str(plant), "--log",
                         str(val), "--hold", "1"])
    assert r.exit_code == 0, r.output
    out = tmp_path / "id.yaml"
    r = run.invoke(cli, ["identify", "estimate", str(log), "-o", str(out), "--report",
                         str(tmp_path / "rep"), "--validation", str(val), "--json"])
    assert r.exit_code == 0, r.output
    import json

    def refuse(token: str) -> None:  # a strict parser (JavaScript's JSON.parse)
        raise AssertionError(f"non-strict JSON constant {token}")

    summary = json.loads(r.output, parse_constant=refuse)
    written = json.loads((tmp_path / "rep" / "summary.json").read_text(),
                         parse_constant=refuse)
    assert written["cross_validation"]["identified"]["rms_all_n_m"] == pytest.approx(
        summary["cross_validation"]["identified"]["rms_all_n_m"])
    cv = summary["cross_validation"]
    assert cv["identified"]["rms_all_n_m"] < 0.2 * cv["nominal"]["rms_all_n_m"]
    assert (tmp_path / "rep" / "parameters.csv").exists()
    r = run.invoke(cli, ["--robot", str(out), "identify", "check", str(val), "--json"])
    assert r.exit_code == 0 and json.loads(r.output)["rms_all_n_m"] == pytest.approx(
        cv["identified"]["rms_all_n_m"])
    r = run.invoke(cli, ["--robot", str(out), "validate", str(excitation.path)])
    assert r.exit_code == 2 and "robot mismatch" in r.output  # made for the nominal robot
    # the identified robot file drives plan, validate, export (no compilation)
    task = tmp_path / "t.yaml"
    task.write_text("name: small\nnodes_per_segment: 6\nwaypoints:\n  - position: [0, 0, 0.58]"
                    "\n  - position: [0.02, 0, 0.58]\n")
    r = run.invoke(cli, ["--robot", str(out), "plan", str(task), "-o", str(tmp_path / "p"),
                         "--no-html", "--quiet"])
    assert r.exit_code == 0, r.output
    planned = tmp_path / "p" / "small.csv"
    r = run.invoke(cli, ["--robot", str(out), "validate", str(planned)])
    assert r.exit_code == 0, r.output
    r = run.invoke(cli, ["--robot", str(out), "export", str(planned), "--format", "drive-csv"])
    assert r.exit_code == 0, r.output
    # a poorly excited log: refused with its condition number and the threshold
    r = run.invoke(cli, ["identify", "estimate", str(val), "-o", str(tmp_path / "y.yaml")])
    assert r.exit_code == 2 and "condition number" in r.output, r.output
    # bad input: one line, exit 2; the output never written over
    r = run.invoke(cli, ["identify", "estimate", str(log), "-o", str(out)])
    assert r.exit_code == 2 and "--force" in r.output
    bad = tmp_path / "bad.csv"
    bad.write_text(log.read_text().replace("\n0.1,", "\n0.1002,", 1))
    r = run.invoke(cli, ["identify", "estimate", str(bad), "-o", str(tmp_path / "x.yaml")])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
    assert not (tmp_path / "x.yaml").exists()


def test_least_squares_equals_a_weighted_lstsq_at_its_weights() -> None:
    """The IRLS through per-joint normal equations and outlier corrections (one pass over
    the rows) gives the weighted least-squares solution of its final weights, as numpy's
    lstsq on the weighted rows computes it independently; heavy-tailed noise makes
    Huber down-weight many rows."""
    rng = np.random.default_rng(1)
    N, r = 5000, 30
    Wb = rng.normal(size=(N, r)) * np.logspace(0, 2, r)
    tau = Wb @ rng.normal(size=r) + rng.standard_t(3, size=N) * 0.1
    ls = least_squares(Wb, tau)
    w = ls.weights
    ref = np.linalg.lstsq(Wb * w[:, None], tau * w, rcond=None)[0]
    np.testing.assert_allclose(ls.beta, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert ls.iterations >= 2 and np.sum(w < np.max(w) * 0.5) > 0.01 * N  # 104 here


def test_a_joint_that_never_moved_is_null_with_its_reason() -> None:
    """A per-joint figure with no rows is NaN in the library and ``null`` in JSON, with
    the reason beside it (issue 53.4)."""
    import json

    from sixplus3.cli.identify import _per_joint
    from sixplus3.fileio import strict_json
    from sixplus3.identification.identify import not_measured

    rms = np.array([0.1, math.nan, 0.2, 0.3, 0.1, 0.1, 0.1, 0.1, math.inf])
    why = not_measured(rms)
    assert list(why) == ["leg0_B", "leg2_C"] and "never moved faster than" in why["leg0_B"]
    text = strict_json({"rms": rms, "x": np.float64("nan"), "ok": 1.5, "why": why})
    doc = json.loads(text, parse_constant=lambda c: pytest.fail(c))
    assert doc["rms"][1] is None and doc["rms"][8] is None and doc["x"] is None
    assert doc["rms"][0] == 0.1 and doc["ok"] == 1.5
    assert "NaN" not in text and "Infinity" not in text
    assert _per_joint(rms).split()[1] == "n/a" and "nan" not in _per_joint(rms)


def test_a_rosbag2_joint_states_log(tmp_path) -> None:
    """A bag of sensor_msgs/JointState with the nine actuated joints' positions and
    efforts (a lab's ros2_control broadcaster) reads as the same log."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    names = [f"leg{i}_{s}" for i in range(3) for s in "ABC"]
    rng = np.random.default_rng(3)
    n = 300
    th = 1.5 + 0.01 * rng.normal(size=(n, 9))
    tau = rng.normal(size=(n, 9))
    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for k in range(n):
            ns = 5_000_000_000 + k * 1_000_000  # stamps from 5 s, at 1 kHz
            msg = T["sensor_msgs/msg/JointState"](
                header=T["std_msgs/msg/Header"](
                    stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9,
                                                           nanosec=ns % 10**9),
                    frame_id="base_link"),
                name=names[::-1], position=th[k, ::-1].copy(), velocity=np.zeros(0),
                effort=tau[k, ::-1].copy())
            w.write(c, ns, store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    log = read_log(bag, ROBOT)
    assert np.allclose(log.theta, th) and np.allclose(log.tau, tau)
    assert log.rate == pytest.approx(1000.0) and log.t[0] == 0.0
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError):
        read_log(empty, ROBOT)


def test_the_wrench_on_a_perturbed_plant_with_its_identified_robot(excitation, tmp_path) -> None:
    """Sensorless touch on a plant of seed 7 with the robot identified on it: a held
    push is estimated inside the band the estimate states, and better than with the
    nominal model."""
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.plant import WrenchProfile, run_on_plant
    from sixplus3.control.pipeline import run_plan
    from sixplus3.identification.identify import identify
    from sixplus3.interaction.observer.wrench import estimate
    from sixplus3.planner.task import task_from_dict

    plant = perturbed_plant(ROBOT, 7)
    idf = identify([run_on_plant(excitation.path, ROBOT, plant, seed=7).log], ROBOT)
    small = run_plan(task_from_dict({"name": "small", "nodes_per_segment": 6, "waypoints": [
        {"position": [0, 0, 0.58]}, {"position": [0.01, 0, 0.58]}]}), tmp_path, ROBOT,
        html=False, plots=False).csv
    push = np.array([0.0, -10.0, 0.0, 0.3, 0.0, 0.0])
    prof = WrenchProfile(np.array([0.0, 0.6, 1.4]), np.array([np.zeros(6), push,
                                                               np.zeros(6)]))
    run = run_on_plant(small, ROBOT, plant, seed=8, hold=1.6, wrench=prof)
    on = (run.log.t > 0.7) & (run.log.t < 1.35)
    est = estimate(run.log, idf.robot)
    err = np.abs(est.wrench[on] - push)
    assert np.all(err <= 4 * est.std[on] + est.band[on])
    nominal = estimate(run.log, ROBOT)
    e_id = np.sqrt(np.mean(np.sum(err[:, :3] ** 2, axis=1)))
    e_nom = np.sqrt(np.mean(np.sum((nominal.wrench[on] - push)[:, :3] ** 2, axis=1)))
    assert e_id < e_nom, (e_id, e_nom)


def test_identify_takes_an_estimator(excitation) -> None:
    """The estimator is a parameter (issue 54, item 3): the default is the consistent
    one; any object with a name and a call is taken, and what it returns is still
    checked to be physical before a robot is made of it."""
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.plant import run_on_plant
    from sixplus3.identification.estimate import least_squares
    from sixplus3.identification.estimators import (
        ESTIMATORS,
        ConsistentEstimator,
        Estimate,
        Estimator,
        Problem,
    )
    from sixplus3.identification.identify import identify

    log = run_on_plant(excitation.path, ROBOT, perturbed_plant(ROBOT, 5), seed=5).log
    default = identify([log], ROBOT)
    assert identify([log], ROBOT, estimator=ESTIMATORS["consistent"]()).robot.hash == \
        default.robot.hash
    assert isinstance(ConsistentEstimator(), Estimator)

    class Nominal:
        """Believes the nominal parameters whatever the data say."""

        name = "nominal"

        def __init__(self, shift: float = 0.0) -> None:
            self.shift = shift

        def __call__(self, p: Problem) -> Estimate:
            pi = p.pi0.copy()
            pi[0] += self.shift  # the first body's mass
            ls = least_squares(p.Wb, p.tau, p.joint)
            return Estimate(beta=ls.beta, cov=None, pi=pi, facts={"believes": "nominal"})

    mine = identify([log], ROBOT, estimator=Nominal())
    np.testing.assert_allclose(mine.beta_consistent, mine.beta_nominal, rtol=1e-9, atol=1e-12)
    assert mine.residual_rms.mean() > default.residual_rms.mean()
    # a second estimator reports in its own terms, faking none of the built-in's
    summ = mine.summary()
    assert summ["estimator"] == "nominal" and summ["condition"] is None
    assert summ["solver"] is None and summ["min_pseudo_inertia_eigenvalue"] >= 0.0
    assert default.summary()["estimator"] == "consistent"
    assert default.summary()["condition"] == pytest.approx(default.condition)
    assert default.condition > 1.0
    assert all(math.isnan(row["std"]) for row in mine.table())

    class Wrong:
        name = "wrong"

        def __call__(self, p: Problem) -> object:
            return (p.pi0, p.pi0)

    with pytest.raises(InputError, match="not an Estimate"):
        identify([log], ROBOT, estimator=Wrong())  # type: ignore[arg-type]
    with pytest.raises(InputError, match="not physically consistent"):
        identify([log], ROBOT, estimator=Nominal(shift=-100.0))  # a negative mass
    with pytest.raises(InputError, match="must be an Estimator"):
        identify([log], ROBOT, estimator="consistent")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="prior weight"):
        ConsistentEstimator(prior_weight=1e300)
