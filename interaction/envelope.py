"""What every controller's command must satisfy and what it may read
(docs/safety.md, "The command on any drive"): a reading checked before any observer
sees it (:func:`reading`, :func:`jump_bound`), the drive's rate as a controller models
it (:class:`DriveRate`, :func:`parse_drive`), and the whole command tau_ff + PD kept
within the envelope for every rate the drive may use (:func:`within_envelope`).  The
contact guard and lead-through both apply it."""

from __future__ import annotations

import math

import numpy as np

from sixplus3.control.drive.command import DriveCommand
from sixplus3.errors import InputError, check_number
from sixplus3.interaction.observer._tick_kernel import envelope
from sixplus3.robot_description.limits import Limits

#: The share of the envelope a command (tau_ff plus the drive's PD) may ask for when the
#: drive's gains are known (the rest: the drive's own rate estimate, which the guard's
#: encoder difference only approximates).
COMMAND_SHARE = 0.97
#: [rad] a measured angle this far outside the joints' range is not a reading: no joint
#: gets there (a broken encoder, a wrong unit, 1e300).
ANGLE_SLACK = 1.0
#: A measured torque beyond this multiple of the hardware's torque limit is not a
#: reading: no drive applies it (the monitor's noise is a few thousandths of it).
TORQUE_SLACK = 2.0
#: [rad] the largest change of a measured angle in one tick beyond the joint rate limit's
#: own (a faulty reading otherwise: the guard's and lead-through's jump check).
MAX_JUMP = 0.05


def within_envelope(cmd: DriveCommand, kp: np.ndarray, kd: np.ndarray, theta: np.ndarray,
                    vel: np.ndarray, cap: float, spread: np.ndarray | None = None
                    ) -> tuple[DriveCommand, float]:
    """(the command, the largest |total| the drive would have been asked for at the rate
    ``vel`` without the move): the reference moved toward the measured angles ``theta`` (or, with
    Kp = 0, the rate reference toward the measured rate ``vel``, the encoder's
    difference over the last tick) wherever the drive's total tau_ff + Kp (theta_ref -
    theta) + Kd (theta_dot_ref - v) would leave +-``cap`` for a rate feedback v anywhere
    in ``vel`` +- ``spread`` (:class:`DriveRate`: the drive's rate as modelled).  A
    blocked platform then never gets more than the envelope from a reference that runs
    ahead, whatever rate estimate the drive uses within the spread."""
    ref, vref = cmd.theta_ref.copy(), cmd.theta_dot_ref.copy()
    ff = np.array(cmd.tau_ff, dtype=float)
    sp = np.zeros(9) if spread is None else np.asarray(spread, dtype=float)
    wanted, moved = envelope(ff, ref, vref, np.asarray(kp, dtype=float),
                             np.asarray(kd, dtype=float), np.asarray(theta, dtype=float),
                             np.asarray(vel, dtype=float), sp, float(cap))
    if not moved:
        return cmd, wanted
    return DriveCommand(ref, vref, ff, cmd.mode, cmd.contact, cmd.wrench), wanted


def reading(theta: object, tau: object, lim: Limits) -> tuple[np.ndarray, np.ndarray] | str:
    """(theta, tau) as 9 floats each, or the reason they are not a reading (never
    raises, for any Python object): not 9 numbers each, not finite, an angle more than
    ANGLE_SLACK outside ``lim``'s range, or a torque beyond TORQUE_SLACK times its torque
    limit (1e300 is finite, and would poison an observer's integral for good)."""
    try:
        for x in (theta, tau):
            if hasattr(x, "__len__") and len(x) != 9:  # type: ignore[arg-type]
                return "a measured angle or torque is not 9 finite numbers"
        th = np.array(theta, dtype=float).reshape(-1)
        tq = np.array(tau, dtype=float).reshape(-1)
    except Exception:  # noqa: BLE001 - any object a caller may pass
        return "a measured angle or torque is not 9 finite numbers"
    if th.shape != (9,) or tq.shape != (9,) or not (np.all(np.isfinite(th))
                                                    and np.all(np.isfinite(tq))):
        return "a measured angle or torque is not 9 finite numbers"
    lo, hi = lim.theta_min - ANGLE_SLACK, lim.theta_max + ANGLE_SLACK
    if np.any(th < lo) or np.any(th > hi):
        return (f"a measured angle is outside [{lo:.3f}, {hi:.3f}] rad (the joints' range "
                f"with {ANGLE_SLACK:g} rad of slack): not a reading")
    tmax = TORQUE_SLACK * lim.torque
    if np.any(np.abs(tq) > tmax):
        return f"a measured torque is beyond {tmax:g} N m: not a reading"
    return th, tq


def jump_bound(lim: Limits, dt: float, ticks: int) -> float:
    """[rad] the largest change of a measured angle over ``ticks`` ticks of ``dt`` [s]
    that is not a faulty reading: MAX_JUMP, plus the joint rate limit's travel over the
    ticks after the first (readings lost between: the robot moved meanwhile)."""
    return MAX_JUMP + lim.velocity * dt * max(0, ticks - 1)


#: The drive rate feedbacks a controller models (:class:`DriveRate`), and the one a
#: drive is taken to use when ``drive_gains`` does not say (with its filter's default
#: time constant [s]).
DRIVE_RATES = ("encoder", "true", "filtered")
DEFAULT_RATE = ("encoder", 1e-3)


class DriveRate:
    """The rate the drive's PD uses, as the controller models it from the encoders, and
    how far the drive's may be from that model (per joint, [rad/s]): the whole command's
    bound holds for every rate in model +- spread (docs/safety.md, "The command on any
    drive").  ``kind``, what the drive is set to:

    - ``"encoder"``: the encoder's difference over the last tick, as the controller
      reads it: the model is exact (no spread);
    - ``"filtered"``: that difference through a first-order low-pass of time constant
      ``tau`` [s] (a drive's speed filter, set to ``tau``): the controller runs the same
      filter, exact too;
    - ``"true"``: the joint's true rate (a drive's speed observer at its best): it leads
      the difference by about half a tick of acceleration; the model is the difference
      plus half its last change, the spread SAFETY times half the larger of the last two
      changes of that change (what the acceleration did since: a contact's onset shows
      a tick late), plus LEAD times the last change, plus a count over a tick.

    A drive set otherwise is outside the bound: the drive's own torque limit (the drive
    table exports it) is then the only bound."""

    #: margins of the true rate's spread: on the change of the acceleration, and a share
    #: of the acceleration itself (a clamp's stiffness changes it within a tick:
    #: BENCHMARKS.md, "Safety that holds like the gate")
    SAFETY = 1.5
    LEAD = 0.25

    def __init__(self, rate: float, robot: object, kind: str = DEFAULT_RATE[0],
                 tau: float = DEFAULT_RATE[1]) -> None:
        if kind not in DRIVE_RATES:
            raise InputError(f"drive_rate must be one of {', '.join(DRIVE_RATES)}, got "
                             f"{str(kind)[:40]!r}", value=str(kind)[:40],
                             valid=", ".join(DRIVE_RATES))
        mot = robot.motors  # type: ignore[attr-defined]
        # [rad] one encoder count at the joint; over a tick, the true rate's spread's floor
        count = 2.0 * math.pi / (float(mot.gear_ratio) * 2.0 ** int(mot.encoder_bits))
        self.kind = kind
        self.tau = check_number("drive_rate_tau [s]", tau, 0.0, 0.1)
        self.dt = 1.0 / rate
        self._floor = count / self.dt
        self.reset()

    def reset(self) -> None:
        self._v: np.ndarray | None = None  # the last encoder difference
        self._dv = np.zeros(9)  # its last change
        self._jerk = np.zeros(9)  # the last change of that change
        #: the modelled rate (9,) and its spread (9,) [rad/s] at the last update
        self.rate = np.zeros(9)
        self.spread = np.full(9, self._floor if self.kind == "true" else 0.0)

    def update(self, vel: np.ndarray) -> None:
        """This tick's encoder difference ``vel`` (two good readings in a row)."""
        # before the first difference the drive held the robot at rest (a filter's state
        # at 0): the first difference's change is not known
        dv = np.zeros(9) if self._v is None else vel - self._v
        if self.kind == "filtered":
            self.rate = self.rate + self.dt / (self.tau + self.dt) * (vel - self.rate)
        elif self.kind == "true":
            self.rate = vel + 0.5 * dv
            jerk = np.abs(dv - self._dv)
            self.spread = (self.SAFETY * 0.5 * np.maximum(jerk, self._jerk)
                           + self.LEAD * np.abs(dv) + self._floor)
            self._jerk = jerk
        else:
            self.rate = vel.copy()
        self._dv, self._v = dv, vel.copy()


def parse_drive(gains: object) -> tuple[np.ndarray, np.ndarray, str, float]:
    """(Kp, Kd, the drive's rate feedback, its filter's time constant [s]) from
    ``drive_gains``: (Kp, Kd), (Kp, Kd, RATE) or (Kp, Kd, "filtered", TAU), RATE one of
    :data:`DRIVE_RATES` ("encoder" when not given: :class:`DriveRate`)."""
    if not isinstance(gains, (tuple, list)) or not 2 <= len(gains) <= 4:
        raise InputError("drive_gains must be (Kp, Kd[, rate feedback[, filter tau]])",
                         value=repr(gains)[:80], valid="(Kp, Kd), (Kp, Kd, 'encoder'|'true'|"
                         "'filtered'[, tau])")
    kp, kd = parse_gains((gains[0], gains[1]))
    kind = gains[2] if len(gains) > 2 else DEFAULT_RATE[0]
    if not isinstance(kind, str) or kind not in DRIVE_RATES:
        raise InputError(f"the drive's rate feedback must be one of {', '.join(DRIVE_RATES)}",
                         value=repr(kind)[:40], valid=", ".join(DRIVE_RATES))
    tau = (check_number("the drive's rate filter [s]", gains[3], 0.0, 0.1) if len(gains) > 3
           else DEFAULT_RATE[1])
    return kp, kd, kind, tau


def parse_gains(gains: tuple[object, object]) -> tuple[np.ndarray, np.ndarray]:
    """(Kp, Kd) (9 each) of a drive's PD from scalars or 9 each; InputError otherwise."""
    try:
        kp, kd = (np.broadcast_to(np.asarray(x, dtype=float), (9,)).copy() for x in gains)
    except (TypeError, ValueError):
        raise InputError("drive_gains must be (Kp, Kd), scalars or 9 numbers each",
                         value=repr(gains)[:80], valid="(Kp, Kd)") from None
    for name, v, hi in (("Kp", kp, 1e6), ("Kd", kd, 1e4)):
        if not (np.all(np.isfinite(v)) and np.all(v >= 0) and np.all(v <= hi)):
            raise InputError(f"the drive's {name} must be in [0, {hi:g}]",
                             value=v.tolist(), valid=f"[0, {hi:g}]")
    return kp, kd


__all__ = ["ANGLE_SLACK", "COMMAND_SHARE", "DEFAULT_RATE", "DRIVE_RATES", "DriveRate",
           "MAX_JUMP", "TORQUE_SLACK", "jump_bound", "parse_drive", "parse_gains", "reading",
           "within_envelope"]
