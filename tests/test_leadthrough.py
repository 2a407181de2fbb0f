"""Lead-through (interaction/lead/leadthrough.py) on the MuJoCo plant with a simulated hand
(control/drive/hand.py), and teach-and-replay (interaction/lead/teach.py): nothing creeps at
rest, a push below the friction band starts nothing, the platform follows a hand at the
admittance's law, a stiff and a soft hand stay stable and the robot passive, the walls
keep the reference inside the gate's limits, the cranks climb to a better margin, and a
guided log becomes a task."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sixplus3.control.drive.command import Mode
from sixplus3.errors import InputError
from sixplus3.identification.plants import perturbed_plant
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()
pytest.importorskip("mujoco")
#: a plant the model was not tuned on: masses, rotors and friction off
PLANT = perturbed_plant(ROBOT, 13, mass=0.05, rotor=0.05, friction=1.2)


def _run(hand: dict, plant: Robot = PLANT, **lead):
    from sixplus3.control.drive.hand import hand_from_dict
    from sixplus3.interaction.lead.leadthrough import LeadThrough
    from sixplus3.interaction.people.hand import run_lead

    start = lead.pop("start_q", None)
    lt = LeadThrough(ROBOT, 1000.0, drive_gains=(300.0, 6.0), **lead)
    return lt, run_lead(ROBOT, plant, hand_from_dict(hand), lead=lt, start=start)


def test_at_rest_nothing_creeps() -> None:
    """Nobody touches the platform: the deadband holds it (the encoder's and the
    monitor's noise and the friction at rest never start a motion)."""
    lt, run = _run({"stiffness": 0, "damping": 0, "duration": 1.5})
    assert run.drift() < 1e-4, run.drift()
    assert not np.any(run.modes == "lead")
    assert run.peak_command < ROBOT.limits.torque


def test_a_push_inside_the_friction_band_starts_nothing() -> None:
    """0.5 N at the platform is inside the joints' friction band at rest (what a hold
    cannot tell from a push): the platform stays; 4 N is beyond it: it moves."""
    weak = {"stiffness": 100.0, "damping": 0.0, "delay": 0.0, "duration": 1.0,
            "path": [{"t": 0.0, "offset": [0.005, 0.0, 0.0]}]}
    _, run = _run(weak)
    assert run.drift() < 3e-4 and not np.any(run.modes == "lead")
    strong = dict(weak, path=[{"t": 0.0, "offset": [0.04, 0.0, 0.0]}])
    _, run = _run(strong)
    assert np.any(run.modes == "lead") and run.drift() > 0.01
    assert run.breakaway() is not None and run.breakaway() < 4.5


def test_the_platform_follows_a_hand_at_the_admittance_law() -> None:
    """Dragged at 0.1 m/s, the hand's force is the virtual damper's D v plus at most
    the deadband (a few tenths of a newton once moving) and the observer's error."""
    damping = 20.0
    hand = {"stiffness": 500.0, "damping": 10.0, "delay": 0.1, "duration": 2.2,
            "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 0.2, "offset": [0, 0, 0]},
                     {"t": 1.7, "offset": [0.15, 0, 0]}]}
    lt, run = _run(hand, damping=(damping, 0.4))
    f = run.force_at_speed(0.1)
    assert f is not None, "never moved at 0.1 m/s"
    assert damping * 0.1 * 0.9 <= f <= damping * 0.1 + 1.0, f
    assert run.peak_command <= 0.97 * ROBOT.limits.torque + 1e-9
    assert np.linalg.norm(run.tcp[-1] - run.anchor[-1]) < 0.01


@pytest.mark.parametrize("stiffness,damping", [(3000.0, 40.0), (150.0, 3.0)])
def test_stable_and_passive_with_a_stiff_and_a_soft_hand(stiffness, damping) -> None:
    """A hand moves the platform 5 cm and holds it: the coupled system settles (no
    sustained oscillation), and the energy the hand put into the robot (its true force
    times the true velocity) never falls below minus the tank's initial energy."""
    hand = {"stiffness": stiffness, "damping": damping, "delay": 0.15, "duration": 2.5,
            "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 1.0, "offset": [0, 0.05, 0]}]}
    lt, run = _run(hand)
    last = run.t > run.t[-1] - 0.5
    assert run.speed[last].max() < 0.01, run.speed[last].max()
    assert run.port_energy_min >= -lt.settings.energy, run.port_energy_min
    assert np.linalg.norm(run.tcp[-1] - run.tcp[0]) > 0.03


def test_walls_keep_the_reference_inside_the_gates_limits() -> None:
    """A hand pulls 25 N toward the workspace's edge along x (the legs' clearance, then
    a singularity, then no assembly at all): the reference stops at the wall, and every
    pose of it is one the gate accepts (margins, clearance, spherical joints, range)."""
    from sixplus3.interaction.lead import walls

    hand = {"stiffness": 1000.0, "damping": 20.0, "max_force": 25.0, "duration": 4.5,
            "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 3.0, "offset": [0.4, 0, 0]}]}
    lt, run = _run(hand)
    assert lt.walls_met > 0
    # the guards (walls.py) stand inside the gate's limits: a slack above minus its
    # guard is inside the limit
    assert lt.min_slack > -walls.CLEARANCE_GUARD / 0.01, lt.min_slack
    assert lt.min_margin >= ROBOT.limits.margin
    assert 0.15 < lt.st.p_ref[0] - run.tcp[0][0] < 0.26
    assert run.peak_command <= ROBOT.limits.torque
    assert not run.events
    # a wall approached along x is met early and gently enough that the commanded
    # accelerations stay within the actuated limit (a wall met suddenly need not:
    # BENCHMARKS.md, "Lead-through", the walls' table)
    acc, _ = run.smoothness()
    assert acc <= ROBOT.limits.acceleration, acc


def test_the_cranks_climb_to_a_better_margin_while_guided() -> None:
    """From cranks at 60 deg (the platform's margin below its best), a slow push: the
    cranks deciding raise the smallest singularity margin; locked, they stay."""
    from sixplus3.kinematics.robot import robot_ik, robot_ik_pose

    start = robot_ik_pose(ROBOT.home_position, (0, 0, 0), [math.radians(60)] * 3,
                          robot=ROBOT)
    m0 = float(start.margins.minimum[0])
    hand = {"stiffness": 400.0, "damping": 10.0, "duration": 2.0,
            "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 1.8, "offset": [0.05, 0, 0]}]}
    out = {}
    for gain in (2.0, 0.0):
        lt, run = _run(hand, crank_gain=gain, start_q=start.q[0])
        cfg = robot_ik(lt.st.p_ref, lt.st.R_ref, lt.st.psi_ref, ROBOT)
        out[gain] = float(cfg.margins.minimum[0])
        assert run.peak_command <= 0.97 * ROBOT.limits.torque + 1e-9
    assert out[2.0] > m0 + 0.02, (m0, out)
    assert abs(out[0.0] - m0) < 0.02, (m0, out)


def test_keep_out_is_the_least_change_that_respects_the_walls() -> None:
    from sixplus3.interaction.lead.leadthrough import LeadThrough

    lt = LeadThrough(ROBOT, 1000.0)
    rng = np.random.default_rng(3)
    for _ in range(20):
        g = rng.normal(size=9)
        b = float(rng.normal())
        lt.st.v, lt.st.psi_dot = rng.normal(size=6), rng.normal(size=3)
        L = 0.5
        x0 = np.r_[lt.st.v[:3], lt.st.v[3:] * L, lt.st.psi_dot * L]
        lt.st.walls = [(g, b)]
        lt._keep_out()
        x = np.r_[lt.st.v[:3], lt.st.v[3:] * L, lt.st.psi_dot * L]
        expect = x0 + max(0.0, b - g @ x0) / (g @ g) * g  # the projection on g.x >= b
        np.testing.assert_allclose(x, expect, atol=1e-12)
    gs = [(rng.normal(size=9), -0.1) for _ in range(3)]
    lt.st.walls = gs
    lt.st.v, lt.st.psi_dot = rng.normal(size=6), rng.normal(size=3)
    lt._keep_out()
    x = np.r_[lt.st.v[:3], lt.st.v[3:] * L, lt.st.psi_dot * L]
    assert all(g @ x >= b - 1e-3 for g, b in gs)


def test_an_empty_tank_only_lets_the_platform_slow_down() -> None:
    from sixplus3.interaction.lead.leadthrough import LeadThrough

    lt = LeadThrough(ROBOT, 1000.0)
    lt.port_energy = -10.0  # the robot has given more than it received
    lt.st.v = np.array([0.1, 0, 0, 0, 0, 0])
    lt._admittance(np.array([5.0, 0, 0, 0, 0, 0]))
    assert lt.tank <= 0 and lt.st.v[0] <= 0.1
    v1 = lt.st.v[0]
    lt._admittance(np.array([-5.0, 0, 0, 0, 0, 0]))
    assert lt.st.v[0] < v1


def test_a_tick_never_raises_and_holds_the_reference() -> None:
    from sixplus3.interaction.lead.leadthrough import CONFIRM, LeadThrough
    from sixplus3.kinematics.robot import home

    lt = LeadThrough(ROBOT, 1000.0)
    th = home(ROBOT).theta[0]
    for _ in range(CONFIRM):  # the reference starts where CONFIRM readings agree
        cmd = lt.step(th, np.zeros(9))
    ref = cmd.theta_ref.copy()
    bad = lt.step(np.full(9, np.nan), np.zeros(9))
    assert bad.mode == "hold" and np.all(np.isfinite(bad.theta_ref))
    np.testing.assert_allclose(bad.theta_ref, ref)
    assert lt.events and "holding: a measured angle" in lt.events[0]
    assert lt.step([1, 2], "x").mode == "hold"


@pytest.mark.parametrize("kwargs,what", [({"mass": -1.0}, "mass"),
                                         ({"damping": (1, 2, 3)}, "damping"),
                                         ({"speed": (0.1,)}, "speed"),
                                         ({"rate_hz": 50.0}, "rate_hz")])
def test_bad_settings_are_refused_by_name(kwargs, what) -> None:
    from sixplus3.interaction.lead.leadthrough import LeadThrough

    with pytest.raises(InputError, match=what):
        LeadThrough(ROBOT, **kwargs)


@pytest.mark.parametrize("doc,what", [
    ({"stiffness": -1}, "stiffness"), ({"path": []}, "path"),
    ({"path": [{"t": 1.0, "offset": [0, 0, 0]}, {"t": 0.5, "offset": [0, 0, 0]}]},
     "increase"),
    ({"path": [{"t": 0.0, "offset": [0, 0]}]}, "offset"), ({"grip": 1}, "unknown key"),
    ({"path": [{"t": 0.0, "offset": [0, 0, 0], "rotation": [9, 0, 0]}]}, "rotation")])
def test_bad_hand_files_are_refused_by_name(doc, what) -> None:
    from sixplus3.control.drive.hand import hand_from_dict

    with pytest.raises(InputError, match=what):
        hand_from_dict(doc)


def test_teach_finds_the_pauses_of_a_guided_motion() -> None:
    """A synthetic log (exact angles by inverse kinematics): rest, a move, a pause of
    0.5 s, a turn, a rest.  The waypoints are the start, the pause's pose and the end."""
    from sixplus3.control.file.drive_log import DriveLog
    from sixplus3.interaction.lead.teach import teach
    from sixplus3.kinematics import rotations as rot
    from sixplus3.kinematics.robot import robot_ik

    t = np.arange(0.0, 2.5, 0.002)
    s1 = np.clip((t - 0.3) / 0.6, 0, 1)
    s2 = np.clip((t - 1.4) / 0.6, 0, 1)
    s1, s2 = 0.5 - 0.5 * np.cos(np.pi * s1), 0.5 - 0.5 * np.cos(np.pi * s2)
    pos = np.asarray(ROBOT.home_position) + np.outer(s1, [0.05, 0.0, 0.0])
    R = rot.matrix_from_rotvec(np.outer(s2, [0.0, 0.0, math.radians(20)]))
    cfg = robot_ik(pos, R, None, ROBOT)
    assert cfg.ok.all()
    log = DriveLog(t=t, theta=cfg.theta, tau=np.zeros_like(cfg.theta), name="synthetic")
    taught = teach(log, ROBOT)
    assert len(taught.times) == 3 and list(taught.paused) == [False, True, False]
    assert 0.9 < taught.times[1] < 1.4
    np.testing.assert_allclose(taught.positions[1], pos[0] + [0.05, 0, 0], atol=1e-6)
    end = rot.rotvec_from_quat(taught.quaternions[2:3])[0]
    np.testing.assert_allclose(end, [0, 0, math.radians(20)], atol=1e-6)
    doc = taught.task(pfl=("hand",), stop=True)
    assert doc["pfl"] == ["hand"] and doc["waypoints"][1]["stop"] is True
    from sixplus3.planner.task import task_from_dict

    task = task_from_dict(doc)
    assert len(task.waypoints) == 3 and task.pfl == ("hand",)
    still = DriveLog(t=t, theta=np.repeat(cfg.theta[:1], len(t), 0),
                     tau=np.zeros_like(cfg.theta), name="still")
    with pytest.raises(InputError, match="never moved"):
        teach(still, ROBOT)


def test_lead_through_and_teach_from_the_command_line(tmp_path) -> None:
    from click.testing import CliRunner

    from sixplus3.cli import main as cli
    from sixplus3.identification.report import robot_yaml

    plant = tmp_path / "plant.yaml"
    plant.write_text(robot_yaml(PLANT))
    hand = tmp_path / "hand.yaml"
    hand.write_text("stiffness: 400\ndamping: 10\ndelay: 0.1\nduration: 2.0\npath:\n"
                    "  - {t: 0.0, offset: [0, 0, 0]}\n  - {t: 0.7, offset: [0.04, 0, 0]}\n"
                    "  - {t: 1.4, offset: [0.04, 0, 0]}\n")
    log = tmp_path / "lead.csv"
    args = ["simulate", "--plant", str(plant), "--lead", str(hand), "--log", str(log)]
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    assert "lead-through on plant" in res.output and "breakaway force" in res.output
    task = tmp_path / "taught.yaml"
    res = CliRunner().invoke(cli, ["teach", str(log), "-o", str(task), "--pfl", "hand"])
    assert res.exit_code == 0, res.output
    from sixplus3.planner.task import load_task

    t = load_task(task)
    assert t.pfl == ("hand",) and len(t.waypoints) >= 2
    for bad, msg in ((["simulate", "--plant", str(plant), "--log", str(log)], "--lead"),
                     ([*args, "--force", "x.csv"], "no trajectory FILE"),
                     (["simulate", "--lead", str(hand)], "--plant and --log"),
                     ([*args], "exists")):
        res = CliRunner().invoke(cli, bad)
        assert res.exit_code == 2 and msg in res.output, (bad, res.output)


def test_the_compiled_state_is_pinocchios_to_rounding() -> None:
    """The observer's per-tick state from the CasADi model compiled to C (forward
    kinematics by Newton in minimal coordinates, J, M, h) against Pinocchio's
    (SingleState), along a sequence of readings away from home, cranks off their home
    angles, on a perturbed robot (its own masses and friction)."""
    from sixplus3.interaction.observer.compiled_state import CompiledState
    from sixplus3.interaction.observer.wrench import SingleState
    from sixplus3.kinematics.robot import robot_ik_pose

    robot = perturbed_plant(ROBOT, 5, mass=0.2, rotor=0.2, friction=1.5)
    cs, ss = CompiledState(robot), SingleState(robot)
    cfg = robot_ik_pose([0.04, -0.03, 0.61], [0.3, -0.2, 0.5], [1.3, 1.8, 1.6],
                        robot=robot)
    rng = np.random.default_rng(1)
    th = cfg.theta[0]
    for k in range(6):
        th = th + rng.normal(0.0, 0.003, 9)
        thd = rng.normal(0.0, 1.5, 9)
        a, b = ss.state(th, thd), cs.state(th, thd)
        tol = 1e-8 if k == 0 else 1e-10  # the first: both from a 1e-9 forward kinematics
        for name, u, v in zip(("J", "M", "h", "offset"), a, b, strict=True):
            np.testing.assert_allclose(v, u, atol=tol * max(1.0, np.abs(u).max()),
                                       err_msg=name)
        np.testing.assert_allclose(cs.position, ss.position, atol=1e-10)
        np.testing.assert_allclose(cs.rotation, ss.rotation, atol=1e-10)
        np.testing.assert_allclose(cs.psi, ss.psi, atol=1e-10)
    with pytest.raises(InputError, match="did not converge"):
        cs.state(th + 3.0, thd)  # no assembly has these angles


def test_a_wall_no_gradient_announces_is_seen_ahead() -> None:
    """Pulled fast toward -y with a stiff drive, the legs' clearance wall appears
    suddenly (the closest pair of the collision model changes): the probes ahead stop
    the reference inside the gate's limits (before them it went 1.4 mm past zero)."""
    from sixplus3.control.drive.hand import hand_from_dict
    from sixplus3.interaction.lead import walls
    from sixplus3.interaction.lead.leadthrough import LeadThrough
    from sixplus3.interaction.people.hand import run_lead

    hand = {"stiffness": 1000.0, "damping": 20.0, "max_force": 25.0, "duration": 2.0,
            "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 1.0, "offset": [0, -0.4, 0]}]}
    lt = LeadThrough(ROBOT, 1000.0, drive_gains=(3000.0, 30.0))
    run = run_lead(ROBOT, ROBOT, hand_from_dict(hand), lead=lt, kp=3000.0, kd=30.0)
    assert lt.walls_met > 0 and not run.events
    assert lt.min_slack > -walls.CLEARANCE_GUARD / 0.01, lt.min_slack
    assert lt.min_margin >= ROBOT.limits.margin
    assert run.peak_command <= ROBOT.limits.torque


def test_a_near_walls_gradient_arrives_two_ticks_after_the_update() -> None:
    """The slow update in three stages (interaction/lead/wall_update.py): the walls found last
    stay in force until the near wall's gradient is computed, at the update's reference,
    two ticks after; that gradient is the finite difference of walls.slacks (the public,
    allocating path) at that reference."""
    from sixplus3.interaction.lead import wall_update as lw
    from sixplus3.interaction.lead import walls
    from sixplus3.interaction.lead.leadthrough import LeadThrough
    from sixplus3.kinematics.robot import robot_ik

    home = robot_ik(np.asarray(ROBOT.home_position), np.eye(3), np.asarray(ROBOT.home_psi),
                    ROBOT)
    from sixplus3.interaction.lead.leadthrough import CONFIRM

    lt = LeadThrough(ROBOT, 1000.0)
    for _ in range(CONFIRM):
        lt.step(home.theta[0], np.zeros(9))
    lt.st.mode = Mode.LEAD
    lt.st.p_ref = np.asarray(ROBOT.home_position) + [0.21, 0.0, 0.0]  # the clearance near
    p, R, psi = lt.st.p_ref.copy(), lt.st.R_ref.copy(), lt.st.psi_ref.copy()
    old = [(np.ones(9), -1.0)]
    lt.st.walls = old
    lt._slow_update()
    assert lt._wu.staged is not None and lt.st.walls == old  # the last walls in force
    lt.st.p_ref = p + [0.001, 0.0, 0.0]  # the reference moves on meanwhile
    lt._found(lt._wu.middle())
    assert lt._wu.pending is not None and lt.st.walls == old  # a wall is near: still
    lt.st.p_ref = p + [0.002, 0.0, 0.0]
    lt.st.walls = lt._wu.second()
    assert lt._wu.pending is None and len(lt.st.walls) == 1
    g, b = lt.st.walls[0]
    now = walls.slacks(ROBOT, p[None], R[None], psi[None])[0]
    assert 0.0 < now[3] < walls.WALL_BAND and now[:3].min() > walls.WALL_BAND
    d = lw.TWIST_STEP * np.eye(6)
    d[:, 3:] /= walls.ANGLE_SCALE
    p2, r2 = walls.moved(p, R, d)
    ref = (walls.slacks(ROBOT, p2, r2, np.repeat(psi[None], 6, axis=0))[:, 3]
           - now[3]) / lw.TWIST_STEP
    np.testing.assert_allclose(g[:6], ref, rtol=0, atol=1e-9)
    assert g[0] < 0.0  # further along +x is into the wall
    assert b == pytest.approx(-lw.WALL_RATE * now[3])
    assert lt.walls_met == 1


def test_the_native_tick_is_the_buffered_one() -> None:
    """WrenchStream's one-call sample (the generated C called from the kernel by
    address, dynamics/native.py) against the same stream through CasADi's buffers: the
    same numbers, the same errors (a reading not finite, angles of no assembly) and the
    same recovery after them."""
    from sixplus3.dynamics.codegen import codegen_enabled
    from sixplus3.dynamics.native import native
    from sixplus3.interaction.observer.stream import WrenchStream
    from sixplus3.kinematics.robot import robot_ik_pose

    robot = perturbed_plant(ROBOT, 6, mass=0.1, rotor=0.1, friction=1.2)
    a = WrenchStream(robot, 1000.0, compiled=True)
    b = WrenchStream(robot, 1000.0, compiled=True)
    if codegen_enabled():
        assert a._native is not None  # the libraries CompiledState built are found
    b._native = None
    assert native("no_such_function", "0", a.model._kin) is None  # type: ignore[union-attr]
    cfg = robot_ik_pose([0.03, 0.02, 0.6], [0.2, 0.1, -0.3], [1.4, 1.7, 1.5], robot=robot)
    rng = np.random.default_rng(4)
    th = cfg.theta[0]
    for k in range(40):
        th = th + rng.normal(0.0, 0.002, 9)
        tau = rng.normal(0.0, 2.0, 9)
        reading = th
        if k == 15:
            reading = th.copy()
            reading[2] = np.nan
        elif k == 25:
            reading = th + 3.0
        outs = []
        for s in (a, b):
            try:
                w, std, band, contact = s.update(reading, tau)
                outs.append((w, std, band, contact, *(a.copy() for a in s.sample),
                             s.model.position, s.model.psi))
            except InputError as exc:
                outs.append(str(exc))
        if isinstance(outs[0], str):
            assert outs[0] == outs[1], k
            continue
        for u, v in zip(*outs, strict=True):
            np.testing.assert_allclose(u, v, rtol=0, atol=1e-12, err_msg=str(k))


def test_a_site_torque_limit_bounds_lead_through_from_the_cli_and_the_api(tmp_path) -> None:
    """Session 34: under a site file of ``limits: {torque: 4}``, lead-through asked
    9.70 N m, printed "limit 10" and exited 0.  Now every command (tau_ff + the drive's
    PD, as the drive computes it) stays within 97 % of the site's 4 N m, from the API and
    the command line, which prints the site's limit; a lower rate limit lowers the guided
    joint rates too."""
    from click.testing import CliRunner

    from sixplus3.cli import main as cli
    from sixplus3.control.drive.hand import hand_from_dict
    from sixplus3.identification.report import robot_yaml
    from sixplus3.interaction.lead.leadthrough import RATE_SHARE, LeadThrough
    from sixplus3.interaction.people.hand import run_lead
    from sixplus3.robot_description import hardware

    site = tmp_path / "site.yaml"
    site.write_text("limits: {torque: 4, velocity: 6}\n")
    hw = hardware.load_hardware(str(site))
    # a firm pull: the default build asks ~9.7 N m of a 300/6 drive
    hand = {"stiffness": 2000.0, "damping": 20.0, "delay": 0.05, "duration": 0.8,
            "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 0.3, "offset": [0.06, 0, 0]}]}
    hardware.use(hw)
    try:
        lt = LeadThrough(ROBOT, 1000.0, drive_gains=(3000.0, 30.0))
        assert lt.cap == 4.0 and lt.tables.rate_cap == RATE_SHARE * 6.0
        run = run_lead(ROBOT, PLANT, hand_from_dict(hand), lead=lt, kp=3000.0, kd=30.0)
    finally:
        hardware.use(None)
    assert run.peak_command <= 0.97 * 4.0 + 1e-9, run.peak_command
    assert np.abs(run.rate_ref).max() <= RATE_SHARE * 6.0 + 1e-9
    # the API with the site given explicitly, the active one the catalogue's
    assert LeadThrough(ROBOT, 1000.0, hardware=hw).cap == 4.0
    plant = tmp_path / "plant.yaml"
    plant.write_text(robot_yaml(PLANT))
    hand_file = tmp_path / "hand.yaml"
    import yaml

    hand_file.write_text(yaml.safe_dump(hand))
    res = CliRunner().invoke(cli, ["--hardware", str(site), "simulate", "--plant",
                                   str(plant), "--lead", str(hand_file), "--log",
                                   str(tmp_path / "l.csv"), "--kp", "3000", "--kd", "30"])
    assert res.exit_code == 0, res.output
    assert "limit 4)" in res.output, res.output
    peak = float(res.output.split("peak |tau| asked of the drives ")[1].split(" N m")[0])
    assert peak <= 0.97 * 4.0 + 0.005, res.output


def test_warmup_runs_every_first_use_path(tmp_path) -> None:
    """``sixplus3 warmup`` (and the end of ``sixplus3 demo``) runs once each path whose
    kernels compile on first use, on a small log it makes: each returns, and a second
    run is fast (its figures: BENCHMARKS.md, "First runs")."""
    from click.testing import CliRunner

    from sixplus3.cli import main as cli
    from sixplus3.cli.warmup import warm

    secs = warm(ROBOT, None, say=lambda _s: None)
    assert set(secs) == {"the wrench estimator (sixplus3 wrench)",
                         "the identification's check (identify check)",
                         "the motors' directions (commission directions)",
                         "lead-through and the streaming observer",
                         "the drive's contact model (a site's position_loop)"}
    res = CliRunner().invoke(cli, ["warmup"])
    assert res.exit_code == 0 and "compiled in" in res.output, res.output
