"""The one drive loop of every simulation (docs/architecture.md, "One tick"):
:func:`run` steps a controller (:class:`~sixplus3.control.drive.command.TickController`)
once per tick on the nine drives of a MuJoCo plant (:class:`DriveLoop`).  The virtual
prototype's replay and jog (:mod:`~sixplus3.control.drive.plant`), the ideal drive's
replay (:func:`~sixplus3.control.drive.simulation.simulate`), the simulated person
(:mod:`sixplus3.control.drive.person`) and the simulated hand
(:mod:`sixplus3.control.drive.hand`) all go through it (docs/identification.md, "The
virtual prototype").

Each tick, as the prototype's drives run:

- the encoder is read: the plant's angle quantised to one count of the motor's encoder
  (``encoder_bits`` per motor turn through the belt);
- the rate feedback: the plant's own rate (``rate_feedback="plant"``: a drive's speed
  observer at its best), the encoder's difference over the last tick (``"encoder"``:
  what a drive without an observer has), or that difference through a first-order
  low-pass of time constant FILTER_TAU (``"filtered"``: a drive's speed filter, which
  lags the true rate by about FILTER_TAU in an acceleration);
- the command u = tau_ff + Kp (theta_ref - theta) + Kd (theta_dot_ref - theta_dot),
  quantised to the drive's torque unit (0.1 % of the motor's rated torque at the joint)
  and applied within the drive's limit (what the drive can give: MuJoCo's actuator
  range is the same), held over the tick in MuJoCo's sub-steps, with an optional hook
  before each sub-step (an external force);
- the torque monitor reads what was applied, quantised, with a seeded Gaussian noise.

An ``ideal`` drive (the replay that checks a file's feed-forward) reads the plant's angle
and rate exactly and applies its command as asked: no quantisation, no limit, no noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sixplus3.control.drive.command import DriveCommand, Mode, TickController
from sixplus3.control.drive.mujoco_model import MujocoRobot
from sixplus3.errors import InputError, check_number
from sixplus3.robot_description.hardware import effective_limits
from sixplus3.robot_description.mjcf import TIMESTEP
from sixplus3.robot_description.robot import Robot, require_robot

#: Default PD gains of the drives [N m/rad, N m s/rad]: about 100 rad/s bandwidth,
#: critically damped, on a joint of 0.03 kg m^2 (rotor + links).
KP, KD = 300.0, 6.0
#: Default standard deviation of the torque monitor's noise [N m at the joint].
TORQUE_NOISE = 0.005
#: [s] the time constant of the ``"filtered"`` rate feedback's low-pass.
FILTER_TAU = 1e-3
#: The drive's rate feedbacks (module doc).
RATE_FEEDBACKS = ("plant", "encoder", "filtered")


@dataclass(frozen=True)
class DriveSettings:
    """A simulated drive's settings beside its PD gains (module doc): its rate feedback
    (one of :data:`RATE_FEEDBACKS`), the torque monitor's noise [N m] and its seed, and
    MuJoCo's step [s]."""

    rate_feedback: str = "encoder"
    torque_noise: float = TORQUE_NOISE
    seed: int = 0
    timestep: float = TIMESTEP

    @classmethod
    def of(cls, drive: DriveSettings | None) -> DriveSettings:
        """``drive``, or the default settings for None; anything else is refused."""
        if drive is None:
            return cls()
        if not isinstance(drive, cls):
            raise InputError("drive must be a DriveSettings", value=type(drive).__name__,
                             valid="control.drive.loop.DriveSettings")
        return drive

    def loop(self, plant: Robot, rate: float, kp: float, kd: float) -> DriveLoop:
        """The drives of ``plant`` at ``rate`` with these settings (checked there)."""
        return DriveLoop(plant, rate, kp, kd, self.timestep, self.torque_noise, self.seed,
                         rate_feedback=self.rate_feedback)


@dataclass(frozen=True)
class Tick:
    """What one tick did: the encoder's angles (9) at its start, the command asked
    (9, before the drive's limit) and the torque applied over the tick (9)."""

    theta: np.ndarray
    command: np.ndarray
    applied: np.ndarray
    #: the rate feedback the PD used
    theta_dot: np.ndarray


class DriveLoop:
    """The nine drives of ``plant`` at ``rate`` [Hz] with PD gains ``kp`` [N m/rad] and
    ``kd`` [N m s/rad] (module doc).  :meth:`start` puts the plant at a configuration;
    each :meth:`tick` reads, commands and advances one tick."""

    def __init__(self, plant: Robot, rate: float, kp: float, kd: float,
                 timestep: float = TIMESTEP, torque_noise: float = TORQUE_NOISE,
                 seed: int = 0, rate_feedback: str = "plant", ideal: bool = False) -> None:
        self.plant = require_robot(plant)
        self.rate = check_number("rate", rate, 100.0, 20000.0)
        self.kp = check_number("kp", kp, 0.0, 1e5)
        self.kd = check_number("kd", kd, 0.0, 1e4)
        check_number("torque_noise", torque_noise, 0.0, 1.0)
        check_number("seed", seed, 0, 2 ** 32 - 1, integer=True)
        if rate_feedback not in RATE_FEEDBACKS:
            raise InputError(f"rate_feedback must be one of {', '.join(RATE_FEEDBACKS)}, "
                             f"got {rate_feedback!r}", value=rate_feedback,
                             valid=", ".join(RATE_FEEDBACKS))
        self.rate_feedback = rate_feedback
        self.ideal = bool(ideal)
        if self.ideal and (rate_feedback != "plant" or torque_noise != 0):
            raise InputError("an ideal drive reads the plant's own rate, with no torque "
                             "noise", value=(rate_feedback, torque_noise),
                             valid='rate_feedback "plant", torque_noise 0')
        self.torque_noise = float(torque_noise)
        self.sim = MujocoRobot(self.plant, timestep)
        self.n_sub = round(1.0 / (self.rate * timestep))
        mot = self.plant.motors
        #: encoder counts per joint radian, and the drive's torque unit [N m at the joint]
        self.counts = mot.gear_ratio * 2 ** mot.encoder_bits / (2 * math.pi)
        self.t_unit = mot.gear_ratio * mot.rated_torque / 1000.0
        #: the drive's own torque limit: the plant's, tightened by the site's (a site
        #: sets its drives' limit too: the drive clamps whatever it is asked)
        self.cap = effective_limits(self.plant).torque
        self.rng = np.random.default_rng(seed)
        self._prev: np.ndarray | None = None
        self._filtered = np.zeros(9)  # the "filtered" feedback's state

    def start(self, q: np.ndarray, theta_dot: np.ndarray | None = None) -> None:
        """The plant at the configuration q (Pinocchio's coordinates), at rest or with
        the actuated rates ``theta_dot``."""
        self.sim.set_state(np.asarray(q, dtype=float),
                           np.zeros(9) if theta_dot is None else np.asarray(theta_dot))
        self._prev = None
        self._filtered = np.zeros(9)

    def encoder(self) -> np.ndarray:
        """The actuated angles as the encoders read them (quantised to a count; an ideal
        drive's exact)."""
        d = self.sim.data
        if self.ideal:
            return np.array(d.qpos[self.sim.act_qpos])
        return np.rint(d.qpos[self.sim.act_qpos] * self.counts) / self.counts

    def true_angles(self) -> np.ndarray:
        return np.array(self.sim.data.qpos[self.sim.act_qpos])

    def monitor(self, applied: np.ndarray) -> np.ndarray:
        """The torque monitor's reading of ``applied``: quantised, with its noise."""
        if self.torque_noise <= 0:
            return np.asarray(applied, dtype=float).copy()
        return np.rint((applied + self.rng.normal(0.0, self.torque_noise, 9))
                       / self.t_unit) * self.t_unit

    def tick(self, theta_ref: np.ndarray, theta_dot_ref: np.ndarray, tau_ff: np.ndarray,
             hook: Callable[[int], None] | None = None, advance: bool = True,
             theta: np.ndarray | None = None) -> Tick:
        """One tick: the encoder read (or ``theta``, read by the caller this tick), the
        PD plus feed-forward quantised and applied within the drive's limit, then
        (``advance``) the plant moved one tick, ``hook(sub_step)`` before each
        sub-step."""
        th = self.encoder() if theta is None else theta
        if self.rate_feedback in ("encoder", "filtered"):
            thd = np.zeros(9) if self._prev is None else (th - self._prev) * self.rate
            if self.rate_feedback == "filtered":
                dt = 1.0 / self.rate
                self._filtered += dt / (FILTER_TAU + dt) * (thd - self._filtered)
                thd = self._filtered.copy()
        else:
            thd = np.array(self.sim.data.qvel[self.sim.act_dof])
        self._prev = th
        u = tau_ff + self.kp * (theta_ref - th) + self.kd * (theta_dot_ref - thd)
        applied = (u if self.ideal else
                   np.rint(np.clip(u, -self.cap, self.cap) / self.t_unit) * self.t_unit)
        self.sim.data.ctrl[:] = applied
        if advance:
            self.advance(hook)
        return Tick(theta=th, command=u, applied=applied, theta_dot=thd)

    def advance(self, hook: Callable[[int], None] | None = None) -> None:
        """The plant moved one tick under the applied torques."""
        mj, m, d = self.sim.mj, self.sim.model, self.sim.data
        for s in range(self.n_sub):
            if hook is not None:
                hook(s)
            mj.mj_step(m, d)


@dataclass(frozen=True)
class Run:
    """What :func:`run` logged, one row a tick: the encoder's angles the controller read
    (n, 9), the commands it returned (n), the drive's whole command before its limit
    and the torque applied over the tick (n, 9); ``readings`` (n + 1, 9): the torque
    monitor's reading at the start of each tick (what the controller got; row 0 NaN
    when nothing was applied before), and row n its reading of the last tick's torque,
    read after it (NaN unless ``final``).  A drive log pairs each tick's angles with
    the torque applied over it: ``readings[1:]``."""

    theta: np.ndarray
    commands: list[DriveCommand]
    command: np.ndarray
    applied: np.ndarray
    readings: np.ndarray


#: Called before each tick's plant step, with the tick and the controller's command: a
#: hook run before each MuJoCo sub-step (an external force), or None.
Before = Callable[[int, DriveCommand], "Callable[[int], None] | None"]
#: Called after each tick, with the tick and what it did (a measurement of the plant).
After = Callable[[int, Tick], None]


def run(loop: DriveLoop, controller: TickController, ticks: int,
        initial: np.ndarray | None = None, before: Before | None = None,
        after: After | None = None, final: bool = False,
        advance_last: bool = True) -> Run:
    """The one drive loop: ``ticks`` ticks of ``controller`` on ``loop``'s drives, from
    the plant as :meth:`DriveLoop.start` left it.  Each tick the encoder and the torque
    monitor are read (the monitor reads the torque applied over the previous tick, at
    the first tick ``initial``: what held the plant before, or None when nothing was
    and the controller reads no torque), the controller steps, and the drive applies its
    command (a ``fault`` command: the drive holds where it is, its reference the angles
    it read) and the plant moves one tick (not after the last unless ``advance_last``).
    ``final``: the monitor reads the last tick's torque too (:class:`Run`)."""
    check_number("ticks", ticks, 1, 10 ** 8, integer=True)
    th_log, cmd_log, app_log = (np.empty((ticks, 9)) for _ in range(3))
    readings = np.full((ticks + 1, 9), np.nan)
    commands: list[DriveCommand] = []
    applied = None if initial is None else np.asarray(initial, dtype=float)
    for k in range(ticks):
        th = loop.encoder()
        if applied is not None:
            readings[k] = loop.monitor(applied)
        cmd = controller.step(th, readings[k])
        commands.append(cmd)
        hook = before(k, cmd) if before is not None else None
        ref = th if cmd.mode == Mode.FAULT else cmd.theta_ref
        tick = loop.tick(ref, cmd.theta_dot_ref, cmd.tau_ff, hook,
                         advance=advance_last or k < ticks - 1, theta=th)
        applied = tick.applied
        th_log[k], cmd_log[k], app_log[k] = th, tick.command, applied
        if after is not None:
            after(k, tick)
    if final and applied is not None:
        readings[ticks] = loop.monitor(applied)
    return Run(theta=th_log, commands=commands, command=cmd_log, applied=app_log,
               readings=readings)


__all__ = ["FILTER_TAU", "KD", "KP", "RATE_FEEDBACKS", "TORQUE_NOISE", "After", "Before",
           "DriveLoop", "DriveSettings",
           "Run", "Tick", "run"]
