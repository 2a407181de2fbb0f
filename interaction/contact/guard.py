"""The contact guard: one object a controller steps each tick (docs/safety.md, "The
guard", where every rule below is stated with its measurements).  It follows a
validated trajectory file, estimates the external torque from the drives alone with a
momentum observer, and on a contact stops along the path as fast as the torque limits
allow; a clamp (the force stays after the stop) is released by retracting along the
path until the force is gone; then it holds.

Nothing is solved online.  At construction, from the gate's own reading of the file and
Pinocchio, for every sample k of the path theta(s) (interaction/contact/tables.py): the
reduced inertia M_k, gravity g_k, the time-scaling terms a_k = M_k theta'_k and
b_k = tau_k - g_k (moving along the path at path speed sd and acceleration sdd needs
a_k sdd + b_k sd^2 + g_k), the velocity torque's slope D_k in the rates, the IK
Jacobian J_k, the thresholds (from the robot's prior: identified or not) and the stop
table beta_k, always recomputed here: the header's is never used.

Each tick: the reading checked (envelope.reading, jump_bound), the observer
r = K (p - p_0 - sum (tau - h + Mdot thetadot + r) dt) with p = M_k thetadot, and a
contact when a joint's |r| stays beyond its threshold for DEBOUNCE ticks.  A drive held
at its limit for SATURATED_FOR while the robot is off its reference by more than
BLOCKED is a stop along the path, not a contact.  With the drive's gains and rate
feedback (``drive_gains``), every command's total tau_ff + PD stays within the envelope
for every rate the drive may use (envelope.DriveRate, within_envelope).

``step`` never raises: a reading that is not one, a jump, or any failure inside is a
safe stop (mode ``hold`` at the last good reference, gravity feed-forward), said in
``cmd.mode`` and kept in :attr:`ContactGuard.events`.  Every feed-forward is clipped to
the hardware envelope.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np

from sixplus3.control.drive.command import DriveCommand, Mode
from sixplus3.control.drive.feed import START_TOL
from sixplus3.control.file.trajectory_parse import parse
from sixplus3.control.file.trajectory_read import read_bytes
from sixplus3.control.gate.stop import TORQUE_SHARE
from sixplus3.control.gate.validation import validate_bytes
from sixplus3.errors import InputError, ValidationFailed, check_number
from sixplus3.interaction.contact.parts import contact_site
from sixplus3.interaction.contact.tables import (
    IDENTIFIED,
    LAG,
    UNIDENTIFIED,
    GuardState,
    ModelPrior,
    deceleration_at,
    path_tables,
    thresholds,
)
from sixplus3.interaction.envelope import (
    COMMAND_SHARE,
    DEFAULT_RATE,
    DriveRate,
    jump_bound,
    parse_drive,
    reading,
    within_envelope,
)
from sixplus3.interaction.observer.momentum import MomentumObserver
from sixplus3.robot_description.hardware import effective_limits, judged_limits
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot, require_robot

#: Observer gain [1/s] (a step reaches 95 % in 3 / K = 6 ms).
GAIN = 500.0
#: Standard deviations of the observer's noise in the threshold.
N_SIGMA = 5.0
#: Ticks a joint must stay beyond its threshold to be a contact.
DEBOUNCE = 2
#: The largest path speed a stop may take where the plan slows down faster than it.
STOP_SD_MAX = 4.0
#: For this long after a contact [s] the residual's crank torques may still place it on
#: a leg (they grow with the force), while the force is at least half its peak so far and
#: the guard is still stopping (a retract's start moves the reference at once).
SITE_WINDOW = 0.02
#: After a stop, the force that stays for this long [s] is a clamp ...
CLAMP_WAIT = 0.02
#: ... and one absent for the last GONE [s] of it is gone: a collision, the body moved
#: away (the free hand is knocked off in a few ms).
GONE = 0.01
#: [rad] the measured angles this far behind the reference, with a force on: blocked.
BLOCKED = 0.004
#: Retract speed along the path, as a share of the plan's path speed.
RETRACT_SPEED = 0.3
#: [s] the shortest time a retract comes to rest in (from RETRACT_SPEED).
SETTLE_TIME = 0.015
#: The longest retract [samples of the path]: then the guard comes to rest and holds.
RETRACT_SAMPLES = 40
#: [rad] the largest offset from the path a contact's stop rests at (per joint).
REST_OFFSET = 0.02
#: The force is gone when every joint stays within its threshold this long [s].
RELEASED = 0.03
#: A drive at this share of the torque limit is saturated ...
SATURATED_SHARE = 0.995
#: ... and one saturated this long [s] cannot follow the plan: a stop, not a contact.
SATURATED_FOR = 0.01


class ContactGuard:
    """Steps a trajectory file with contact detection and reaction (module doc).

    ``robot`` None: the robot the file was planned for (its header); a file of another
    robot than ``robot`` is refused here (the gate's check).  ``step(theta, tau)`` is
    called once per tick from the file's t = 0 with the measured actuated angles (9,
    rad) and the torque applied over the previous tick (9, N m; at the first call the
    file's first feed-forward)."""

    def __init__(self, robot: Robot | None, trajectory_file: str | Path,
                 rate_hz: float = 1000.0, gain: float = GAIN,
                 model_error: float | None = None, n_sigma: float = N_SIGMA,
                 torque_noise: float = 0.01, torque_share: float = TORQUE_SHARE,
                 reaction: str = "hold",
                 drive_gains: tuple[object, ...] | None = None,
                 parameter_cov: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        if reaction not in ("hold", "yield"):
            raise InputError(f"reaction must be hold or yield, got {reaction!r}",
                             value=reaction, valid="hold or yield")
        #: after a contact's stop (and a clamp's retract): "hold" the pose, or "yield":
        #: a compliant hold (the reference follows the measured angles, so the drive's
        #: PD only damps; gravity's feed-forward): a person can push the platform away
        self.reaction = reaction
        # the file is read once: its robot (when none is given) and the samples the gate
        # judges come from the same bytes
        raw = read_bytes(trajectory_file)
        if robot is None:
            header, _ = parse(raw, Path(trajectory_file).name)
            rec = header.get("robot")
            if not isinstance(rec, dict) or not isinstance(rec.get("parameters"), dict):
                raise InputError("the file's header names no robot: give the robot",
                                 value=None, valid="a header with robot.parameters")
            robot = Robot.from_dict(rec["parameters"])
        self.robot = require_robot(robot)
        self.rate = check_number("rate_hz", rate_hz, 100.0, 20000.0)
        self.gain = check_number("gain", gain, 10.0, 5000.0)
        #: how well the robot is known: identified (its parameters' covariance given:
        #: ``parameter_cov``) or the stated prior of a build's spread (tables:
        #: IDENTIFIED, UNIDENTIFIED); ``model_error`` given overrides the model share
        self.identified = parameter_cov is not None
        prior = IDENTIFIED if self.identified else UNIDENTIFIED
        if model_error is not None:
            prior = ModelPrior(check_number("model_error", model_error, 0.0, 1.0),
                               prior.friction)
        self.prior = prior
        self.model_error = prior.model_error
        self.n_sigma = check_number("n_sigma", n_sigma, 0.0, 100.0)
        share = check_number("torque_share", torque_share, 0.1, 1.0)
        #: the drive's (Kp [N m/rad], Kd [N m s/rad]), scalars or 9 each; given, every
        #: command's tau_ff + Kp (theta_ref - theta) + Kd (theta_dot_ref - theta_dot)
        #: stays within the envelope (:func:`envelope.within_envelope`)
        self.kp: np.ndarray | None = None
        self.kd: np.ndarray | None = None
        self._drive_rate = DEFAULT_RATE
        rep = validate_bytes(raw, self.robot, Path(trajectory_file).name)
        if not rep.ok or rep.data is None or rep.header is None:
            raise ValidationFailed("the guard runs only a valid file: "
                                   + "; ".join(rep.messages()), rep.exit_code, rep)
        #: the gate's report of the file (its samples in ``report.data``)
        self.report = rep
        file_rate = float(rep.header["rate_hz"])
        if abs(file_rate - self.rate) > 1e-6 * self.rate:
            raise InputError(f"the file is sampled at {file_rate:g} Hz, the guard ticks at "
                             f"{self.rate:g} Hz", value=self.rate, valid=f"{file_rate:g} Hz")
        self.lim = effective_limits(self.robot)
        self.dt = 1.0 / self.rate
        # the stop table is recomputed under the limits the gate judged the file by (the
        # envelope tightened by the file's own): the gate's own table, never the header's
        judged = judged_limits(self.robot, Limits(**rep.limits)) if rep.limits else self.lim
        tables = path_tables(self.robot, rep, self.rate, judged, share, self.gain,
                             self.prior, self.n_sigma, torque_noise, parameter_cov)
        #: the frozen tables of the path (tables.PathTables: the reference, the
        #: dynamics along it, the stop table, the thresholds), computed once
        self.tables = tables
        self.n = len(tables.theta)
        self.path = Path(trajectory_file)
        self.reset(drive_gains)  # the drive's gains and rate feedback (parse_drive)

    # ------------------------------------------------------------------ offline
    def _stop_from_measured(self) -> None:
        """Enter the stop from where the robot is: the path position nearest the measured
        angles, and the measured path speed (the rate projected on the path's tangent),
        never faster than the reference's.  An impact that has already slowed the
        platform is not undone by a reference that runs on ahead of it."""
        if self.st.mode == Mode.FOLLOW and self.st.prev is not None:
            self.st.s = self._nearest(self.st.s)
            k = int(round(self.st.s))
            tan = self.tables.theta_d[k]
            t2 = float(tan @ tan)
            if t2 > 1e-12:
                self.st.sd = min(self.st.sd, max(0.0, float(self.st.vel @ tan) / t2))
        self.st.mode = Mode.STOP

    def _blocked(self) -> bool:
        """The measured angles lag the reference by more than BLOCKED while the
        observer sees a force: the platform is held."""
        return (self.st.prev is not None and self.st.over > 0
                and float(np.abs(self.st.last_ref - self.st.prev).max()) > BLOCKED)

    def _nearest(self, s: float) -> float:
        """The path position, at or before ``s``, nearest to the measured angles."""
        assert self.st.prev is not None
        k = int(min(max(s, 0.0), self.n - 1.0))
        lo = max(0, k - int(self.rate * 0.2))
        d = np.abs(self.tables.theta[lo:k + 1] - self.st.prev).max(axis=1)
        return float(lo + int(np.argmin(d)))

    # ------------------------------------------------------------------ online
    def reset(self, drive_gains: tuple[object, ...] | None = None) -> None:
        """Back to the file's t = 0, with no contact and no events (the tables kept):
        the same guard runs the file again; ``drive_gains``: new (Kp, Kd), or keep."""
        if drive_gains is not None:
            self.kp, self.kd, kind, tau = parse_drive(drive_gains)
            self._drive_rate = (kind, tau)
        # the state: the drive's rate as the guard models it, and how far the drive's
        # may be from it (envelope.DriveRate: the bound on the whole command covers
        # it), the path position, the observer, the contact, the events
        self._reset()

    def _reset(self) -> None:
        self.st = GuardState(
            rates=DriveRate(self.rate, self.robot, *self._drive_rate),
            motion=deque(maxlen=max(1, round(LAG * self.rate))),
            last_ref=self.tables.theta[0].copy(),
            # the one momentum observer (momentum.py); the encoder's difference is the
            # rate half a tick ago (lag 1/2)
            observer=MomentumObserver(self.gain, lag=0.5))

    @property
    def events(self) -> list[str]:
        """What the guard did and why, one line each (since the last reset)."""
        return self.st.events

    @property
    def contact_site(self) -> str | None:
        """Where the contact was found ("the platform" or "a leg"), once there was one."""
        return self.st.contact_site

    @property
    def mode(self) -> Mode:
        return self.st.mode

    def _at(self, arr: np.ndarray) -> np.ndarray:
        k = min(max(self.st.s, 0.0), self.n - 1.0)
        i = int(k)
        j = min(i + 1, self.n - 1)
        f = k - i
        return (1.0 - f) * arr[i] + f * arr[j]

    def _command(self, sdd: float, mode: Mode, wrench: np.ndarray) -> DriveCommand:
        """The reference at the path position s with path speed sd and acceleration
        sdd (the time-scaling feed-forward, clipped to the envelope)."""
        k = min(max(self.st.s, 0.0), self.n - 1.0)
        i = int(k)
        j, f = min(i + 1, self.n - 1), k - i

        def at(arr: np.ndarray) -> np.ndarray:
            return (1.0 - f) * arr[i] + f * arr[j]

        tb = self.tables
        th = at(tb.theta) + self.st.offset
        ff = at(tb.a) * sdd + at(tb.b) * self.st.sd ** 2 + at(tb.g)
        cap = self.lim.torque
        ff = np.clip(np.nan_to_num(ff, nan=0.0), -cap, cap)
        self.st.last_ref = th
        return DriveCommand(th, at(tb.theta_d) * self.st.sd, ff, mode, self.st.contact, wrench)

    def _safe_hold(self, why: str) -> DriveCommand:
        if not self.st.events or self.st.events[-1] != why:
            self.st.events.append(f"t={self.st.t:.4f} s: {why}")
        self.st.mode, self.st.sd = Mode.HOLD, 0.0
        g = np.clip(self._at(self.tables.g), -self.lim.torque, self.lim.torque)
        return DriveCommand(self.st.last_ref.copy(), np.zeros(9), g, Mode.HOLD, self.st.contact,
                            np.zeros(6))

    def step(self, theta: object, tau: object) -> DriveCommand:
        """One tick (class doc); never raises."""
        got = reading(theta, tau, self.lim)  # never raises
        try:
            self._drive_reads(got)
            cmd = self._step(got)
        except Exception as exc:  # noqa: BLE001 - the loop must never see an exception
            cmd = self._safe_hold(f"internal failure, holding: {type(exc).__name__}: "
                                  f"{str(exc)[:120]}")
        try:
            if self.kp is None or self.kd is None or self.st.prev is None:
                return cmd  # no good reading yet: the file's start, held, unmoved
            # at the angles the drive's PD acts on this tick (its encoder's: this
            # reading, a refused jump too; the last good one when this is not a
            # reading), with the drive's rate the encoder's difference of its last two
            # readings, and how far the drive's own rate may be from it
            # (envelope.DriveRate).  This tick's command only: the guard's state is not
            # moved by a reading it refused
            at = self.st.prev if isinstance(got, str) else got[0]
            out, wanted = within_envelope(cmd, self.kp, self.kd, at, self.st.rates.rate,
                                          COMMAND_SHARE * self.lim.torque,
                                          self.st.rates.spread)
            # the drive would have been at its limit without the move: saturated
            self.st.clipped = wanted >= self.lim.torque
            return out
        except Exception:  # noqa: BLE001
            return cmd

    def _drive_reads(self, got: tuple[np.ndarray, np.ndarray] | str) -> None:
        """The drive's rate feedback this tick, as this guard models it.  The drive
        differences every reading its encoder gives, the ones this guard refuses as a
        jump too: the rate model follows each plausible reading (within twice the rate
        limit: the envelope's move of the reference never answers a rate no joint has)
        and starts again after one that is not a reading (found by hypothesis: a jump
        accepted over two ticks, a refused one back, then two good readings: the drive's
        difference of the last two was not modelled, and the whole command reached
        9.77 N m against 9.7)."""
        if isinstance(got, str):
            self.st.read = None
            return
        th = got[0]
        if self.st.read is not None:
            vmax = 2.0 * self.lim.velocity
            self.st.rates.update(np.clip((th - self.st.read) / self.dt, -vmax, vmax))
        self.st.read = th

    def _step(self, got: tuple[np.ndarray, np.ndarray] | str) -> DriveCommand:
        self.st.since_good += 1
        if isinstance(got, str):
            return self._safe_hold(got)
        th, tq = got
        dt = self.dt
        if (self.st.prev is not None and np.abs(th - self.st.prev).max()
                > jump_bound(self.lim, dt, self.st.since_good)):
            return self._safe_hold(f"the measured angles jumped by "
                                   f"{np.abs(th - self.st.prev).max():.3f} rad in "
                                   f"{self.st.since_good} tick(s)")
        span, self.st.since_good = max(1, self.st.since_good), 0
        if self.st.prev is None:  # the first tick: no torque has acted yet
            gap = float(np.abs(th - self.tables.theta[0]).max())
            if gap > START_TOL:  # the file runs only from its start (the feed's check)
                return self._safe_hold(f"the first reading is {gap:.4f} rad from the "
                                       f"file's start (tolerance {START_TOL:g} rad): not "
                                       "starting")
            self.st.prev = th.copy()
            # at rest (the file's start): the first momentum, nothing integrated yet
            self.st.observer.step(tq, self.st.vel, self.tables.M[0], self.tables.g[0], dt)
            self.st.t += dt
            return self._advance(False, np.zeros(6))
        # the encoder's difference: the rate at t - dt/2 (over the ticks since the last
        # good reading, when readings were lost between)
        self.st.vel = (th - self.st.prev) / (dt * span)
        self.st.prev = th.copy()
        k = int(round(min(max(self.st.s, 0.0), self.n - 1.0)))
        M = self.tables.M[k]
        # the velocity torque at the measured rates: along the path at the measured path
        # speed sm (c_k sm^2), and its slope times the rest of the measured rate (a drive
        # that lags, saturates or is pushed; not the reference's speed, which a stop or a
        # retract changes at once)
        tan = self.tables.theta_d[k]
        t2 = float(tan @ tan)
        sm = float(self.st.vel @ tan) / t2 if t2 > 1e-12 else 0.0
        self.st.sm = sm
        tb = self.tables
        h = (tb.c[k] * sm ** 2 + sm * (tb.D[k] @ (self.st.vel - sm * tan)) + tb.g[k]
             + self.robot.motors.friction(self.st.vel))
        r = self.st.observer.step(tq, self.st.vel, M, h, dt)
        thr_site, thr = thresholds(self, k, self.st.motion)
        over = bool(np.any(np.abs(r) > thr))
        self.st.over = self.st.over + 1 if over else 0
        full = self.tables.J[k].T @ r  # (wrench at the platform centre, crank torques)
        wrench = full[:6]
        if (self.st.over >= DEBOUNCE and not self.st.contact
                and self.st.mode in (Mode.FOLLOW, Mode.STOP)):
            self.st.contact = True
            self.st.contact_t = self.st.t
            self.st.contact_site = contact_site(full, np.abs(self.tables.J[k]).T @ thr_site)
            self._stop_from_measured()
            self.st.events.append(f"t={self.st.t:.4f} s: contact at {self.st.contact_site}, joint "
                               f"residual {np.abs(r).max():.3f} N m; stopping")
        if self.st.contact and self.st.t - self.st.contact_t <= SITE_WINDOW:
            self.st.fmax = max(self.st.fmax, float(np.linalg.norm(full[0:3])))
        if (self.st.contact and self.st.contact_site == "the platform" and self.st.mode == Mode.STOP
              and self.st.t - self.st.contact_t <= SITE_WINDOW
              and float(np.linalg.norm(full[0:3])) >= 0.5 * self.st.fmax
              and contact_site(full, np.abs(self.tables.J[k]).T @ thr_site) == "a leg"):
            # the crank torques grow with the force: a leg's shows within a few ticks
            self.st.contact_site = "a leg"
            self.st.events.append(f"t={self.st.t:.4f} s: the contact is on a leg (the residual's "
                               "crank torques)")
        # a drive held at its limit: this robot cannot follow the plan (it needs more
        # torque than the model says); the platform leaves the planned (and PFL-checked)
        # path, so stop along it
        sat = ((self.st.clipped or bool(np.any(np.abs(tq) >= SATURATED_SHARE * self.lim.torque)))
               and float(np.abs(self.st.last_ref - th).max()) > BLOCKED)
        self.st.saturated = self.st.saturated + dt if sat else 0.0
        if self.st.saturated >= SATURATED_FOR and self.st.mode == Mode.FOLLOW:
            self._stop_from_measured()
            self.st.events.append(f"t={self.st.t:.4f} s: a drive saturated for "
                               f"{1e3 * self.st.saturated:.0f} ms: this robot cannot follow "
                               "the plan; stopping")
        self.st.t += dt
        return self._advance(over, wrench)

    def _advance(self, over: bool, wrench: np.ndarray) -> DriveCommand:
        dt = self.dt
        k = int(round(min(max(self.st.s, 0.0), self.n - 1.0)))
        sdd = 0.0
        if self.st.mode == Mode.FOLLOW:
            self.st.s += self.rate * dt * self.st.sd
            if self.st.s >= self.n - 1:
                self.st.s, self.st.sd, self.st.mode = self.n - 1.0, 0.0, Mode.DONE
        elif self.st.mode == Mode.STOP and self._blocked():
            # the platform no longer follows its reference while the force is on: a
            # body is held against something (a clamp). Advancing the reference would
            # only press harder: take the reference back to where the robot is, at rest
            self.st.s = self._nearest(self.st.s)
            self.st.sd, self.st.since, self.st.quiet = 0.0, 0.0, 0.0
            self.st.retract_from = self.st.s
            self.st.mode = Mode.RETRACT
            self.st.events.append(f"t={self.st.t:.4f} s: blocked while stopping (a clamp): "
                               "retracting along the path")
        elif self.st.mode == Mode.STOP:
            # the joint speed along the path, sigma = sd |theta'(s)|, falls at the table's
            # beta (control/gate/stop.py), or faster where the torque limits allow it at
            # the stop's own path speed; sd follows from it where the path goes on
            tb = self.tables
            beta = max(float(tb.beta[k]), deceleration_at(
                tb.a[k], tb.b_cross[k], tb.g[k], tb.theta_d[k], self.st.sd, self.lim.torque,
                self.lim.acceleration))
            v0 = float(self._at(self.tables.vnorm))
            sigma = max(0.0, self.st.sd * v0 - beta * v0 * dt)
            s_new = min(self.n - 1.0, self.st.s + self.rate * dt * self.st.sd)
            self.st.s = s_new
            v1 = float(self._at(self.tables.vnorm))
            sd_new = min(sigma / v1, STOP_SD_MAX) if v1 > 1e-9 and sigma > 0 else 0.0
            # never ahead of the robot: an impact (or the person) that slowed the
            # platform below the stop's profile is not undone by a stiff drive dragging
            # it back up to the reference (the feed-forward keeps the table's rate)
            sd_new = min(sd_new, max(0.0, self.st.sm))
            sdd = max((sd_new - self.st.sd) / dt, -beta * max(v0, 1e-9) / max(v1, 1e-9))
            self.st.sd = sd_new
            if self.st.sd <= 0.0 and self.st.contact and not self.st.rested:
                # at rest after a contact: rest where the robot is. An impact pushes the
                # platform off the path; a stiff drive pulling it back onto the path
                # would move it towards the person again. The offset stays with every
                # later reference (the retract runs parallel to the path)
                self.st.rested = True
                assert self.st.prev is not None
                self.st.offset = np.clip(self.st.prev - self._at(self.tables.theta), -REST_OFFSET,
                                       REST_OFFSET)
            if self.st.sd <= 0.0:
                # at rest: the force present is the residual beyond its threshold for
                # DEBOUNCE ticks (as a contact is found; one tick over is noise)
                self.st.since += dt
                self.st.quiet = self.st.quiet + dt if self.st.over < DEBOUNCE else 0.0
                if self.st.quiet >= RELEASED or (self.st.since >= CLAMP_WAIT
                                               and self.st.quiet >= GONE):
                    self.st.mode = Mode.HOLD
                    self.st.events.append(f"t={self.st.t:.4f} s: stopped, the force is gone (a "
                                       "collision): holding")
                elif self.st.since >= CLAMP_WAIT and self.st.contact:
                    self.st.mode = Mode.RETRACT
                    self.st.retract_from = self.st.s
                    self.st.events.append(f"t={self.st.t:.4f} s: the force stays after the stop "
                                       "(a clamp, or a body still pressing): retracting "
                                       "along the path")
        elif self.st.mode == Mode.RETRACT:
            beta = float(self.tables.beta[k])
            if self.st.sd > -RETRACT_SPEED:
                sdd = -beta
                self.st.sd = max(-RETRACT_SPEED, self.st.sd - beta * dt)
            self.st.s = max(0.0, self.st.s + self.rate * dt * self.st.sd)
            self.st.quiet = self.st.quiet + dt if not over else 0.0
            self.st.since += dt
            back = self.st.retract_from - self.st.s
            if self.st.quiet >= RELEASED or self.st.s <= 0.0 or back >= RETRACT_SAMPLES:
                self.st.mode = Mode.SETTLE  # come to rest, then hold
                self.st.events.append(f"t={self.st.t:.4f} s: released: coming to rest")
        elif self.st.mode == Mode.SETTLE:
            # no harder than the table allows, and over at least SETTLE_TIME: a stiff
            # drive stopped at once from the retract's speed springs back towards the
            # person (measured: 6-8 cm/s)
            sdd = min(float(self.tables.beta[k]), RETRACT_SPEED / SETTLE_TIME)
            self.st.sd = min(0.0, self.st.sd + sdd * dt)
            self.st.s = max(0.0, self.st.s + self.rate * dt * self.st.sd)
            if self.st.sd >= 0.0:
                self.st.mode = Mode.HOLD
                self.st.events.append(f"t={self.st.t:.4f} s: at rest: holding")
        self.st.sdd = sdd
        mode_out = Mode.RETRACT if self.st.mode == Mode.SETTLE else self.st.mode
        if self.st.mode == Mode.HOLD and self.st.contact and self.reaction == "yield":
            assert self.st.prev is not None
            g = np.clip(self._at(self.tables.g), -self.lim.torque, self.lim.torque)
            self.st.last_ref = self.st.prev.copy()
            return DriveCommand(self.st.prev.copy(), np.zeros(9), g, Mode.HOLD, True, wrench)
        return self._command(sdd, mode_out, wrench)


__all__ = ["ContactGuard"]
