"""A virtual prototype: a trajectory file run on a *plant* robot in MuJoCo, logged as the
drives would log it (docs/identification.md, "The virtual prototype").

The plant is a robot file whose parameters differ from the model that planned the file
(masses, per-body inertias, centres of mass, rotor inertias, friction); it shares with
the planning model only what a lab knows (the geometry, the drive train, offsets and
directions).  MuJoCo runs it from its own MJCF (built from the plant's URDF), with the
plant's friction as MuJoCo's own: viscous ``damping`` and dry ``frictionloss`` (true
static friction, not the planner's smoothed law).  The drive runs at the file's rate:
every tick it reads its encoder, applies the file's feed-forward (held over the tick,
its mean) plus its PD on the measured angle and the plant's rate, quantised to the
drive's torque resolution, and holds it over the tick.  An optional external wrench on
the platform (a person's push: :class:`WrenchProfile`) acts through MuJoCo's
``xfrc_applied``.

The log (:mod:`sixplus3.control.file.drive_log`) holds what the drive saw: the encoder angle
quantised to one count of the motor's encoder (20 bit per motor turn through the belt:
2.8 microrad at the joint), and the torque it applied, quantised to 0.1 % of the motor's
rated torque (0.0106 N m at the joint) plus a seeded Gaussian noise of the torque
monitor (``torque_noise``, default 0.005 N m).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sixplus3.control.drive.command import FileController
from sixplus3.control.drive.loop import KD, KP, TORQUE_NOISE, DriveLoop, run
from sixplus3.control.drive.mujoco_model import MujocoRobot
from sixplus3.control.drive.simulation import first_configuration, judged_motion
from sixplus3.control.file.drive_log import DriveLog
from sixplus3.control.file.file_format import columns
from sixplus3.control.file.trajectory_parse import NUMBER
from sixplus3.control.gate.interval import held_torque
from sixplus3.control.gate.validation import validate_file
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InputError, ValidationFailed, check_number
from sixplus3.fileio import read_text
from sixplus3.kinematics.robot import home
from sixplus3.robot_description.mjcf import TIMESTEP
from sixplus3.robot_description.robot import Robot, require_robot


@dataclass
class WrenchProfile:
    """An external wrench on the platform over time: t (m,) [s], and (m, 6) force [N]
    and moment [N m] in the base frame, about the platform centre; held between rows
    (zero-order hold), zero before the first and after the last."""

    t: np.ndarray
    wrench: np.ndarray

    def at(self, t: float) -> np.ndarray:
        k = int(np.searchsorted(self.t, t + 1e-12, side="right")) - 1
        if k < 0 or t > self.t[-1] + 1e-12:
            return np.zeros(6)
        return self.wrench[k]


def read_wrench_profile(path: str | Path) -> WrenchProfile:
    """A wrench profile CSV: a header ``t,fx,fy,fz,mx,my,mz`` (``#`` comments allowed),
    times increasing, every value a finite number (|f| <= 500 N, |m| <= 50 N m)."""


    num = re.compile(NUMBER)
    lines = [ln.strip() for ln in read_text(path, "wrench profile").splitlines()]
    lines = [ln for ln in lines if ln and not ln.startswith("#")]
    if not lines or [c.strip() for c in lines[0].split(",")] != \
            ["t", "fx", "fy", "fz", "mx", "my", "mz"]:
        raise InputError(f"{Path(path).name}: the first row must name the columns "
                         "t,fx,fy,fz,mx,my,mz", value=lines[0][:60] if lines else "",
                         valid="t,fx,fy,fz,mx,my,mz")
    rows = []
    for k, ln in enumerate(lines[1:], 2):
        f = [x.strip() for x in ln.split(",")]
        if len(f) != 7 or not all(num.fullmatch(x) for x in f):
            raise InputError(f"{Path(path).name}: row {k} is not 7 numbers", value=ln[:60],
                             valid="7 decimal numbers")
        rows.append([float(x) for x in f])
    a = np.array(rows)
    if len(a) == 0 or np.any(np.diff(a[:, 0]) <= 0) or a[0, 0] < 0:
        raise InputError(f"{Path(path).name}: times must start >= 0 and increase",
                         value=None, valid="increasing times")
    if np.abs(a[:, 1:4]).max() > 500 or np.abs(a[:, 4:7]).max() > 50:
        raise InputError(f"{Path(path).name}: a force above 500 N or a moment above 50 N m",
                         value=float(np.abs(a[:, 1:]).max()), valid="|f| <= 500 N, "
                         "|m| <= 50 N m")
    return WrenchProfile(t=a[:, 0], wrench=a[:, 1:])


@dataclass
class PlantRun:
    log: DriveLog
    peak_torque: float  # largest |torque| the drives were asked for [N m] (> limit: saturated)
    max_tracking_error_rad: float
    torque_limit: float
    saturated: bool = False
    notes: list[str] = field(default_factory=list)


def run_on_plant(path: str | Path, model: Robot, plant: Robot, seed: int = 0,
                 kp: float = KP, kd: float = KD, torque_noise: float = TORQUE_NOISE,
                 wrench: WrenchProfile | None = None, hold: float = 0.0,
                 timestep: float = TIMESTEP) -> PlantRun:
    """Validate ``path`` for the planning ``model`` (the gate: only a valid file runs),
    then run it on ``plant`` in MuJoCo and log it (module doc).  ``hold`` [s]: keep
    commanding the last sample this long after the motion (a hold at rest)."""

    model, plant = require_robot(model), require_robot(plant)
    if plant.geometry != model.geometry or plant.mode != model.mode:
        raise InputError("the plant must have the planning model's geometry and assembly "
                         "mode (what differs is what a lab measures)", value=None,
                         valid="the same geometry")
    check_number("torque_noise", torque_noise, 0.0, 1.0)
    check_number("hold", hold, 0.0, 60.0)
    check_number("seed", seed, 0, 2 ** 32 - 1, integer=True)
    rep = validate_file(path, model)
    if not rep.ok or rep.data is None or rep.header is None:
        raise ValidationFailed("not run on the plant: " + "; ".join(rep.messages()),
                               rep.exit_code, rep)
    data = rep.data
    motion = judged_motion(rep)  # the plant runs what the gate judged
    rate, theta_ref, vel_ref = motion.rate, motion.theta, motion.theta_dot
    ff = held_torque(columns(data, "tau"), "mean")
    n_hold = int(round(hold * rate))
    if n_hold:
        theta_ref = np.vstack([theta_ref, np.repeat(theta_ref[-1:], n_hold, axis=0)])
        vel_ref = np.vstack([vel_ref, np.zeros((n_hold, 9))])
        ff = np.vstack([ff, np.repeat(columns(data, "tau")[-1:], n_hold, axis=0)])
    n = len(theta_ref)
    loop = DriveLoop(plant, rate, kp, kd, timestep, torque_noise, seed)
    loop.start(first_configuration(model, rep))
    sim = loop.sim
    mj, m = sim.mj, sim.model
    platform = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, "platform_free")
    if platform < 0:
        platform = next(b for b in range(m.nbody) if m.body_jntnum[b] and
                        m.jnt_type[m.body_jntadr[b]] == mj.mjtJoint.mjJNT_FREE)
    err = 0.0

    def before_tick(k: int, _cmd: object) -> Callable[[int], None] | None:
        nonlocal err
        err = max(err, float(np.abs(theta_ref[k] - loop.true_angles()).max()))
        if wrench is None:
            return None

        def hook(s: int) -> None:
            _apply_wrench(sim, platform, wrench.at((k + s / loop.n_sub) / rate))
        return hook

    # the file followed as it is, through the one drive loop; the log pairs each tick's
    # angles with the torque applied over it (the monitor read after the tick)
    out = run(loop, FileController(theta_ref, vel_ref, ff), n, before=before_tick, final=True,
              advance_last=False)
    th_log, tau_log = out.theta, out.readings[1:]
    peak = float(np.abs(np.rint(out.command / loop.t_unit) * loop.t_unit).max())
    t = np.arange(n) / rate
    log = DriveLog(t=t, theta=th_log, tau=tau_log, name=Path(path).name,
                   meta={"plant": plant.name, "seed": seed, "torque_noise": torque_noise})
    return PlantRun(log=log, peak_torque=peak, max_tracking_error_rad=err,
                    torque_limit=model.limits.torque,
                    saturated=peak > model.limits.torque)


def run_jog(plant: Robot, amplitude: float = 0.1, each: float = 1.2,
            rest: float = 0.3, rate: float = 1000.0, seed: int = 0,
            torque_noise: float = TORQUE_NOISE, kp: float = KP, kd: float = KD,
            timestep: float = TIMESTEP) -> DriveLog:
    """Each motor of ``plant`` jogged in turn from its home pose (the home jig's), as a
    lab jogs them for commissioning: motor j goes out by ``amplitude`` [rad] and back
    (a 1 - cos profile over ``each`` seconds) while the others hold, then all rest for
    ``rest`` seconds.  Every drive runs its PD at ``rate`` with the holding torques of
    home as feed-forward, as :func:`run_on_plant`'s drives do.  The log holds the true
    joint angles (quantised to a count) and the applied torques; write it in the drive's
    units with the plant's own offsets and directions (``write_log(..., units="drive")``)
    to get what the drives would report."""

    plant = require_robot(plant)
    for name, v, lo, hi in (("amplitude", amplitude, 0.0, 0.5), ("each", each, 0.2, 30.0),
                            ("rest", rest, 0.0, 30.0), ("rate", rate, 100.0, 10000.0)):
        check_number(name, v, lo, hi)
    h = home(plant)
    q0, th0 = np.asarray(h.q[0]), np.asarray(h.theta[0])
    ff = ClosedLoopDynamics(plant).gravity_torques(q0)
    n_each, n_rest = int(round(each * rate)), int(round(rest * rate))
    prof = amplitude * 0.5 * (1 - np.cos(2 * np.pi * np.arange(n_each) / n_each))
    vprof = amplitude * 0.5 * (2 * np.pi * rate / n_each) * np.sin(
        2 * np.pi * np.arange(n_each) / n_each)
    ref = np.tile(th0, (9 * (n_each + n_rest) + n_rest, 1))
    vref = np.zeros_like(ref)
    for j in range(9):
        k0 = n_rest + j * (n_each + n_rest)
        ref[k0:k0 + n_each, j] += prof
        vref[k0:k0 + n_each, j] = vprof
    loop = DriveLoop(plant, rate, kp, kd, timestep, torque_noise, seed)
    loop.start(q0)
    n = len(ref)
    out = run(loop, FileController(ref, vref, ff), n, final=True)
    th_log, tau_log = out.theta, out.readings[1:]
    return DriveLog(t=np.arange(n) / rate, theta=th_log, tau=tau_log, name="jog",
                    meta={"plant": plant.name, "seed": seed, "jog_amplitude_rad": amplitude})


def _apply_wrench(sim: MujocoRobot, body: int, w: np.ndarray) -> None:
    """MuJoCo's ``xfrc_applied`` is a force at the body's centre of mass and a moment: a
    wrench about the platform centre (the body's origin) is moved there."""
    d = sim.data
    f, mom = w[:3], w[3:]
    com = d.xipos[body]
    origin = d.xpos[body]
    d.xfrc_applied[body, :3] = f
    d.xfrc_applied[body, 3:] = mom + np.cross(origin - com, f)


__all__ = ["PlantRun", "WrenchProfile", "read_wrench_profile", "run_on_plant"]
