"""Lead-through guided by a simulated hand (docs/leadthrough.md, "The simulated hand"):
:func:`run_lead` builds lead-through (or takes one to run again) and runs it on the
virtual prototype with the hand on the platform
(:func:`sixplus3.control.drive.hand.guide`, the hand beside the plant it drives)."""

from __future__ import annotations

import numpy as np

from sixplus3.control.drive.hand import Hand, LeadRun, guide
from sixplus3.control.drive.loop import KD, KP, TORQUE_NOISE, DriveSettings
from sixplus3.errors import InputError
from sixplus3.interaction.lead.leadthrough import LeadThrough
from sixplus3.interaction.observer.wrench import SingleState
from sixplus3.robot_description.mjcf import TIMESTEP
from sixplus3.robot_description.robot import Robot, require_robot


def run_lead(model: Robot, plant: Robot, hand: Hand, lead: LeadThrough | None = None,
             rate: float = 1000.0, kp: float = KP, kd: float = KD, seed: int = 0,
             torque_noise: float = TORQUE_NOISE, timestep: float = TIMESTEP,
             start: np.ndarray | None = None) -> LeadRun:
    """The hand guides the platform of ``plant`` (from ``start``, Pinocchio's q of
    ``model``; default its home) through the drives (their rate feedback the encoder's
    difference), ``lead`` (default: a LeadThrough of ``model`` with the drive's gains)
    in the loop, for the hand's duration."""
    model, plant = require_robot(model), require_robot(plant)
    lt = lead if lead is not None else LeadThrough(model, rate, drive_gains=(kp, kd))
    if abs(lt.rate - rate) > 1e-9 or lt.robot.hash != model.hash:
        raise InputError("the lead-through given is for another rate or robot",
                         value=lt.rate, valid=f"{rate:g} Hz, robot {model.name}")
    lt.reset()
    state = SingleState(plant)

    def holding(theta: np.ndarray) -> np.ndarray:
        # the drives held the plant still before (whatever controller ran then): the
        # torque at rest at the encoder's first angles
        return np.asarray(state.state(theta, np.zeros(9))[2], dtype=float)

    drive = DriveSettings(rate_feedback="encoder", torque_noise=torque_noise, seed=seed,
                          timestep=timestep)
    return guide(model, plant, hand, lt, holding, rate, kp, kd, drive, start)


__all__ = ["run_lead"]
