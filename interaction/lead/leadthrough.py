"""Lead-through: a person guides the platform by hand, sensorlessly (docs/leadthrough.md).

Stepped each tick like :class:`~sixplus3.interaction.contact.guard.ContactGuard`:
``step(theta, tau) -> DriveCommand``, what the drive applies as
tau_ff + Kp (theta_ref - theta) + Kd (theta_dot_ref - theta_dot).

Each tick:

1. **The wrench** a person applies, from the drives alone: the momentum observer of
   :class:`~sixplus3.interaction.observer.stream.WrenchStream` (its standard deviation ``std``
   and, for joints slower than ``V_BAND``, the dry friction ``band``), moved to the tool
   centre point (the point a person holds).
2. **A deadband with hysteresis.** At rest (mode ``hold``) a component counts only
   beyond ``n_sigma std + band`` (at rest every joint's friction is a band: 1.2-1.6 N at
   the platform on the prototype), and only once it stays there ``start_time``: noise
   and friction never start a motion, so nothing creeps.  Once moving (mode ``lead``)
   the band is only that of the joints still slow: the platform answers a fraction of a
   newton.  The input is the wrench beyond the threshold (a soft deadband: no jump).
   With no input and the platform all but still for ``rest_time``, back to ``hold``.
3. **Admittance** per axis of the tool point: M_v dv/dt + D_v v = w_in (``mass``,
   ``damping``: translation and rotation, or six values), integrated semi-implicitly,
   its acceleration and speed capped (``acceleration``, ``speed``).
4. **Passivity**: an energy tank (Ferraguti et al. 2015; Hannaford and Ryu 2002's
   passivity observer): T = ``energy`` + the energy the person put into the robot
   (the estimated wrench times the measured twist) - the virtual mass's kinetic energy,
   capped at 4 ``energy``.  At T <= 0 the admittance takes only the input that slows it
   down: the robot never gives the person more energy than it received.
5. **Walls and cranks** (every ``slow_every`` ticks, in two halves on consecutive
   ticks: :mod:`sixplus3.interaction.lead.wall_update`; :mod:`sixplus3.interaction.lead.walls`):
   the reference pose's slacks against the walls of singularity, spherical cones,
   actuated range and clearance.  A wall is near when its slack is inside the band or
   would be within HORIZON at the rate it fell; its gradient in the twist and the crank
   rates (finite differences) gives a barrier g . (v, psi_dot) >= -WALL_RATE max(s, 0),
   applied by the least change each tick after the caps, to the admittance's state too
   (the platform slides along the wall; beyond it, no deeper, no push back).  Probes
   5, 10 and 20 mm ahead along the current direction must have an assembly and be inside
   every wall (a leg's reach, a clearance's closest pair changing: walls no gradient
   announces); the motion approaches the farthest one that is.  The crank rates climb
   the crank score's gradient (``crank_gain`` [rad/s per unit gradient], 0: cranks
   locked), within ``crank_rate``, while the platform is guided.
6. **The reference**: theta_dot_ref = J (v_centre, omega, psi_dot), scaled within half
   the joint rate limit; theta_ref integrated and re-anchored on the closed-form inverse
   kinematics of the reference pose at each slow update; tau_ff the model's torque at the
   reference's acceleration (friction at the reference rate, so the encoder's noise does
   not chatter the feed-forward), and with ``drive_gains`` the whole command within 97 %
   of the envelope (:func:`~sixplus3.interaction.envelope.within_envelope`).
"""

from __future__ import annotations

import math

import numpy as np

from sixplus3.control.drive.command import DriveCommand, Mode
from sixplus3.errors import InputError, check_number
from sixplus3.interaction.envelope import (
    COMMAND_SHARE,
    DEFAULT_RATE,
    DriveRate,
    jump_bound,
    parse_drive,
    reading,
    within_envelope,
)
from sixplus3.interaction.lead import _lead_kernel as kern
from sixplus3.interaction.lead import walls
from sixplus3.interaction.lead.settings import LeadSettings, LeadState, LeadTables
from sixplus3.interaction.lead.wall_update import Found, WallUpdate
from sixplus3.interaction.observer.stream import WrenchStream
from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.hardware import Hardware, effective_limits
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot, require_robot

#: Platform speeds below which the guided platform is at rest [m/s], [rad/s].
REST_SPEED = (0.002, 0.02)
#: The cranks' acceleration cap [rad/s^2].
CRANK_ACCELERATION = 5.0
#: The guided joint rates stay within this share of the rate limit.
RATE_SHARE = 0.5
#: Good readings in a row that agree with each other before a reference starts there
#: (at the first readings, and after a jump).
CONFIRM = 3


def _norm(a: np.ndarray) -> float:
    return math.sqrt(float(a @ a))


class LeadThrough:
    """The platform follows a person's hand (module doc): its ``settings``
    (:class:`~sixplus3.interaction.lead.settings.LeadSettings`: the defaults, changed
    by name as keyword arguments, e.g. ``crank_gain=0``), its frozen ``tables``
    (:class:`~sixplus3.interaction.lead.settings.LeadTables`) and its state ``st``
    (:class:`~sixplus3.interaction.lead.settings.LeadState`, made anew by
    :meth:`reset`).  ``drive_gains``: the drive's (Kp, Kd[, rate feedback[, tau]])
    (None: the feed-forward alone is kept within the envelope); ``hardware``: the site
    whose limits tighten the robot's (default ``$SIXPLUS3_HARDWARE`` or the
    catalogue's)."""

    def __init__(self, robot: Robot, rate_hz: float = 1000.0,
                 settings: LeadSettings | None = None,
                 drive_gains: tuple[object, ...] | None = None,
                 hardware: Hardware | None = None, **named: object) -> None:
        self.robot = require_robot(robot)
        rate = check_number("rate_hz", rate_hz, 200.0, 20000.0)
        if settings is not None and not isinstance(settings, LeadSettings):
            raise InputError("settings must be a LeadSettings", value=type(settings).__name__,
                             valid="interaction.lead.settings.LeadSettings")
        self.settings = se = LeadSettings.named(settings, named)
        drive = None if drive_gains is None else parse_drive(drive_gains)
        self.stream = WrenchStream(self.robot, rate, gain=se.gain,
                                   monitor_noise=se.monitor_noise,
                                   model_sigma=se.model_sigma, n_sigma=se.n_sigma,
                                   compiled=se.compiled)
        # the envelope every command stays within: the robot's limits tightened by the
        # site's (the gate's one authority, robot_description/hardware.py)
        lim = effective_limits(self.robot, hardware)
        mot = self.robot.motors
        home = robot_ik(np.asarray(self.robot.home_position), np.eye(3),
                        np.asarray(self.robot.home_psi), self.robot,
                        platform_margins=False).theta
        self.tables = LeadTables(
            rate=rate, dt=1.0 / rate,
            start_ticks=max(1, round(se.start_time * rate)),
            rest_ticks=max(1, round(se.rest_time * rate)),
            lim=lim, cap=lim.torque, rate_cap=RATE_SHARE * lim.velocity,
            tool=np.asarray(self.robot.tool.xyz, dtype=float),
            viscous=np.asarray(mot.viscous_per_joint, dtype=float),
            coulomb=np.asarray(mot.coulomb_per_joint, dtype=float),
            cspeed=float(mot.coulomb_velocity),
            accel_cap=np.array(se.acceleration, dtype=float),
            speed_cap=np.array(se.speed, dtype=float),
            gains=None if drive is None else (drive[0], drive[1]),
            home=np.asarray(home, dtype=float).reshape(-1)[:9])
        # the walls near and the cranks' climb, every slow_every ticks (wall_update.py)
        self._wu = WallUpdate(self.robot, self.tables.tool, se.crank_gain, se.crank_rate)
        #: the drive's rate as modelled, and how far the drive's may be from it
        self._rates = DriveRate(rate, self.robot, *(DEFAULT_RATE if drive is None
                                                    else (drive[2], drive[3])))
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the reference and the observer's past: the next tick starts a hold
        where the robot is."""
        self.stream.reset()
        e0 = self.settings.energy
        # [J] the tank's initial energy, what the person put into the robot (estimated),
        # the tank, its least value (interaction/lead/_lead_kernel.py: E0, PORT, TANK, MIN_TANK)
        self.st = LeadState(sc=np.array([e0, 0.0, e0, e0]))
        self._wu.reset()
        self._rates.reset()

    # the settings and tables a caller reads
    @property
    def rate(self) -> float:
        """[Hz]"""
        return self.tables.rate

    @property
    def lim(self) -> Limits:
        """The envelope (the robot's limits tightened by the site's)."""
        return self.tables.lim

    @property
    def cap(self) -> float:
        """[N m] the envelope's torque."""
        return self.tables.cap

    @property
    def mode(self) -> Mode:
        return self.st.mode

    @property
    def events(self) -> list[str]:
        """What lead-through did and why, one line each (since the last reset)."""
        return self.st.events

    def _start(self, theta: np.ndarray) -> None:
        model = self.stream.model
        self.st.p_ref = np.array(model.position, dtype=float)
        self.st.R_ref = np.array(model.rotation, dtype=float)
        self.st.psi_ref = np.array(model.psi, dtype=float)
        self.st.theta_ref = theta.copy()
        self.st.started = True

    # ------------------------------------------------------------------ the tick
    def step(self, theta: object, tau: object) -> DriveCommand:
        """One tick (module doc); never raises, for any Python object as ``theta`` or
        ``tau`` (docs/leadthrough.md, "What it guarantees"):

        - a reading that is not one (envelope.reading: not 9 finite numbers, an angle
          far outside the range, a torque no drive applies) never reaches the observer:
          the guided motion stops, the reference holds (mode ``hold``), and the observer
          starts afresh at the next good reading;
        - a reading that jumped further than the joints can move since the last good one
          (envelope.jump_bound) is refused the same way; only CONFIRM readings in a
          row that agree with each other re-anchor the controller there (a hold where
          the robot reads itself to be: no motion);
        - before CONFIRM good readings in a row there is no reference: mode ``fault``,
          zero feed-forward and rates, and the drive must hold its own position (its
          ``theta_ref`` is the robot's home pose, a placeholder, not a target);
        - every command is finite, its feed-forward within the envelope, and with the
          drive's gains its whole PD within it too, for every rate the drive may use
          (envelope.DriveRate)."""
        try:
            self.st.since_good += 1 if self.st.last_good is not None else 0
            got = reading(theta, tau, self.tables.lim)
            if isinstance(got, str):
                self.st.cand = None
                self.st.have_prev = False  # no rate from the encoder's difference next tick
                return self._fault(got)
            th, tq = got
            self.st.reading = th
            if self.st.last_good is None or (float(np.abs(th - self.st.last_good).max())
                                           > jump_bound(self.tables.lim, self.tables.dt,
                                                        self.st.since_good)):
                why = self._candidate(th)
                if why is not None:
                    return self._fault(why)
            if self.st.resync:  # the observer's past is void: start it at this reading
                self.stream.reset()
                self.st.resync = False
            self.st.last_good, self.st.since_good = th, 0
            cmd = self._step(th, tq)
            if not (np.all(np.isfinite(cmd.theta_ref)) and np.all(np.isfinite(cmd.tau_ff))
                    and np.all(np.isfinite(cmd.theta_dot_ref))):
                return self._fault("the command was not finite")
            return cmd
        except Exception as exc:  # noqa: BLE001 - a per-tick loop must answer
            return self._fault(f"{type(exc).__name__}: {str(exc)[:120]}")

    def _candidate(self, th: np.ndarray) -> str | None:
        """A reading that does not follow from the last good one (or the first ones):
        None once CONFIRM of them in a row agree (the controller re-anchored there: a new
        start where the robot reads itself to be), else why it is refused ('' for the
        first readings: no event)."""
        if self.st.cand is not None and (float(np.abs(th - self.st.cand).max())
                                       <= jump_bound(self.tables.lim, self.tables.dt, 1)):
            self.st.cand_n += 1
        else:
            self.st.cand_n = 1
            self.st.reading, self.st.have_prev = None, False  # no rate across a jump
        self.st.cand = th
        if self.st.cand_n < CONFIRM:
            if self.st.last_good is None:
                return ""  # the first readings: a fault command, not an event
            return (f"the measured angles jumped by "
                    f"{float(np.abs(th - self.st.last_good).max()):.3f} rad in "
                    f"{self.st.since_good} tick(s)")
        if self.st.last_good is not None and len(self.st.events) < 100:
            self.st.events.append(f"tick {self.st.tick}: {CONFIRM} readings agree after a jump: "
                               "holding where the robot reads itself to be")
        self.st.cand, self.st.started, self.st.resync = None, False, True
        return None

    def _fault(self, why: str) -> DriveCommand:
        """Hold the reference (or, before any good reading, ask the drive to hold its own
        position), stop the guided motion, and restart the observer at the next good
        reading; said in :attr:`events`."""
        if why and len(self.st.events) < 100 and (not self.st.events
                                               or why not in self.st.events[-1]):
            self.st.events.append(f"tick {self.st.tick}: holding: {why}")
        self.st.mode, self.st.above, self.st.still = Mode.HOLD, 0, 0
        self.st.v[:] = 0.0
        self.st.psi_dot[:] = 0.0
        self.st.psi_dot_target[:] = 0.0
        self._wu.staged = self._wu.pending = None
        self.st.walls = []
        self.st.theta_dot_ref = np.zeros(9)
        self.st.resync = True
        self.st.tick += 1
        if self.st.reading is not None:  # a plausible reading refused: the rate from it
            self._rate_from(self.st.reading)
            self.st.reading = None
        if not self.st.started or self.st.last_good is None:
            return DriveCommand(self.tables.home.copy(), np.zeros(9), np.zeros(9), Mode.FAULT,
                                False, np.zeros(6))
        if not np.all(np.isfinite(self.st.last_ff)):
            self.st.last_ff = np.zeros(9)
        top = COMMAND_SHARE * self.tables.cap
        ff = np.clip(self.st.last_ff, -top, top)
        cmd = DriveCommand(self.st.theta_ref.copy(), np.zeros(9), ff, Mode.HOLD, False, np.zeros(6))
        return self._bounded(cmd, self.st.last_good, fresh=False)

    def _rate_from(self, theta: np.ndarray) -> None:
        """The encoder's difference (the drive's rate feedback) at this reading."""
        # within what a joint can do (twice the rate limit): the envelope's move of the
        # reference never answers a rate that is not one
        vmax = 2.0 * self.tables.lim.velocity
        self.st.vel = (np.clip((theta - self.st.prev_theta) * self.tables.rate, -vmax, vmax)
                     if self.st.have_prev else np.zeros(9))
        if self.st.have_prev:
            self._rates.update(self.st.vel)
        self.st.prev_theta[:] = theta
        self.st.have_prev = True

    # the tank's scalars (kept in the kernels' array)
    @property
    def port_energy(self) -> float:
        """[J] the energy the person put into the robot (estimated)."""
        return float(self.st.sc[kern.PORT])

    @port_energy.setter
    def port_energy(self, value: float) -> None:
        self.st.sc[kern.PORT] = value

    @property
    def tank(self) -> float:
        """[J] the energy tank (module doc, 4)."""
        return float(self.st.sc[kern.TANK])

    @property
    def min_tank(self) -> float:
        """[J] the tank's least value so far."""
        return float(self.st.sc[kern.MIN_TANK])

    def _step(self, theta: np.ndarray, tau: np.ndarray) -> DriveCommand:
        s = self.stream
        w, std, band, _ = s.update(theta, tau)
        J, M, h, thd = s.sample
        if not self.st.started:
            self._start(theta)
        off = self.st.R_ref @ self.tables.tool
        # the wrench at the tool point, the input beyond the deadband, and the energy
        # the person put in (the measured twist of the tool point)
        w_t, w_in = np.empty(6), np.empty(6)
        beyond, power, info = kern.lead_input(w, std, band, J, thd, off, self.settings.n_sigma, w_t,
                                              w_in, self.st.lu, self.st.piv)
        if info != 0:
            raise InputError("the Jacobian is singular here", value=info,
                             valid="a pose off the singularities")
        self.st.sc[kern.PORT] += power * self.tables.dt
        if self.st.mode == Mode.HOLD:
            self.st.above = self.st.above + 1 if beyond else 0
            if self.st.above >= self.tables.start_ticks:
                self.st.mode = Mode.LEAD
                self.st.still = 0
                self._slow_update(at_once=True)
            else:
                w_in[:] = 0.0
        elif self.st.mode == Mode.LEAD and self._wu.staged is not None:
            self._found(self._wu.middle())  # the slow update's middle stage
        elif self.st.mode == Mode.LEAD and self._wu.pending is not None:
            self.st.walls = self._wu.second()  # and its last
        elif self.st.mode == Mode.LEAD and self.st.tick % self.settings.slow_every == 0:
            self._slow_update()
        self._admittance(w_in)
        if self.st.mode == Mode.LEAD:
            self._tick_lead(w_in)
        self.st.tick += 1
        return self._command(J, M, h, thd, theta, w)

    def _admittance(self, w_in: np.ndarray) -> None:
        """The admittance's step (the tank first) and the cranks' wish within their caps,
        then the walls (the least change that keeps out of them) last: a wall that
        appears suddenly (the clearance's closest pair changing) is met at once, not
        braked into; one approached smoothly is met early (wall_update.HORIZON), gently
        (wall_update.WALL_RATE)."""
        wish = self.st.psi_dot_target if self.st.mode == Mode.LEAD else np.zeros(3)
        tb, se = self.tables, self.settings
        kern.admittance(w_in, self.st.v, self.st.psi_dot, wish, se.mass, se.damping, tb.dt,
                        tb.accel_cap, tb.speed_cap, CRANK_ACCELERATION * tb.dt, self.st.sc)
        self._keep_out()

    def _keep_out(self) -> None:
        """The twist and the crank rates (metric: rotations and cranks weighed by
        ``walls.ANGLE_SCALE``) kept out of the walls near: each wall's slack s may fall
        at most wall_update.WALL_RATE s per second (a barrier: g . (v, psi_dot) >= -WALL_RATE max(s,
        0): beyond a wall it may not fall, and the platform is not pushed back against
        the person), by the least change (cyclic projections)."""
        kern.keep_out(self.st.v, self.st.psi_dot, self.st.G, self.st.b, self.st.n_walls,
                      self.settings.crank_gain > 0, walls.ANGLE_SCALE)

    def _tick_lead(self, w_in: np.ndarray) -> None:
        still = (_norm(self.st.v[:3]) < REST_SPEED[0]
                 and _norm(self.st.v[3:]) < REST_SPEED[1])
        self.st.still = self.st.still + 1 if (still and not w_in.any()) else 0
        if self.st.still >= self.tables.rest_ticks and not self.st.psi_dot.any():
            self.st.mode, self.st.above = Mode.HOLD, 0
            self.st.v[:] = 0.0
            self.st.psi_dot_target[:] = 0.0
            self.st.walls = []
            self._wu.staged = self._wu.pending = None

    def _slow_update(self, at_once: bool = False) -> None:
        """The walls near and the cranks' climb (module doc, 5; wall_update.py): its first
        stage (the reference re-anchored on the inverse kinematics of its pose), or
        every stage ``at_once`` (the guided motion's first tick; an update every tick
        or two)."""
        args = (self.st.p_ref, self.st.R_ref, self.st.psi_ref, self.st.v, self.st.psi_dot,
                self.st.tick * self.tables.dt, self.st.mode == Mode.LEAD)
        if at_once or self.settings.slow_every < 3:
            self.st.anchor_theta, found = self._wu.update(*args)
            self._found(found)
        else:
            self.st.anchor_theta = self._wu.first(*args)

    def _found(self, f: Found) -> None:
        """The middle stage's decisions applied (wall_update.py)."""
        self.st.psi_dot_target = f.target
        if f.stand_still:  # the reference itself unsolvable: stand still
            self.st.v[:] = 0.0
            self.st.psi_dot[:] = 0.0
            self.st.walls = []
        elif f.walls is not None:
            self.st.walls = f.walls

    # the slow update's record (wall_update.WallUpdate)
    @property
    def min_margin(self) -> float:
        """The reference's smallest singularity margin at the slow updates."""
        return self._wu.min_margin

    @min_margin.setter
    def min_margin(self, value: float) -> None:
        self._wu.min_margin = value

    @property
    def min_slack(self) -> float:
        """The reference's smallest slack (walls.py) at the slow updates."""
        return self._wu.min_slack

    @property
    def walls_met(self) -> int:
        """Slow updates that found a wall near or ahead."""
        return self._wu.walls_met

    # ------------------------------------------------------------------ command
    def _command(self, J: np.ndarray, M: np.ndarray, h: np.ndarray, thd: np.ndarray,
                 theta: np.ndarray, w: np.ndarray) -> DriveCommand:
        has_anchor = self.st.anchor_theta is not None  # this tick's slow update solved it
        anchor = self.st.anchor_theta if self.st.anchor_theta is not None else self.st.no_anchor
        tb = self.tables
        ff = np.empty(9)
        kern.command((J, M, h, thd), (self.st.v, self.st.psi_dot, self.st.mode == Mode.LEAD),
                     (self.st.theta_dot_ref, self.st.p_ref, self.st.R_ref, self.st.psi_ref,
                      self.st.theta_ref), anchor, has_anchor,
                     (tb.tool, tb.rate_cap, tb.dt, tb.viscous, tb.coulomb, tb.cspeed,
                      COMMAND_SHARE * tb.cap), ff)
        self.st.anchor_theta = None
        self.st.last_ff = ff
        contact = bool(self.st.mode == Mode.LEAD or self.st.above > 0)
        return self._bounded(DriveCommand(self.st.theta_ref.copy(), self.st.theta_dot_ref.copy(),
                                          ff, self.st.mode, contact, w), theta)

    def _bounded(self, cmd: DriveCommand, theta: np.ndarray, fresh: bool = True
                 ) -> DriveCommand:
        """``cmd`` with the drive's whole command (tau_ff + PD) within the envelope, given
        its gains (the drive's rate feedback: the encoder's difference; ``fresh``: this
        tick's reading, else the last good one and its rate)."""
        if fresh:
            self._rate_from(theta)
            self.st.reading = None
        if self.tables.gains is None:
            return cmd
        kp, kd = self.tables.gains
        return within_envelope(cmd, kp, kd, theta, self._rates.rate,
                               COMMAND_SHARE * self.tables.cap, self._rates.spread)[0]

__all__ = ["CONFIRM", "LeadThrough", "RATE_SHARE", "REST_SPEED"]
