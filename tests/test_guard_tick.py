"""The controllers' ticks on recorded readings, no MuJoCo (issue 68, item 6): the
readings a run on the simulated prototype gave each controller
(scripts/record_tick_inputs.py), played to a new one.

- The contact guard (the stiff drive; nobody in the way, then a free hand met at the
  fastest sample): no claim without a touch, a claim within 10 ms of the touch, a stop
  to rest, and a command tau_ff + PD (the drive's rate the encoder's difference) within
  the envelope.
- Lead-through (a hand pulls the tool point 4 cm): it leads, and stays within the
  envelope.

A controller is a function of its readings, so the replay gives the commands it sent:
they are compared bit for bit with the recording (a change of a controller's
arithmetic shows here; if it is meant, record again)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sixplus3.control.drive.command import DriveCommand, Mode, TickController
from sixplus3.errors import InputError
from sixplus3.interaction.contact.guard import ContactGuard
from sixplus3.interaction.envelope import COMMAND_SHARE
from sixplus3.robot_description.robot import Robot

DATA = Path(__file__).resolve().parent / "data"
RATE = 1000.0


@pytest.fixture(scope="module")
def recorded():
    return dict(np.load(DATA / "tick_readings.npz"))


@pytest.fixture(scope="module")
def guard(recorded):
    return ContactGuard(Robot.default(), DATA / "tick_move.csv", RATE,
                        drive_gains=(float(recorded["kp"]), float(recorded["kd"])))


def replay(guard: ContactGuard, theta: np.ndarray, tau: np.ndarray) -> list:
    guard.reset()
    return [guard.step(th, ta) for th, ta in zip(theta, tau, strict=True)]


def commands(cmds: list, theta: np.ndarray, kp: float, kd: float) -> np.ndarray:
    """(n, 9) what the drive applied: tau_ff + Kp (ref - theta) + Kd (ref_dot - rate),
    the rate the encoder's difference (the drive the guard was told of)."""
    rate = np.r_[np.zeros((1, 9)), np.diff(theta, axis=0) * RATE]
    return np.array([c.tau_ff + kp * (c.theta_ref - th) + kd * (c.theta_dot_ref - r)
                     for c, th, r in zip(cmds, theta, rate, strict=True)])


def test_nobody_there_the_guard_follows_the_file_to_its_end(guard, recorded) -> None:
    assert isinstance(guard, TickController)
    cmds = replay(guard, recorded["quiet_theta"], recorded["quiet_tau"])
    assert all(type(c) is DriveCommand and isinstance(c.mode, Mode) for c in cmds)
    np.testing.assert_array_equal(np.array([c.tau_ff for c in cmds]), recorded["quiet_ff"])
    assert not any(c.contact for c in cmds)
    modes = [c.mode for c in cmds]
    assert modes[0] == "follow" and modes[-1] == "done" and set(modes) == {"follow", "done"}
    np.testing.assert_array_equal(cmds[-1].theta_ref, guard.tables.theta[-1])
    limit = guard.lim.torque
    applied = commands(cmds, recorded["quiet_theta"], guard.kp, guard.kd)
    assert np.abs(applied).max() <= COMMAND_SHARE * limit + 1e-9


def test_a_touch_is_claimed_within_10_ms_and_the_guard_stops_within_its_envelope(
        guard, recorded) -> None:
    theta, tau = recorded["touch_theta"], recorded["touch_tau"]
    onset = int(recorded["touch_onset"])
    assert 0 < onset < len(theta)
    cmds = replay(guard, theta, tau)
    np.testing.assert_array_equal(np.array([c.tau_ff for c in cmds]), recorded["touch_ff"])
    flags = np.array([c.contact for c in cmds])
    assert not flags[:onset].any()  # no claim before the hand was touched
    first = int(np.argmax(flags))
    assert flags.any() and first - onset <= 10, (onset, first)
    modes = [c.mode for c in cmds]
    assert modes[first] in ("stop", "hold") and modes[-1] == "hold"
    assert "follow" not in modes[first:]  # a stop is latched
    np.testing.assert_array_equal(cmds[-1].theta_dot_ref, np.zeros(9))
    applied = commands(cmds, theta, guard.kp, guard.kd)
    assert np.abs(applied).max() <= COMMAND_SHARE * guard.lim.torque + 1e-9
    # the replay is the guard's function of its readings: the same again after a reset
    again = replay(guard, theta, tau)
    for a, b in zip(cmds, again, strict=True):
        assert a.mode == b.mode and a.contact == b.contact
        np.testing.assert_array_equal(a.tau_ff, b.tau_ff)


@pytest.mark.parametrize("bad", [1e300, np.nan, -np.inf])
def test_one_broken_reading_in_the_touch_neither_raises_nor_moves_the_guard(
        guard, recorded, bad) -> None:
    """A broken sensor's one reading in the middle of the touch: the guard says so, holds
    where its reference was (latched: it never follows again; the envelope shifts the
    held reference by at most the PD's reserve), and every command stays finite and
    within the torque limit."""
    theta, tau = recorded["touch_theta"].copy(), recorded["touch_tau"].copy()
    k = int(recorded["touch_onset"]) + 1
    theta[k, 4] = bad
    cmds = replay(guard, theta, tau)
    for c in cmds:
        assert np.isfinite(c.tau_ff).all() and np.isfinite(c.theta_ref).all()
        assert np.isfinite(c.theta_dot_ref).all()
        assert np.abs(c.tau_ff).max() <= guard.lim.torque
    assert [c.mode for c in cmds[:k]] == ["follow"] * k
    assert all(c.mode == "hold" for c in cmds[k:])
    assert any("not a reading" in e or "not 9 finite numbers" in e
               for e in guard.events), guard.events
    for c in cmds[k:]:  # held (the envelope shifts the reference by the PD's reserve)
        assert np.abs(c.theta_ref - cmds[k].theta_ref).max() < 0.02
        np.testing.assert_array_equal(c.theta_dot_ref, np.zeros(9))


def test_lead_through_leads_a_pull_within_its_envelope(recorded) -> None:
    from sixplus3.interaction.lead.leadthrough import LeadThrough

    kp, kd = float(recorded["lead_kp"]), float(recorded["lead_kd"])
    lt = LeadThrough(Robot.default(), RATE, drive_gains=(kp, kd))
    assert isinstance(lt, TickController)
    theta, tau = recorded["lead_theta"], recorded["lead_tau"]
    cmds = [lt.step(th, ta) for th, ta in zip(theta, tau, strict=True)]
    assert all(type(c) is DriveCommand and isinstance(c.mode, Mode) for c in cmds)
    np.testing.assert_array_equal(np.array([c.tau_ff for c in cmds]), recorded["lead_ff"])
    np.testing.assert_array_equal(np.array([c.theta_dot_ref for c in cmds]),
                                  recorded["lead_rate"])
    modes = [c.mode for c in cmds]
    # a fault until readings agree (leadthrough.py: CONFIRM), then hold and lead
    assert "lead" in modes and "fault" not in modes[3:]
    assert float(recorded["lead_moved"]) > 0.03  # the recording: the hand moved it 4 cm
    applied = commands(cmds, theta, kp, kd)
    assert np.abs(applied).max() <= COMMAND_SHARE * lt.lim.torque + 1e-9


def test_a_command_names_its_mode_from_the_enum() -> None:
    z = np.zeros(9)
    cmd = DriveCommand(z, z, z, "hold", False, np.zeros(6))
    assert cmd.mode is Mode.HOLD and cmd.mode == "hold" and f"{cmd.mode}" == "hold"
    with pytest.raises(ValueError):
        DriveCommand(z, z, z, "hurry", False, np.zeros(6))


def test_a_file_followed_as_it_is_is_a_controller_that_holds_at_its_end() -> None:
    from sixplus3.control.drive.command import FileController

    rng = np.random.default_rng(0)
    th, vel, ff = rng.normal(size=(3, 4, 9))
    hold = rng.normal(size=9)
    fc = FileController(th, vel, ff, hold_tau=hold)
    assert isinstance(fc, TickController)
    cmds = [fc.step(np.full(9, np.nan), None) for _ in range(6)]  # it reads nothing
    for k in range(4):
        np.testing.assert_array_equal(cmds[k].theta_ref, th[k])
        np.testing.assert_array_equal(cmds[k].theta_dot_ref, vel[k])
        np.testing.assert_array_equal(cmds[k].tau_ff, ff[k])
        assert cmds[k].mode is Mode.FOLLOW
    for c in cmds[4:]:  # past the end: the last angles, at rest, with the hold torque
        np.testing.assert_array_equal(c.theta_ref, th[-1])
        np.testing.assert_array_equal(c.theta_dot_ref, np.zeros(9))
        np.testing.assert_array_equal(c.tau_ff, hold)
        assert c.mode is Mode.DONE
    fc.reset()
    np.testing.assert_array_equal(fc.step(None, None).theta_ref, th[0])
    with pytest.raises(InputError, match=r"\(n, 9\)"):
        FileController(th[:, :8], vel, ff)
