"""The contact guard met by a simulated person (docs/safety.md, "A simulated person"):
:func:`run_contact` validates the file, builds the guard (or takes one to run again)
and runs it on the virtual prototype with a body region in the way
(:func:`sixplus3.control.drive.person.meet`, the person beside the plant it drives)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sixplus3.control.drive.loop import FILTER_TAU, KD, KP, DriveSettings
from sixplus3.control.drive.person import Contact, ContactRun, checked_run, meet
from sixplus3.control.gate.validation import validate_file
from sixplus3.control.report import ValidationReport
from sixplus3.errors import InputError, ValidationFailed
from sixplus3.interaction.contact.guard import ContactGuard
from sixplus3.robot_description.robot import Robot, require_robot


def run_contact(path: str | Path, model: Robot, plant: Robot, contact: Contact | None,
                guard: bool | ContactGuard = True, kp: float = KP, kd: float = KD,
                after: float = 0.5, reaction: str = "hold",
                parameter_cov: tuple[np.ndarray, np.ndarray] | None = None,
                drive: DriveSettings | None = None) -> ContactRun:
    """Run the file on ``plant`` with the person ``contact`` (None: nobody, for false
    alarms) in the way, the guard in the loop (``guard``) or the plan followed as it
    is, for ``after`` seconds past the contact (or the file's end); ``reaction``: the
    guard's, hold or yield; ``drive``: the drives' rate feedback, torque noise, seed and
    MuJoCo's step (control/drive/loop.py; default: the encoder's difference);
    ``parameter_cov``: an identification's (base columns, covariance) for the guard's
    thresholds.  ``guard`` may be a :class:`ContactGuard` of this file and model: it is
    reset and run again (its tables are not rebuilt: a battery of contacts on a file)."""
    model = require_robot(model)
    drive = checked_run(kp, kd, after, drive)  # before anything is built
    rep = _report(path, model, guard)
    assert rep.header is not None
    g = _guard(guard, path, model, float(rep.header["rate_hz"]), reaction,
               _drive(kp, kd, drive.rate_feedback), parameter_cov)
    return meet(rep, path, model, plant, contact, g, kp, kd, after, drive)


def _report(path: str | Path, model: Robot, guard: bool | ContactGuard) -> ValidationReport:
    """The gate's report of the file: the one its guard was built on, or a new one;
    ValidationFailed for a file the gate refuses."""
    if isinstance(guard, ContactGuard) and guard.path.resolve() == Path(path).resolve():
        rep = guard.report
    else:
        rep = validate_file(path, model)
    if not rep.ok or rep.data is None or rep.header is None:
        raise ValidationFailed("not run: " + "; ".join(rep.messages()), rep.exit_code, rep)
    return rep


def _drive(kp: float, kd: float, rate_feedback: str) -> tuple[float, float, str, float]:
    """The guard's ``drive_gains`` for the simulated drives: their PD and their rate
    feedback as the guard models it (envelope.DriveRate: the plant's rate is the true
    rate, the filter the drive loop's)."""
    kind = {"plant": "true", "encoder": "encoder", "filtered": "filtered"}.get(
        rate_feedback if isinstance(rate_feedback, str) else "")
    if kind is None:
        raise InputError(f"rate_feedback must be plant, encoder or filtered, got "
                         f"{str(rate_feedback)[:40]!r}", value=str(rate_feedback)[:40],
                         valid="plant, encoder, filtered")
    return kp, kd, kind, FILTER_TAU


def _guard(guard: bool | ContactGuard, path: str | Path, model: Robot, rate: float,
           reaction: str, drive: tuple[float, float, str, float],
           parameter_cov: tuple[np.ndarray, np.ndarray] | None) -> ContactGuard | None:
    """The guard in the loop: the one given (of this file and model, reset), a new
    one, or none."""
    if isinstance(guard, ContactGuard):  # a guard of this file, run again from t = 0
        if guard.path.resolve() != Path(path).resolve() or guard.robot.hash != model.hash:
            raise InputError("the guard given is for another file or robot",
                             value=str(guard.path), valid=str(path))
        if guard.reaction != reaction:
            raise InputError("the guard given has another reaction", value=guard.reaction,
                             valid=reaction)
        guard.reset(drive_gains=drive)
        return guard
    return (ContactGuard(model, path, rate, reaction=reaction,
                         drive_gains=drive,
                         parameter_cov=parameter_cov) if guard else None)


__all__ = ["run_contact"]
