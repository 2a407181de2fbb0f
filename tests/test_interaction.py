"""Sensorless touch (docs/interaction.md): the wrench on the platform from the drives
alone, checked against the wrench MuJoCo applied to a simulated plant."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from sixplus3.cli import main as cli
from sixplus3.control.file.drive_log import DriveLog
from sixplus3.errors import InputError
from sixplus3.interaction.observer.stream import WrenchStream
from sixplus3.interaction.observer.wrench import SingleState, StateModel, estimate
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()
PUSH = np.array([10.0, 0.0, 0.0, 0.0, 0.0, 0.5])  # 10 N along x, 0.5 N m about z


@pytest.fixture(scope="module")
def hold_file(tmp_path_factory):
    """A small motion whose last sample the plant then holds."""
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.task import task_from_dict

    out = tmp_path_factory.mktemp("hold")
    task = task_from_dict({"name": "small", "nodes_per_segment": 6, "waypoints": [
        {"position": [0, 0, 0.58]}, {"position": [0.01, 0, 0.58]}]})
    return run_plan(task, out, ROBOT, html=False, plots=False).csv


@pytest.fixture(scope="module")
def slow_file(tmp_path_factory):
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.task import task_from_dict

    out = tmp_path_factory.mktemp("slow")
    task = task_from_dict({"name": "slow", "waypoints": [
        {"position": [0.0, 0.0, 0.58]},
        {"position": [0.02, -0.01, 0.60], "rpy": [20, -10, 5]},
        {"position": [0.0, 0.0, 0.58]}],
        "limits": {"jerk": 3000, "torque_rate": 60}, "torque_fraction": 0.6})
    return run_plan(task, out, ROBOT, html=False, plots=False).csv


def _profile(t_on: float, t_off: float, w: np.ndarray):
    from sixplus3.control.drive.plant import WrenchProfile

    return WrenchProfile(t=np.array([0.0, t_on, t_off]), wrench=np.array([np.zeros(6), w,
                                                                           np.zeros(6)]))


def test_two_jacobians_agree() -> None:
    """The inverse kinematics Jacobian from the legs' closed forms (ik_jacobian) and from
    the closed-loop G of Pinocchio agree, and so do the batched and the one-sample
    reduced inertia and bias torque."""
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.identification.base import random_states

    q, v, _ = random_states(ROBOT, 4, seed=6)
    act = ClosedLoopDynamics(ROBOT).clm.idx_q_act
    for k in range(4):
        ss, sm = SingleState(ROBOT), StateModel(ROBOT)
        J1, M1, h1, _ = ss.state(q[k][act], v[k])
        J2, M2, h2, _ = sm.states(q[k][act][None], v[k][None])
        assert np.abs(J1 - J2[0]).max() < 1e-9
        assert np.abs(M1 - M2[0]).max() < 1e-9 and np.abs(h1 - h2[0]).max() < 1e-9


def test_a_push_and_a_twist_held_at_home(hold_file) -> None:
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.plant import run_on_plant

    run = run_on_plant(hold_file, ROBOT, ROBOT, seed=1, hold=1.6,
                       wrench=_profile(0.6, 1.4, PUSH))
    est = estimate(run.log, ROBOT)
    t = est.t
    on = (t > 0.7) & (t < 1.35)  # held, after the 100 ms the robot takes to settle
    e = est.wrench[on] - PUSH
    assert np.sqrt(np.mean(np.sum(e[:, :3] ** 2, axis=1))) <= 0.5
    assert np.sqrt(np.mean(np.sum(e[:, 3:] ** 2, axis=1))) <= 0.05
    # inside its stated uncertainty, the dry friction band included
    half = 4 * est.std[on] + est.band[on]
    assert np.all(np.abs(e) <= half)
    # a step push is detected within 20 ms, and nothing is flagged before it
    before = (t > 0.3) & (t < 0.59)
    assert not est.contact[before].any()
    first = t[(t >= 0.6) & est.contact][0]
    assert first - 0.6 <= 0.020
    # the direct residual with filtered accelerations says the same at a hold
    assert np.nanmax(np.abs(est.direct[on] - est.wrench[on])[:, :3]) < 0.5


def test_a_push_during_a_slow_plan(slow_file) -> None:
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.plant import run_on_plant

    w = np.array([0.0, 8.0, -5.0, 0.0, 0.0, 0.3])
    run = run_on_plant(slow_file, ROBOT, ROBOT, seed=3, hold=0.5, wrench=_profile(0.15, 0.6, w))
    est = estimate(run.log, ROBOT)
    on = (est.t > 0.2) & (est.t < 0.55)
    e = est.wrench[on] - w
    assert np.sqrt(np.mean(np.sum(e[:, :3] ** 2, axis=1))) <= 1.0
    # the streaming form, fed sample by sample, follows it
    st = WrenchStream(ROBOT, run.log.rate)
    ws = np.array([st.update(run.log.theta[k], run.log.tau[k])[0]
                   for k in range(len(run.log.t))])
    es = ws[on] - w
    assert np.sqrt(np.mean(np.sum(es[:, :3] ** 2, axis=1))) <= 1.0


def test_stiff_static_friction_stays_inside_the_band(hold_file) -> None:
    """A plant whose joints stick (Coulomb friction x5): a hold cannot tell a push from
    friction; the estimate stays inside its band, which says how wide it is."""
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.plant import run_on_plant
    from sixplus3.robot_description.physical import MotorModel

    sticky = ROBOT.replace(motors=MotorModel(coulomb=0.5))
    run = run_on_plant(hold_file, ROBOT, sticky, seed=2, hold=1.6,
                       wrench=_profile(0.6, 1.4, PUSH))
    est = estimate(run.log, sticky)
    on = (est.t > 0.7) & (est.t < 1.35)
    e = est.wrench[on] - PUSH
    assert np.all(np.abs(e) <= 4 * est.std[on] + est.band[on])
    assert est.band[on][:, 0].min() > 2.0  # several newtons: the report says so
    assert any("dry friction" in n for n in est.notes)


def test_bad_logs_are_refused(tmp_path) -> None:
    t = np.arange(300) / 100.0  # 100 Hz: too slow for the observer
    log = DriveLog(t, np.full((300, 9), 1.5), np.zeros((300, 9)), name="slow.csv")
    with pytest.raises(InputError, match="too low for the observer"):
        estimate(log, ROBOT)
    with pytest.raises(InputError):
        estimate(DriveLog(np.arange(300) / 1e3, np.full((300, 9), 1.5), np.zeros((300, 9))),
                 ROBOT, gain=-1.0)
    bad = tmp_path / "nan.csv"
    cols = ["t"] + [f"leg{i}_{s}_pos" for i in range(3) for s in "ABC"] + \
        [f"leg{i}_{s}_tau" for i in range(3) for s in "ABC"]
    bad.write_text(",".join(cols) + "\n" + "\n".join(
        ",".join([repr(k / 1000)] + ["nan"] * 18) for k in range(300)) + "\n")
    res = CliRunner().invoke(cli, ["wrench", str(bad)])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output


def test_cli_wrench_and_resolution(hold_file, tmp_path) -> None:
    pytest.importorskip("mujoco")
    run = CliRunner()
    prof = tmp_path / "push.csv"
    prof.write_text("t,fx,fy,fz,mx,my,mz\n0,0,0,0,0,0,0\n0.5,0,0,-10,0,0,0\n1.0,0,0,0,0,0,0\n")
    plant = tmp_path / "plant.yaml"
    assert run.invoke(cli, ["identify", "plant", "-o", str(plant), "--seed", "0", "--mass",
                            "0", "--rotor", "0", "--friction", "1"]).exit_code == 0
    log = tmp_path / "log.csv"
    r = run.invoke(cli, ["simulate", str(hold_file), "--plant", str(plant), "--log", str(log),
                         "--hold", "1.2", "--wrench", str(prof)])
    assert r.exit_code == 0, r.output
    out = tmp_path / "w.csv"
    r = run.invoke(cli, ["wrench", str(log), "-o", str(out), "--plot", str(tmp_path / "w.png"),
                         "--at", "tcp"])
    assert r.exit_code == 0, r.output
    # a picture under another name (session 34: a PNG written as x.txt) is refused
    for args in (["wrench", str(log), "--plot", str(tmp_path / "x.txt")],
                 ["wrench-resolution", "-o", str(tmp_path / "map.pdf")]):
        r = run.invoke(cli, args)
        assert r.exit_code == 2 and "writes a PNG" in r.output, r.output
        assert len(r.output.strip().splitlines()) == 1, r.output
    assert not (tmp_path / "x.txt").exists() and not (tmp_path / "map.pdf").exists()
    rows = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    assert rows[0].startswith("t,fx,fy,fz,mx,my,mz")
    head = out.read_text().splitlines()[0]  # each note once, "; " between them
    assert head.count("observer gain") == 1 and "per joint; below" in head, head
    data = np.array([[float(x) for x in ln.split(",")] for ln in rows[1:]])
    during = (data[:, 0] > 0.6) & (data[:, 0] < 0.95)
    # fz = -10 N, within 4 standard deviations and the dry friction band of a hold
    err = np.abs(data[during, 3] + 10.0)
    assert np.all(err <= 4 * data[during, 9] + data[during, 15]), err.max()
    assert np.mean(data[during, 3]) < -8.0
    r = run.invoke(cli, ["wrench-resolution", "-o", str(tmp_path / "map.png"), "--step",
                         "0.05", "--json"])
    assert r.exit_code == 0, r.output
    import json

    res = json.loads(r.output)
    assert 0 < res["home_moving"][0] < res["home_at_rest"][0]


def test_the_parameters_confidence_widens_the_uncertainty(hold_file, tmp_path) -> None:
    """With an identification's covariance, each sample's standard deviation adds the
    parameters' confidence at that state (never less than without it), and the CLI
    takes the report's parameters.npz."""
    pytest.importorskip("mujoco")
    from sixplus3.control.drive.plant import run_on_plant
    from sixplus3.control.file.drive_log import write_log
    from sixplus3.identification.base import base_parameters

    run = run_on_plant(hold_file, ROBOT, ROBOT, seed=4, hold=0.5)
    base = base_parameters(ROBOT)
    cov = np.eye(base.rank) * 1e-6
    plain = estimate(run.log, ROBOT, direct=False)
    wide = estimate(run.log, ROBOT, direct=False, parameter_cov=(base.index, cov))
    assert np.all(wide.std >= plain.std - 1e-15) and np.any(wide.std > 1.01 * plain.std)
    with pytest.raises(InputError, match="another base"):
        estimate(run.log, ROBOT, parameter_cov=(base.index[:-1], cov))
    npz = tmp_path / "parameters.npz"
    np.savez(npz, index=base.index, beta=np.zeros(base.rank), cov=cov)
    log = tmp_path / "log.csv"
    write_log(log, run.log, ROBOT)
    r = CliRunner().invoke(cli, ["wrench", str(log), "--parameters", str(npz), "--json"])
    assert r.exit_code == 0, r.output
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a npz")
    r = CliRunner().invoke(cli, ["wrench", str(log), "--parameters", str(bad)])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
