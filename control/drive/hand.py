"""A hand that guides the platform in the virtual prototype (docs/leadthrough.md, "The
simulated hand"), a controller in the drives' loop (lead-through:
:func:`~sixplus3.interaction.people.hand.run_lead` builds it).  A test harness beside the
plant it drives, not a part a controller uses.

The hand is a spring-damper between the tool centre point and an anchor that follows a
target path with the person's reaction delay:

    F = k (a(t) - p) + c (a'(t) - p'),  a(t) = p_0 + target(t - delay),  |F| <= max_force,

and, when it also grips the platform (``stiffness_rot`` > 0), a torsional spring-damper
toward the anchor's orientation R_a(t) = exp(rotation(t - delay)) R_0:

    T = k_r log(R_a R^T) + c_r (omega_a - omega),  |T| <= max_torque,

both applied at the tool point (MuJoCo's ``xfrc_applied``) before every sub-step.  The target
is piecewise linear in time through the path's points (offsets from the tool point's
start [m]); a hand of stiffness 0 is nobody (the drift at rest).

A hand file (YAML): ``stiffness`` [N/m], ``damping`` [N s/m], ``delay`` [s],
``max_force`` [N], optional ``stiffness_rot`` [N m/rad], ``damping_rot`` [N m s/rad],
``max_torque`` [N m], ``duration`` [s] and ``path``: a list of ``{t: s, offset: [x, y,
z]}`` (base frame, metres; times increasing from 0), each with an optional ``rotation:
[rx, ry, rz]`` (a rotation vector [rad], base frame, from the start orientation).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.drive.command import DriveCommand, TickController
from sixplus3.control.drive.loop import KD, KP, DriveSettings, Tick, run
from sixplus3.control.file.drive_log import DriveLog
from sixplus3.errors import InputError, check_number
from sixplus3.fileio import read_yaml
from sixplus3.kinematics.robot import home
from sixplus3.robot_description.robot import Robot, require_robot

#: The tool point has started moving once this far from its start [m].
MOVED = 0.0005


@dataclass(frozen=True)
class Hand:
    stiffness: float  # [N/m]
    damping: float  # [N s/m]
    delay: float  # [s]
    max_force: float  # [N]
    duration: float  # [s]
    times: tuple[float, ...]
    offsets: tuple[tuple[float, float, float], ...]
    rotations: tuple[tuple[float, float, float], ...] = ()
    stiffness_rot: float = 0.0  # [N m/rad]
    damping_rot: float = 0.0  # [N m s/rad]
    max_torque: float = 5.0  # [N m]

    def target(self, t: float) -> np.ndarray:
        """The anchor's offset from the tool point's start at time t (delayed)."""
        return self._interp(t, self.offsets)

    def turn(self, t: float) -> np.ndarray:
        """The anchor's rotation vector from the start orientation at time t."""
        return self._interp(t, self.rotations) if self.rotations else np.zeros(3)

    def _interp(self, t: float, pts: tuple[tuple[float, float, float], ...]) -> np.ndarray:
        s = t - self.delay
        ts = np.asarray(self.times)
        arr = np.asarray(pts)
        return np.array([np.interp(s, ts, arr[:, i]) for i in range(3)])


def hand_from_dict(doc: object, name: str = "hand") -> Hand:
    if not isinstance(doc, dict):
        raise InputError(f"{name} must be a mapping (stiffness, damping, delay, max_force, "
                         "duration, path)", value=type(doc).__name__, valid="a mapping")
    keys = {"stiffness", "damping", "delay", "max_force", "duration", "path",
            "stiffness_rot", "damping_rot", "max_torque"}
    extra = sorted(set(doc) - keys)
    if extra:
        raise InputError(f"{name}: unknown key {extra[0]!r}", value=extra[0],
                         valid=", ".join(sorted(keys)))
    k = check_number(f"{name}: stiffness [N/m]", doc.get("stiffness", 500.0), 0.0, 1e5)
    c = check_number(f"{name}: damping [N s/m]", doc.get("damping", 10.0), 0.0, 1e4)
    delay = check_number(f"{name}: delay [s]", doc.get("delay", 0.15), 0.0, 2.0)
    fmax = check_number(f"{name}: max_force [N]", doc.get("max_force", 60.0), 0.0, 500.0)
    kr = check_number(f"{name}: stiffness_rot [N m/rad]", doc.get("stiffness_rot", 0.0),
                      0.0, 1e4)
    cr = check_number(f"{name}: damping_rot [N m s/rad]", doc.get("damping_rot", 0.0),
                      0.0, 1e3)
    tmax = check_number(f"{name}: max_torque [N m]", doc.get("max_torque", 5.0), 0.0, 100.0)
    path = doc.get("path", [{"t": 0.0, "offset": [0.0, 0.0, 0.0]}])
    if not isinstance(path, list) or not path:
        raise InputError(f"{name}: path must be a non-empty list of {{t, offset}}",
                         value=type(path).__name__, valid="a list")
    times: list[float] = []
    offsets: list[tuple[float, float, float]] = []
    turns: list[tuple[float, float, float]] = []
    for i, p in enumerate(path):
        if not (isinstance(p, dict) and {"t", "offset"} <= set(p)
                and set(p) <= {"t", "offset", "rotation"}):
            raise InputError(f"{name}: path[{i}] must be {{t, offset[, rotation]}}",
                             value=repr(p)[:60], valid="{t: s, offset: [x, y, z]}")
        t = check_number(f"{name}: path[{i}].t [s]", p["t"], 0.0, 3600.0)
        if times and t <= times[-1]:
            raise InputError(f"{name}: path times must increase", value=t,
                             valid=f"> {times[-1]:g} s")
        o = p["offset"]
        if not (isinstance(o, list) and len(o) == 3):
            raise InputError(f"{name}: path[{i}].offset must be 3 numbers [m]", value=o,
                             valid="[x, y, z]")
        vals = [check_number(f"{name}: path[{i}].offset [m]", x, -2.0, 2.0) for x in o]
        times.append(t)
        offsets.append((vals[0], vals[1], vals[2]))
        r = p.get("rotation", [0.0, 0.0, 0.0])
        if not (isinstance(r, list) and len(r) == 3):
            raise InputError(f"{name}: path[{i}].rotation must be 3 numbers [rad]", value=r,
                             valid="[rx, ry, rz]")
        rv = [check_number(f"{name}: path[{i}].rotation [rad]", x, -math.pi, math.pi)
              for x in r]
        turns.append((rv[0], rv[1], rv[2]))
    duration = check_number(f"{name}: duration [s]",
                            doc.get("duration", times[-1] + delay + 1.0), 0.01, 600.0)
    return Hand(k, c, delay, fmax, duration, tuple(times), tuple(offsets), tuple(turns),
                kr, cr, tmax)


def read_hand(path: str | Path) -> Hand:
    return hand_from_dict(read_yaml(path, "hand file"), f"hand file {Path(path).name}")


@dataclass
class LeadRun:
    """What the guided run did (module doc): series per tick and their summary."""

    t: np.ndarray  # (n,)
    tcp: np.ndarray  # (n, 3) the tool point's true position
    anchor: np.ndarray  # (n, 3) the hand's anchor
    force: np.ndarray  # (n, 3) the hand's force on the tool point
    speed: np.ndarray  # (n,) the tool point's true speed
    torque: np.ndarray  # (n, 3) the hand's torque on the platform (a grip)
    angle: np.ndarray  # (n,) the platform's rotation from its start [rad]
    modes: np.ndarray  # (n,) str
    rate_ref: np.ndarray  # (n, 9) the commanded joint rates [rad/s]
    tau_ff: np.ndarray  # (n, 9) the commanded feed-forward [N m]
    peak_command: float  # [N m] the largest |tau_ff + PD| asked of the drives
    peak_applied: float  # [N m]
    min_margin: float  # the reference's smallest singularity margin
    min_slack: float
    walls_met: int
    port_energy_min: float  # [J] the least of the true energy the hand put in
    events: list[str] = field(default_factory=list)
    log: DriveLog | None = field(default=None, repr=False)

    def breakaway(self) -> float | None:
        """|F| [N] when the tool point first left its start by MOVED (None: never)."""
        d = np.linalg.norm(self.tcp - self.tcp[0], axis=1)
        k = np.flatnonzero(d > MOVED)
        return None if len(k) == 0 else float(np.linalg.norm(self.force[k[0]]))

    def drift(self) -> float:
        """[m] the tool point's largest distance from its start."""
        return float(np.linalg.norm(self.tcp - self.tcp[0], axis=1).max())

    def force_at_speed(self, v: float = 0.1, tol: float = 0.1) -> float | None:
        """The median |F| [N] over the ticks where the tool point moves at v (+-tol v)."""
        sel = np.abs(self.speed - v) <= tol * v
        return None if sel.sum() < 10 else float(np.median(
            np.linalg.norm(self.force[sel], axis=1)))

    def smoothness(self) -> tuple[float, float]:
        """(the largest commanded joint acceleration [rad/s^2], the largest rate of
        change of the feed-forward [N m/s]) from tick to tick."""
        rate = 1.0 / float(self.t[1] - self.t[0]) if len(self.t) > 1 else 1.0
        if len(self.t) < 2:
            return 0.0, 0.0
        return (float(np.abs(np.diff(self.rate_ref, axis=0)).max()) * rate,
                float(np.abs(np.diff(self.tau_ff, axis=0)).max()) * rate)

    def summary(self) -> dict[str, Any]:
        lag = np.linalg.norm(self.tcp - self.anchor, axis=1)
        acc, dff = self.smoothness()
        return {"ticks": len(self.t), "breakaway_n": self.breakaway(),
                "force_at_0.1_m_s_n": self.force_at_speed(0.1),
                "drift_m": self.drift(), "max_speed_m_s": float(self.speed.max()),
                "rms_lag_m": float(np.sqrt(np.mean(lag ** 2))),
                "final_lag_m": float(lag[-1]),
                "max_force_n": float(np.linalg.norm(self.force, axis=1).max()),
                "max_torque_n_m": float(np.linalg.norm(self.torque, axis=1).max()),
                "max_angle_deg": math.degrees(float(self.angle.max())),
                "min_margin": self.min_margin, "walls_met": self.walls_met,
                "peak_command_n_m": self.peak_command, "peak_applied_n_m": self.peak_applied,
                "max_reference_acceleration_rad_s2": acc, "max_feedforward_rate_n_m_s": dff,
                "port_energy_min_j": self.port_energy_min,
                "final_speed_m_s": float(self.speed[-1]),
                "lead_share": float(np.mean(self.modes == "lead")), "events": self.events}


class _Grip:
    """The simulated hand on the platform of a MuJoCo simulation: its anchor over time,
    and the spring-damper's force (and with a grip, moment) applied at the tool point
    each sub-step, with the power it puts in."""

    def __init__(self, hand: Hand, sim: Any, tool: np.ndarray, sub_dt: float) -> None:
        # deferred: Pinocchio's SO(3) exp and log, only when a run is made
        import pinocchio as pin

        self.pin, self.hand, self.sub_dt = pin, hand, sub_dt
        self.mj, self.m, self.d = sim.mj, sim.model, sim.data
        self.body = self.mj.mj_name2id(self.m, self.mj.mjtObj.mjOBJ_BODY, "platform_free")
        self.tool = tool
        self.jac, self.jac_r = np.zeros((3, self.m.nv)), np.zeros((3, self.m.nv))
        self.p0, _ = self.point()
        self.R0 = self.rotation()
        self.grips = hand.stiffness_rot > 0 or hand.damping_rot > 0
        self.f, self.moment, self.e = np.zeros(3), np.zeros(3), 0.0

    def rotation(self) -> np.ndarray:
        return np.array(self.d.xmat[self.body]).reshape(3, 3)

    def point(self) -> tuple[np.ndarray, np.ndarray]:
        """The tool point and its velocity."""
        d, body = self.d, self.body
        p = np.asarray(d.xpos[body] + d.xmat[body].reshape(3, 3) @ self.tool)
        self.mj.mj_jac(self.m, d, self.jac, self.jac_r, p, body)
        return p, self.jac @ d.qvel

    def aim(self, t: float) -> None:
        """The anchor at time t (held over the tick): position, velocity, orientation
        and angular velocity."""
        hand, pin = self.hand, self.pin
        a = self.p0 + hand.target(t)
        self.a, self.ad = a, (self.p0 + hand.target(t + 1e-3) - a) / 1e-3
        if self.grips:
            r1, r2 = hand.turn(t), hand.turn(t + 1e-3)
            Ra = pin.exp3(r1) @ self.R0
            self.Ra, self.wa = Ra, pin.log3(pin.exp3(r2) @ self.R0 @ Ra.T) / 1e-3

    def push(self) -> None:
        """The hand's force (and moment) on the platform for the next sub-step; ``e``
        the energy it puts in over it."""
        hand, d, body = self.hand, self.d, self.body
        p, v = self.point()
        f = hand.stiffness * (self.a - p) + hand.damping * (self.ad - v)
        nf = float(np.linalg.norm(f))
        if nf > hand.max_force:
            f *= hand.max_force / nf
        torque = np.zeros(3)
        e = float(f @ v)
        if self.grips:
            w = self.jac_r @ d.qvel
            R = self.rotation()
            torque = (hand.stiffness_rot * self.pin.log3(self.Ra @ R.T)
                      + hand.damping_rot * (self.wa - w))
            nt = float(np.linalg.norm(torque))
            if nt > hand.max_torque:
                torque *= hand.max_torque / nt
            e += float(torque @ w)
        d.xfrc_applied[body, :3] = f
        d.xfrc_applied[body, 3:] = np.cross(p - d.xipos[body], f) + torque
        self.f, self.moment, self.e = f, torque, e * self.sub_dt


def guide(model: Robot, plant: Robot, hand: Hand, controller: TickController,
          holding: Callable[[np.ndarray], np.ndarray], rate: float = 1000.0,
          kp: float = KP, kd: float = KD, drive: DriveSettings | None = None,
          start: np.ndarray | None = None) -> LeadRun:
    """The hand guides the platform of ``plant`` (from ``start``, Pinocchio's q of
    ``model``; default its home) through the drives, ``controller`` in the loop (lead-
    through: :func:`~sixplus3.interaction.people.hand.run_lead` builds it), for the
    hand's duration.  ``holding(theta)``: the torque that held the plant still before
    the first tick, at the encoder's first angles (the torque monitor's first reading);
    ``drive``: the drives' rate feedback, torque noise, seed and MuJoCo's step (default:
    the encoder's difference).  The controller's ``events``, ``min_margin``,
    ``min_slack`` and ``walls_met``, when it has them, are the run's."""
    model, plant = require_robot(model), require_robot(plant)
    drive = DriveSettings.of(drive)
    seed, torque_noise, timestep = drive.seed, drive.torque_noise, drive.timestep
    lt = controller
    loop = drive.loop(plant, rate, kp, kd)
    q0 = np.asarray(home(model).q[0] if start is None else start, dtype=float)
    loop.start(q0)
    g = _Grip(hand, loop.sim, np.asarray(model.tool.xyz, dtype=float), timestep)
    n = int(round(hand.duration * rate))
    out_t = np.arange(n) / rate
    tcp, anchor, force = np.empty((n, 3)), np.empty((n, 3)), np.zeros((n, 3))
    speed, angle, torque = np.empty(n), np.empty(n), np.zeros((n, 3))
    energy = 0.0
    e_min = 0.0
    de = 0.0
    touches = hand.stiffness > 0 or hand.damping > 0 or g.grips

    def push(_s: int) -> None:
        nonlocal de
        g.push()
        de += g.e

    def before_tick(k: int, _cmd: DriveCommand) -> Callable[[int], None] | None:
        nonlocal de
        g.aim(k / rate)
        de = 0.0
        return push if touches else None

    def after_tick(k: int, _tick: Tick) -> None:
        nonlocal energy, e_min
        energy += de
        e_min = min(e_min, energy)
        p, v = g.point()
        tcp[k], speed[k] = p, float(np.linalg.norm(v))
        anchor[k] = g.p0 + hand.target(k / rate)
        force[k], torque[k] = g.f, g.moment
        angle[k] = float(np.linalg.norm(g.pin.log3(g.rotation() @ g.R0.T)))
        g.d.xfrc_applied[g.body] = 0.0

    # before the first tick the drives were holding the plant still (whatever controller
    # ran before): the torque monitor's first reading is the plant's holding torque
    held = np.asarray(holding(loop.encoder()), dtype=float)
    out = run(loop, lt, n, initial=held, before=before_tick, after=after_tick)
    modes = np.array([c.mode for c in out.commands], dtype=object)
    rate_ref = np.array([c.theta_dot_ref for c in out.commands])
    ff_ref = np.array([c.tau_ff for c in out.commands])
    peak_cmd = float(np.abs(out.command).max())
    peak_app = float(np.abs(out.applied).max())
    th_log, tau_log = out.theta, out.readings[:n]
    margin = float(getattr(lt, "min_margin", math.nan))
    log = DriveLog(t=out_t, theta=th_log, tau=tau_log, name="lead",
                   meta={"plant": plant.name, "seed": seed, "torque_noise": torque_noise,
                         "lead": True})
    return LeadRun(t=out_t, tcp=tcp, anchor=anchor, force=force, speed=speed,
                   torque=torque, angle=angle, modes=modes, rate_ref=rate_ref,
                   tau_ff=ff_ref,
                   peak_command=peak_cmd, peak_applied=peak_app,
                   min_margin=margin if math.isfinite(margin) else float("nan"),
                   min_slack=float(getattr(lt, "min_slack", math.nan)),
                   walls_met=int(getattr(lt, "walls_met", 0)), port_energy_min=e_min,
                   events=list(getattr(lt, "events", [])), log=log)


__all__ = ["Hand", "LeadRun", "MOVED", "guide", "hand_from_dict", "read_hand"]
