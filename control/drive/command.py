"""The one tick shape every simulated drive loop steps (docs/architecture.md, "One
tick"): a controller (:class:`TickController`) reads the encoder's angles and the drives'
torques and returns a :class:`DriveCommand`, whose ``mode`` is a :class:`Mode`.  The
contact guard and lead-through are controllers; so is a file followed as it is
(:class:`FileController`: the virtual prototype's replay, its jog, a person met with
no guard, the ideal drive's replay).  :func:`~sixplus3.control.drive.loop.run` is the
loop they all go through, as libfranka's ``Robot::control(callback)`` is one loop
around any callback."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Protocol, runtime_checkable

import numpy as np

from sixplus3.errors import InputError


class Mode(str, Enum):
    """What a controller does this tick (a :class:`DriveCommand`'s ``mode``).  The
    guard: ``follow`` the file, ``stop`` along it, ``retract`` from a clamp (``settle``
    to rest first, reported as ``retract``), ``hold`` after a stop, ``done`` at the
    file's end.  Lead-through: ``hold`` at rest, ``lead`` a person's hand, ``fault``
    before its readings agree (the loop then holds the drive where it is).  A file
    followed as it is: ``follow``, then ``done`` past its end.  A str: it compares equal
    to its value."""

    FOLLOW = "follow"
    STOP = "stop"
    RETRACT = "retract"
    SETTLE = "settle"
    HOLD = "hold"
    DONE = "done"
    LEAD = "lead"
    FAULT = "fault"

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class DriveCommand:
    """What the drive applies: tau_ff + Kp (theta_ref - theta) + Kd (theta_dot_ref -
    theta_dot), the one command type of every controller a drive loop steps.  ``mode``
    (:class:`Mode`; a name is converted, an unknown one refused); ``contact``: the
    controller claims a contact; ``wrench`` (6): the estimated wrench at the platform
    centre, base frame [N, N m]."""

    theta_ref: np.ndarray
    theta_dot_ref: np.ndarray
    tau_ff: np.ndarray
    mode: Mode
    contact: bool
    wrench: np.ndarray

    def __post_init__(self) -> None:
        if not isinstance(self.mode, Mode):
            object.__setattr__(self, "mode", Mode(self.mode))


@runtime_checkable
class TickController(Protocol):
    """A controller a drive loop steps once per tick: the encoder's angles and the
    drives' torques in, a :class:`DriveCommand` out; it never raises (a reading it
    cannot use is a hold or a fault, with its reason)."""

    def step(self, theta: object, tau: object) -> DriveCommand: ...


class FileController:
    """A sampled motion followed as it is, one row a tick: (n, 9) ``theta``,
    ``theta_dot`` and ``tau_ff`` (the feed-forward held over each tick).  Past the last
    row it holds the last angles at rest with ``hold_tau`` (default: the last row's
    feed-forward), mode ``done``.  It reads nothing: what a drive replaying a file
    does, the readings only logged."""

    def __init__(self, theta: np.ndarray, theta_dot: np.ndarray, tau_ff: np.ndarray,
                 hold_tau: np.ndarray | None = None) -> None:
        theta, theta_dot, tau_ff = (np.asarray(a, dtype=float)
                                    for a in (theta, theta_dot, tau_ff))
        if (theta.ndim != 2 or theta.shape[1] != 9 or len(theta) == 0
                or theta_dot.shape != theta.shape
                or tau_ff.shape not in (theta.shape, (9,))):
            raise InputError("a followed motion is (n, 9) angles, rates and torques "
                             f"(n >= 1), got {theta.shape}, {theta_dot.shape}, "
                             f"{tau_ff.shape}", value=theta.shape, valid="(n, 9) arrays")
        self.theta, self.theta_dot = theta, theta_dot
        self.tau_ff = np.broadcast_to(tau_ff, theta.shape)
        self.hold_tau = (self.tau_ff[-1] if hold_tau is None
                         else np.asarray(hold_tau, dtype=float))
        self.k = 0
        self._zero = np.zeros(9)

    def reset(self) -> None:
        self.k = 0

    def step(self, theta: object, tau: object) -> DriveCommand:
        k, self.k = self.k, self.k + 1
        if k < len(self.theta):
            return DriveCommand(self.theta[k], self.theta_dot[k], self.tau_ff[k],
                                Mode.FOLLOW, False, np.zeros(6))
        return DriveCommand(self.theta[-1], self._zero, self.hold_tau, Mode.DONE, False,
                            np.zeros(6))


__all__ = ["DriveCommand", "FileController", "Mode", "TickController"]
