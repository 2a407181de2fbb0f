"""Lead-through: a person guides the platform by hand, sensorlessly (docs/leadthrough.md).

Stepped each tick like :class:`~sixplus3.interaction.guard.ContactGuard`:
``step(theta, tau) -> DriveCommand``, what the drive applies as
tau_ff + Kp (theta_ref - theta) + Kd (theta_dot_ref - theta_dot).

Each tick:

1. **The wrench** a person applies, from the drives alone: the momentum observer of
   :class:`~sixplus3.interaction.stream.WrenchStream` (its standard deviation ``std``
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
   ticks: :mod:`sixplus3.interaction.lead_walls`; :mod:`sixplus3.interaction.walls`):
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
   of the envelope (:func:`~sixplus3.interaction.guard_parts.within_envelope`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from sixplus3.control.drive.command import DriveCommand, Mode
from sixplus3.errors import InputError, check_number
from sixplus3.interaction import _lead_kernel as kern
from sixplus3.interaction import walls
from sixplus3.interaction.guard_parts import (
    COMMAND_SHARE,
    DEFAULT_RATE,
    DriveRate,
    jump_bound,
    parse_drive,
    reading,
    within_envelope,
)
from sixplus3.interaction.lead_settings import pair, six
from sixplus3.interaction.lead_walls import Found, WallUpdate
from sixplus3.interaction.stream import WrenchStream
from sixplus3.interaction.wrench import GAIN, MODEL_SIGMA, N_SIGMA
from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.hardware import Hardware, effective_limits
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
#: The walls near at once, at most (the four slacks' and a cliff ahead).
MAX_WALLS = 8


def _norm(a: np.ndarray) -> float:
    return math.sqrt(float(a @ a))


class LeadThrough:
    """The platform follows a person's hand (module doc).  ``mass`` [kg, kg m^2] and
    ``damping`` [N s/m, N m s/rad]: per axis of the tool point, (translation, rotation)
    or six; ``speed`` [m/s, rad/s] and ``acceleration`` [m/s^2, rad/s^2]: caps of the
    tool point's twist; ``drive_gains``: the drive's (Kp, Kd) (None: the feed-forward
    alone is kept within the envelope); ``compiled``: the observer's state from the
    compiled CasADi model (interaction/compiled_state.py) rather than Pinocchio."""

    def __init__(self, robot: Robot, rate_hz: float = 1000.0,
                 mass: Sequence[float] = (4.0, 0.08),
                 damping: Sequence[float] = (20.0, 0.4),
                 speed: Sequence[float] = (0.25, 1.0),
                 acceleration: Sequence[float] = (2.0, 10.0),
                 crank_gain: float = 2.0, crank_rate: float = 0.5,
                 drive_gains: tuple[object, ...] | None = None,
                 n_sigma: float = N_SIGMA, start_time: float = 0.005,
                 rest_time: float = 0.1, slow_every: int = 10, energy: float = 0.5,
                 gain: float = GAIN, model_sigma: float = MODEL_SIGMA,
                 monitor_noise: float = 0.005, compiled: bool = True,
                 hardware: Hardware | None = None) -> None:
        self.robot = require_robot(robot)
        self.rate = check_number("rate_hz", rate_hz, 200.0, 20000.0)
        self.dt = 1.0 / self.rate
        self.mass = six("mass", mass, 1e-3, 1e3)
        self.damping = six("damping", damping, 0.0, 1e4)
        self.speed = pair("speed [m/s, rad/s]", speed, 1e-3, 10.0)
        self.accel = pair("acceleration [m/s^2, rad/s^2]", acceleration, 1e-2, 1e3)
        self.crank_gain = check_number("crank_gain", crank_gain, 0.0, 100.0)
        self.crank_rate = check_number("crank_rate", crank_rate, 0.0, 10.0)
        self.n_sigma = check_number("n_sigma", n_sigma, 0.0, 100.0)
        self.start_ticks = max(1, round(check_number("start_time", start_time, 0.0, 1.0)
                                        * self.rate))
        self.rest_ticks = max(1, round(check_number("rest_time", rest_time, 0.0, 10.0)
                                       * self.rate))
        self.slow_every = int(check_number("slow_every", slow_every, 1, 1000, integer=True))
        self.energy0 = check_number("energy", energy, 0.0, 100.0)
        drive = None if drive_gains is None else parse_drive(drive_gains)
        self.gains = None if drive is None else (drive[0], drive[1])
        self.stream = WrenchStream(self.robot, self.rate, gain=gain,
                                   monitor_noise=monitor_noise, model_sigma=model_sigma,
                                   n_sigma=n_sigma, compiled=compiled)
        #: the envelope every command stays within: the robot's limits tightened by the
        #: site's (``hardware``, else ``$SIXPLUS3_HARDWARE`` or the catalogue's: the
        #: gate's one authority, robot_description/hardware.py)
        self.lim = effective_limits(self.robot, hardware)
        self.cap = self.lim.torque
        self.rate_cap = RATE_SHARE * self.lim.velocity
        self.tool = np.asarray(self.robot.tool.xyz, dtype=float)
        mot = self.robot.motors
        self._viscous = np.asarray(mot.viscous_per_joint, dtype=float)
        self._coulomb = np.asarray(mot.coulomb_per_joint, dtype=float)
        self._cspeed = float(mot.coulomb_velocity)
        self._accel_cap = np.array(self.accel, dtype=float)
        self._speed_cap = np.array(self.speed, dtype=float)
        # the per-tick kernels' work arrays (interaction/_lead_kernel.py)
        self._lu = np.zeros((9, 9))
        self._piv = np.zeros(9, dtype=np.int64)
        self._G = np.zeros((MAX_WALLS, 9))
        self._b = np.zeros(MAX_WALLS)
        self._no_anchor = np.zeros(9)
        # a fault's placeholder reference before any good reading (step's doc): the
        # home pose's angles, never a target
        self._home = np.asarray(robot_ik(np.asarray(self.robot.home_position),
                                         np.eye(3), np.asarray(self.robot.home_psi),
                                         self.robot, platform_margins=False).theta,
                                dtype=float).reshape(-1)[:9]
        # the walls near and the cranks' climb, every slow_every ticks (lead_walls.py)
        self._wu = WallUpdate(self.robot, self.tool, self.crank_gain, self.crank_rate)
        #: the drive's rate as modelled, and how far the drive's may be from it
        self._rates = DriveRate(self.rate, self.robot, *(DEFAULT_RATE if drive is None
                                                         else (drive[2], drive[3])))
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the reference and the observer's past: the next tick starts a hold
        where the robot is."""
        if hasattr(self, "stream"):
            self.stream.reset()
        self.mode = Mode.HOLD
        self.events: list[str] = []
        self._started = False
        self._tick = 0
        self._above = 0  # ticks the input has stayed beyond the rest threshold
        self._still = 0  # ticks with no input and the platform still
        self.v = np.zeros(6)  # the tool point's twist (v, omega) [m/s, rad/s]
        self.psi_dot = np.zeros(3)
        self._psi_dot_target = np.zeros(3)
        self._walls = []
        self._theta_dot_ref = np.zeros(9)
        # [J] the tank's initial energy, what the person put into the robot (estimated),
        # the tank, its least value (interaction/_lead_kernel.py: E0, PORT, TANK, MIN_TANK)
        self._sc = np.array([self.energy0, 0.0, self.energy0, self.energy0])
        if hasattr(self, "_wu"):
            self._wu.reset()
        if hasattr(self, "_rates"):
            self._rates.reset()
        self._last_ff = np.zeros(9)
        self._prev_theta = np.zeros(9)
        self._vel = np.zeros(9)
        self._have_prev = False
        self._anchor_theta: np.ndarray | None = None
        self._last_good: np.ndarray | None = None  # the last reading accepted
        self._since_good = 0  # ticks since it
        self._resync = False  # the observer restarts at the next good reading
        self._cand: np.ndarray | None = None  # readings that do not follow, agreeing ...
        self._cand_n = 0  # ... this many in a row
        self._reading: np.ndarray | None = None  # this tick's reading, until its rate is

    def _start(self, theta: np.ndarray) -> None:
        st = self.stream.model
        self.p_ref = np.array(st.position, dtype=float)
        self.R_ref = np.array(st.rotation, dtype=float)
        self.psi_ref = np.array(st.psi, dtype=float)
        self.theta_ref = theta.copy()
        self._started = True

    # ------------------------------------------------------------------ the tick
    def step(self, theta: object, tau: object) -> DriveCommand:
        """One tick (module doc); never raises, for any Python object as ``theta`` or
        ``tau`` (docs/leadthrough.md, "What it guarantees"):

        - a reading that is not one (guard_parts.reading: not 9 finite numbers, an angle
          far outside the range, a torque no drive applies) never reaches the observer:
          the guided motion stops, the reference holds (mode ``hold``), and the observer
          starts afresh at the next good reading;
        - a reading that jumped further than the joints can move since the last good one
          (guard_parts.jump_bound) is refused the same way; only CONFIRM readings in a
          row that agree with each other re-anchor the controller there (a hold where
          the robot reads itself to be: no motion);
        - before CONFIRM good readings in a row there is no reference: mode ``fault``,
          zero feed-forward and rates, and the drive must hold its own position (its
          ``theta_ref`` is the robot's home pose, a placeholder, not a target);
        - every command is finite, its feed-forward within the envelope, and with the
          drive's gains its whole PD within it too, for every rate the drive may use
          (guard_parts.DriveRate)."""
        try:
            self._since_good += 1 if self._last_good is not None else 0
            got = reading(theta, tau, self.lim)
            if isinstance(got, str):
                self._cand = None
                self._have_prev = False  # no rate from the encoder's difference next tick
                return self._fault(got)
            th, tq = got
            self._reading = th
            if self._last_good is None or (float(np.abs(th - self._last_good).max())
                                           > jump_bound(self.lim, self.dt,
                                                        self._since_good)):
                why = self._candidate(th)
                if why is not None:
                    return self._fault(why)
            if self._resync:  # the observer's past is void: start it at this reading
                self.stream.reset()
                self._resync = False
            self._last_good, self._since_good = th, 0
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
        if self._cand is not None and (float(np.abs(th - self._cand).max())
                                       <= jump_bound(self.lim, self.dt, 1)):
            self._cand_n += 1
        else:
            self._cand_n = 1
            self._reading, self._have_prev = None, False  # no rate across a jump
        self._cand = th
        if self._cand_n < CONFIRM:
            if self._last_good is None:
                return ""  # the first readings: a fault command, not an event
            return (f"the measured angles jumped by "
                    f"{float(np.abs(th - self._last_good).max()):.3f} rad in "
                    f"{self._since_good} tick(s)")
        if self._last_good is not None and len(self.events) < 100:
            self.events.append(f"tick {self._tick}: {CONFIRM} readings agree after a jump: "
                               "holding where the robot reads itself to be")
        self._cand, self._started, self._resync = None, False, True
        return None

    def _fault(self, why: str) -> DriveCommand:
        """Hold the reference (or, before any good reading, ask the drive to hold its own
        position), stop the guided motion, and restart the observer at the next good
        reading; said in :attr:`events`."""
        if why and len(self.events) < 100 and (not self.events
                                               or why not in self.events[-1]):
            self.events.append(f"tick {self._tick}: holding: {why}")
        self.mode, self._above, self._still = Mode.HOLD, 0, 0
        self.v[:] = 0.0
        self.psi_dot[:] = 0.0
        self._psi_dot_target[:] = 0.0
        self._wu.staged = self._wu.pending = None
        self._walls = []
        self._theta_dot_ref = np.zeros(9)
        self._resync = True
        self._tick += 1
        if self._reading is not None:  # a plausible reading refused: the rate from it
            self._rate_from(self._reading)
            self._reading = None
        if not self._started or self._last_good is None:
            return DriveCommand(self._home.copy(), np.zeros(9), np.zeros(9), Mode.FAULT, False,
                                np.zeros(6))
        if not np.all(np.isfinite(self._last_ff)):
            self._last_ff = np.zeros(9)
        ff = np.clip(self._last_ff, -COMMAND_SHARE * self.cap, COMMAND_SHARE * self.cap)
        cmd = DriveCommand(self.theta_ref.copy(), np.zeros(9), ff, Mode.HOLD, False, np.zeros(6))
        return self._bounded(cmd, self._last_good, fresh=False)

    def _rate_from(self, theta: np.ndarray) -> None:
        """The encoder's difference (the drive's rate feedback) at this reading."""
        # within what a joint can do (twice the rate limit): the envelope's move of the
        # reference never answers a rate that is not one
        vmax = 2.0 * self.lim.velocity
        self._vel = (np.clip((theta - self._prev_theta) * self.rate, -vmax, vmax)
                     if self._have_prev else np.zeros(9))
        if self._have_prev:
            self._rates.update(self._vel)
        self._prev_theta[:] = theta
        self._have_prev = True

    # the tank's scalars (kept in the kernels' array)
    @property
    def port_energy(self) -> float:
        """[J] the energy the person put into the robot (estimated)."""
        return float(self._sc[kern.PORT])

    @port_energy.setter
    def port_energy(self, value: float) -> None:
        self._sc[kern.PORT] = value

    @property
    def tank(self) -> float:
        """[J] the energy tank (module doc, 4)."""
        return float(self._sc[kern.TANK])

    @property
    def min_tank(self) -> float:
        """[J] the tank's least value so far."""
        return float(self._sc[kern.MIN_TANK])

    @property
    def _walls(self) -> list[tuple[np.ndarray, float]]:
        """The walls near: (gradient (9,) in the walls' metric, bound) each."""
        return list(self._wall_list)

    @_walls.setter
    def _walls(self, found: list[tuple[np.ndarray, float]]) -> None:
        self._wall_list = list(found)[:MAX_WALLS]
        for k, (g, b) in enumerate(self._wall_list):
            self._G[k] = g
            self._b[k] = b
        self._n_walls = len(self._wall_list)

    def _step(self, theta: np.ndarray, tau: np.ndarray) -> DriveCommand:
        s = self.stream
        w, std, band, _ = s.update(theta, tau)
        J, M, h, thd = s.J, s.M, s.h, s.theta_dot
        if not self._started:
            self._start(theta)
        off = self.R_ref @ self.tool
        # the wrench at the tool point, the input beyond the deadband, and the energy
        # the person put in (the measured twist of the tool point)
        w_t, w_in = np.empty(6), np.empty(6)
        beyond, power, info = kern.lead_input(w, std, band, J, thd, off, self.n_sigma, w_t,
                                              w_in, self._lu, self._piv)
        if info != 0:
            raise InputError("the Jacobian is singular here", value=info,
                             valid="a pose off the singularities")
        self._sc[kern.PORT] += power * self.dt
        if self.mode == Mode.HOLD:
            self._above = self._above + 1 if beyond else 0
            if self._above >= self.start_ticks:
                self.mode = Mode.LEAD
                self._still = 0
                self._slow_update(at_once=True)
            else:
                w_in[:] = 0.0
        elif self.mode == Mode.LEAD and self._wu.staged is not None:
            self._found(self._wu.middle())  # the slow update's middle stage
        elif self.mode == Mode.LEAD and self._wu.pending is not None:
            self._walls = self._wu.second()  # and its last
        elif self.mode == Mode.LEAD and self._tick % self.slow_every == 0:
            self._slow_update()
        self._admittance(w_in)
        if self.mode == Mode.LEAD:
            self._tick_lead(w_in)
        self._tick += 1
        return self._command(J, M, h, thd, theta, w)

    def _admittance(self, w_in: np.ndarray) -> None:
        """The admittance's step (the tank first) and the cranks' wish within their caps,
        then the walls (the least change that keeps out of them) last: a wall that
        appears suddenly (the clearance's closest pair changing) is met at once, not
        braked into; one approached smoothly is met early (lead_walls.HORIZON), gently
        (lead_walls.WALL_RATE)."""
        wish = self._psi_dot_target if self.mode == Mode.LEAD else np.zeros(3)
        kern.admittance(w_in, self.v, self.psi_dot, wish, self.mass, self.damping, self.dt,
                        self._accel_cap, self._speed_cap, CRANK_ACCELERATION * self.dt,
                        self._sc)
        self._keep_out()

    def _keep_out(self) -> None:
        """The twist and the crank rates (metric: rotations and cranks weighed by
        ``walls.ANGLE_SCALE``) kept out of the walls near: each wall's slack s may fall
        at most lead_walls.WALL_RATE s per second (a barrier: g . (v, psi_dot) >= -WALL_RATE max(s,
        0): beyond a wall it may not fall, and the platform is not pushed back against
        the person), by the least change (cyclic projections)."""
        kern.keep_out(self.v, self.psi_dot, self._G, self._b, self._n_walls,
                      self.crank_gain > 0, walls.ANGLE_SCALE)

    def _tick_lead(self, w_in: np.ndarray) -> None:
        still = (_norm(self.v[:3]) < REST_SPEED[0]
                 and _norm(self.v[3:]) < REST_SPEED[1])
        self._still = self._still + 1 if (still and not w_in.any()) else 0
        if self._still >= self.rest_ticks and not self.psi_dot.any():
            self.mode, self._above = Mode.HOLD, 0
            self.v[:] = 0.0
            self._psi_dot_target[:] = 0.0
            self._walls = []
            self._wu.staged = self._wu.pending = None

    def _slow_update(self, at_once: bool = False) -> None:
        """The walls near and the cranks' climb (module doc, 5; lead_walls.py): its first
        stage (the reference re-anchored on the inverse kinematics of its pose), or
        every stage ``at_once`` (the guided motion's first tick; an update every tick
        or two)."""
        args = (self.p_ref, self.R_ref, self.psi_ref, self.v, self.psi_dot,
                self._tick * self.dt, self.mode == Mode.LEAD)
        if at_once or self.slow_every < 3:
            self._anchor_theta, found = self._wu.update(*args)
            self._found(found)
        else:
            self._anchor_theta = self._wu.first(*args)

    def _found(self, f: Found) -> None:
        """The middle stage's decisions applied (lead_walls.py)."""
        self._psi_dot_target = f.target
        if f.stand_still:  # the reference itself unsolvable: stand still
            self.v[:] = 0.0
            self.psi_dot[:] = 0.0
            self._walls = []
        elif f.walls is not None:
            self._walls = f.walls

    # the slow update's record (lead_walls.WallUpdate)
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
        has_anchor = self._anchor_theta is not None  # this tick's slow update solved it
        anchor = self._anchor_theta if self._anchor_theta is not None else self._no_anchor
        ff = np.empty(9)
        kern.command((J, M, h, thd), (self.v, self.psi_dot, self.mode == Mode.LEAD),
                     (self._theta_dot_ref, self.p_ref, self.R_ref, self.psi_ref,
                      self.theta_ref), anchor, has_anchor,
                     (self.tool, self.rate_cap, self.dt, self._viscous, self._coulomb,
                      self._cspeed, COMMAND_SHARE * self.cap), ff)
        self._anchor_theta = None
        self._last_ff = ff
        contact = bool(self.mode == Mode.LEAD or self._above > 0)
        return self._bounded(DriveCommand(self.theta_ref.copy(), self._theta_dot_ref.copy(),
                                          ff, self.mode, contact, w), theta)

    def _bounded(self, cmd: DriveCommand, theta: np.ndarray, fresh: bool = True
                 ) -> DriveCommand:
        """``cmd`` with the drive's whole command (tau_ff + PD) within the envelope, given
        its gains (the drive's rate feedback: the encoder's difference; ``fresh``: this
        tick's reading, else the last good one and its rate)."""
        if fresh:
            self._rate_from(theta)
            self._reading = None
        if self.gains is None:
            return cmd
        return within_envelope(cmd, self.gains[0], self.gains[1], theta, self._rates.rate,
                               COMMAND_SHARE * self.cap, self._rates.spread)[0]

__all__ = ["CONFIRM", "LeadThrough", "RATE_SHARE", "REST_SPEED"]
