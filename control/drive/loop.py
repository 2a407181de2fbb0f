"""One tick of the nine drives on the MuJoCo plant: the one drive loop the virtual
prototype's replay (:func:`~sixplus3.control.drive.plant.run_on_plant`), its jog
(:func:`~sixplus3.control.drive.plant.run_jog`) and the simulated person
(:mod:`sixplus3.interaction.person`) step through (docs/identification.md, "The virtual
prototype").

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
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sixplus3.control.drive.simulation import MujocoRobot
from sixplus3.errors import InputError, check_number
from sixplus3.robot_description.hardware import effective_limits
from sixplus3.robot_description.mjcf import TIMESTEP
from sixplus3.robot_description.robot import Robot, require_robot

#: Default standard deviation of the torque monitor's noise [N m at the joint].
TORQUE_NOISE = 0.005
#: [s] the time constant of the ``"filtered"`` rate feedback's low-pass.
FILTER_TAU = 1e-3
#: The drive's rate feedbacks (module doc).
RATE_FEEDBACKS = ("plant", "encoder", "filtered")


@dataclass(frozen=True)
class Tick:
    """What one tick did: the encoder's angles (9) at its start, the command asked
    (9, before the drive's limit) and the torque applied over the tick (9)."""

    theta: np.ndarray
    command: np.ndarray
    applied: np.ndarray


class DriveLoop:
    """The nine drives of ``plant`` at ``rate`` [Hz] with PD gains ``kp`` [N m/rad] and
    ``kd`` [N m s/rad] (module doc).  :meth:`start` puts the plant at a configuration;
    each :meth:`tick` reads, commands and advances one tick."""

    def __init__(self, plant: Robot, rate: float, kp: float, kd: float,
                 timestep: float = TIMESTEP, torque_noise: float = TORQUE_NOISE,
                 seed: int = 0, rate_feedback: str = "plant") -> None:
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
        """The actuated angles as the encoders read them (quantised to a count)."""
        d = self.sim.data
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
        applied = np.rint(np.clip(u, -self.cap, self.cap) / self.t_unit) * self.t_unit
        self.sim.data.ctrl[:] = applied
        if advance:
            self.advance(hook)
        return Tick(theta=th, command=u, applied=applied)

    def advance(self, hook: Callable[[int], None] | None = None) -> None:
        """The plant moved one tick under the applied torques."""
        mj, m, d = self.sim.mj, self.sim.model, self.sim.data
        for s in range(self.n_sub):
            if hook is not None:
                hook(s)
            mj.mj_step(m, d)


__all__ = ["FILTER_TAU", "RATE_FEEDBACKS", "TORQUE_NOISE", "DriveLoop", "Tick"]
