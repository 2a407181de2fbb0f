"""Replay and cross-check trajectories in MuJoCo, an engine that shares no code with ours.

The robot is exported as MJCF (:mod:`sixplus3.robot_description.mjcf`).  Two things
are done with it:

- **Constrained inverse dynamics** (:func:`mujoco_inverse_dynamics`): at each sample,
  MuJoCo's own kinematics give the tree velocity and acceleration that realise the
  actuated rates (the closure Jacobian Jc from the site Jacobians, its drift from
  ``mj_jacDot``); then [S^T Jc^T] [tau; lambda] = M qacc + qfrc_bias is solved (M from
  ``mj_fullM``, armature included) and the motors' friction law is added.  Only the
  configuration is taken from our kinematics, and MuJoCo's closure residual checks it.
- **Closed-loop replay** (:func:`simulate`): from the file's first state, the
  controller runs at the file's rate with a zero-order hold, through the one drive
  loop (:func:`~sixplus3.control.drive.loop.run`, an ideal drive): every tick
  u = s tau_ff + Kp (theta_ref - theta) + Kd (theta_dot_ref - theta_dot), with the
  plant's friction MuJoCo's own (viscous ``damping`` and dry ``frictionloss``, not the
  planner's smoothed law).  It reports the tracking error, the share of the PD in the
  torque, and the peak total torque against the hardware limit.

``mujoco`` is an optional dependency (``pip install sixplus3[sim]``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.drive.command import FileController
from sixplus3.control.drive.loop import KD, KP, DriveLoop, Tick, run
from sixplus3.control.drive.mujoco_model import MujocoRobot
from sixplus3.control.file.file_format import columns, motion_of
from sixplus3.control.gate.findings import FEEDFORWARD_TOL
from sixplus3.control.gate.interval import check_torque_hold, held_torque
from sixplus3.control.gate.validation import validate_file
from sixplus3.control.report import ValidationReport
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InputError, check_number
from sixplus3.kinematics.robot import home, robot_ik
from sixplus3.kinematics.rotations import matrix_from_quat
from sixplus3.motion import Motion
from sixplus3.robot_description.mjcf import TIMESTEP, build_mjcf, qpos_from_q
from sixplus3.robot_description.robot import Robot, require_robot


def mujoco_inverse_dynamics(robot: Robot, q: np.ndarray, theta_dot: np.ndarray,
                            theta_ddot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's constrained inverse dynamics of n states: (tau (n, 9), residual (n,))."""
    sim = MujocoRobot(robot)
    out = [sim.inverse_dynamics(q[k], theta_dot[k], theta_ddot[k]) for k in range(len(q))]
    return np.array([o[0] for o in out]), np.array([o[1] for o in out])


@dataclass
class SimulationReport:
    """What the closed-loop replay measured (angles [rad], torques [N m])."""

    rate_hz: float
    kp: float
    kd: float
    feedforward_scale: float
    samples: int
    duration_s: float
    max_tracking_error_rad: float
    rms_tracking_error_rad: float
    final_tracking_error_rad: float
    max_pd_torque: float
    pd_share: float  # ||tau_pd|| / ||tau_total|| over every joint and tick (2-norms)
    peak_total_torque: float
    torque_limit: float
    max_closure_residual_m: float
    #: MuJoCo's step [s] (implicitfast): the peak is of the torques commanded at the
    #: ticks, from the state this step integrated
    timestep_s: float = TIMESTEP
    torque_hold: str = "sample"  # the feed-forward held over each tick

    @property
    def within_torque_limit(self) -> bool:
        return self.peak_total_torque <= self.torque_limit

    def summary(self) -> dict[str, Any]:
        out = asdict(self)
        out["within_torque_limit"] = self.within_torque_limit
        return out


#: The feed-forward a sampled drive is given by default (docs/validation.md, "Torque for
#: sampled drives": the measured peaks of both modes on every example).
DEFAULT_TORQUE_HOLD = "mean"


def export_mjcf(robot: Robot, contacts: bool = False) -> str:
    """The MJCF file of ``robot`` as a user runs it: actuators and actuated joints
    limited by the robot's limits, and a ``home`` keyframe in the assembled home pose
    whose ctrl holds it against gravity (Pinocchio's closed-loop holding torques);
    ``contacts`` between the links of different legs.  ``mujoco.mj_resetDataKeyframe(m,
    d, 0)`` starts it assembled."""

    robot = require_robot(robot)
    q = home(robot).q[0]
    ctrl = ClosedLoopDynamics(robot).gravity_torques(q)
    return build_mjcf(robot, keyframe=(qpos_from_q(robot, q), ctrl), limits=True,
                      contacts=bool(contacts))


def _check(name: str, v: float, lo: float, hi: float) -> float:
    return check_number(name, v, lo, hi)


def judged_motion(rep: ValidationReport) -> Motion:
    """The motion the gate judged in ``rep`` (a report of a file it passed): its samples
    at the header's rate, the same fingerprint."""
    if rep.data is None or rep.header is None:
        raise InputError("a replay needs a report of validate_file with its samples",
                         value=None, valid="a report with data")
    motion = motion_of(rep.data, float(rep.header["rate_hz"]))
    if motion.fingerprint != rep.fingerprint:
        raise InputError("the samples are not the ones the gate judged", value=None,
                         valid="the report's own samples")
    return motion


def simulate(robot: Robot, q0: np.ndarray, motion: Motion, tau_ff: np.ndarray,
             kp: float = KP, kd: float = KD, feedforward_scale: float = 1.0,
             timestep: float = TIMESTEP) -> SimulationReport:
    """Replay a sampled ``motion`` (the gate's: its rate judged there, not again here)
    in MuJoCo under feed-forward ``tau_ff`` (n, 9) + PD at its rate.

    ``q0`` is the first sample's configuration (Pinocchio's coordinates; the motion must
    start at rest or at its first rates).  Gains and the feed-forward scale are checked,
    and that MuJoCo's step divides the control period.
    """
    kp = _check("kp", kp, 0.0, 1e5)
    kd = _check("kd", kd, 0.0, 1e4)
    s = _check("feedforward_scale", feedforward_scale, 0.0, 2.0)
    if not isinstance(motion, Motion):
        raise InputError("simulate replays a Motion (the gate's, e.g. motion_of of a "
                         "validated file's samples)", value=type(motion).__name__,
                         valid="sixplus3.motion.Motion")
    rate, theta, theta_dot = motion.rate, motion.theta, motion.theta_dot
    n_sub = round(1.0 / (rate * timestep)) if math.isfinite(rate) and rate > 0 else 0
    if n_sub < 1 or abs(n_sub * timestep * rate - 1.0) > 1e-9:
        raise InputError(f"the control period 1/{rate:g} s is not a multiple of the "
                         f"simulation step {timestep:g} s", value=rate,
                         valid=f"a rate dividing {1 / timestep:g} Hz")
    # the one drive loop (control/drive/loop.py), with an ideal drive: the plant's
    # angles and rates read exactly, the command applied as asked (no limit: the replay
    # reports the torque it commands, saturated or not)
    loop = DriveLoop(robot, rate, kp, kd, timestep, torque_noise=0.0, ideal=True)
    loop.start(q0, theta_dot[0])
    n = len(theta)
    rates = np.zeros((n, theta.shape[1]))
    res = 0.0

    def after_tick(k: int, tick: Tick) -> None:
        nonlocal res
        rates[k] = tick.theta_dot
        if k < n - 1:
            res = max(res, loop.sim.closure_residual())

    out = run(loop, FileController(theta, theta_dot, s * np.asarray(tau_ff)), n, after=after_tick,
              advance_last=False)
    err = theta - out.theta
    pd = kp * err + kd * (theta_dot - rates)
    total = out.command
    absmax = np.abs(err).max(axis=1)
    return SimulationReport(
        rate_hz=rate, kp=kp, kd=kd, feedforward_scale=s, samples=n,
        duration_s=(n - 1) / rate,
        max_tracking_error_rad=float(absmax.max()),
        rms_tracking_error_rad=float(np.sqrt(np.mean(err ** 2))),
        final_tracking_error_rad=float(absmax[-1]),
        max_pd_torque=float(np.abs(pd).max()),
        pd_share=float(np.linalg.norm(pd)) / max(float(np.linalg.norm(total)), 1e-300),
        peak_total_torque=float(np.abs(total).max()),
        torque_limit=robot.limits.torque,
        max_closure_residual_m=res, timestep_s=timestep)


def first_configuration(robot: Robot, rep: ValidationReport) -> np.ndarray:
    """Pinocchio configuration of a validated report's first sample (its platform pose
    and crank angles from the validator's own forward kinematics)."""

    assert rep.quaternion is not None and rep.position is not None and rep.psi is not None
    R = matrix_from_quat(rep.quaternion[0])[0]
    cfg = robot_ik(rep.position[0], R, rep.psi[0], robot)
    return np.asarray(cfg.q[0])


def simulate_file(path: str | Path, robot: Robot, kp: float = KP,
                  kd: float = KD, feedforward_scale: float = 1.0,
                  torque_hold: str = DEFAULT_TORQUE_HOLD
                  ) -> tuple[ValidationReport, Any]:
    """Validate a trajectory file, then replay it in MuJoCo: (validation, simulation).

    Only a file that passes the gate is simulated: with a defect (exit code 2) or a
    violated limit (exit code 1), the simulation is None.  ``torque_hold``: the
    feed-forward held over each tick (:func:`sixplus3.control.gate.interval.held_torque`).
    """

    robot = require_robot(robot)
    check_torque_hold(torque_hold)  # a bad mode is refused before the work
    rep = validate_file(path, robot)
    if not rep.ok or rep.data is None or rep.position is None:
        return rep, None
    ff = held_torque(columns(rep.data, "tau"), torque_hold)
    sim = simulate(robot, first_configuration(robot, rep), judged_motion(rep), ff, kp, kd,
                   feedforward_scale)
    sim.torque_hold = torque_hold
    return rep, sim


@dataclass
class EngineCheck:
    """The MuJoCo stage of ``validate --simulate`` on a validated file."""

    feedforward_error: float  # max |tau_file - tau_MuJoCo| over every sample [N m]
    closure_residual: float  # MuJoCo's closure residual at our configurations [m]
    simulation: SimulationReport
    exit_code: int  # 0 ok; 1 peak total torque over the limit; 2 feed-forward mismatch
    messages: list[str]

    def summary(self) -> dict[str, Any]:
        return {"mujoco_feedforward_error": self.feedforward_error,
                "mujoco_closure_residual": self.closure_residual,
                "simulation": self.simulation.summary(), "exit_code": self.exit_code,
                "messages": self.messages}


def engine_check(robot: Robot, rep: ValidationReport, kp: float = KP, kd: float = KD,
                 torque_hold: str = DEFAULT_TORQUE_HOLD) -> EngineCheck:
    """Check a validated report's file in MuJoCo: its feed-forward torques against
    MuJoCo's constrained inverse dynamics on every sample (a defect beyond the
    validator's feed-forward tolerance), then the closed-loop replay's peak total torque
    against the hardware limit (a violation above it)."""

    if rep.data is None or rep.position is None or rep.quaternion is None:
        raise InputError("engine_check needs a report of validate_file with its samples",
                         value=None, valid="a report with data")
    data = rep.data
    q = robot_ik(rep.position, matrix_from_quat(rep.quaternion), rep.psi, robot).q
    tau, res = mujoco_inverse_dynamics(robot, q, columns(data, "vel"), columns(data, "acc"))
    ff = float(np.abs(tau - columns(data, "tau")).max())
    sim = simulate(robot, q[0], judged_motion(rep), held_torque(columns(data, "tau"),
                                                                 torque_hold), kp, kd)
    sim.torque_hold = torque_hold
    code, msgs = 0, []
    if not ff <= FEEDFORWARD_TOL:
        code = 2
        msgs.append(f"feed-forward torque vs MuJoCo's inverse dynamics: {ff:.3g} N m > "
                    f"{FEEDFORWARD_TOL:g} N m")
    if not sim.within_torque_limit:
        code = code or 1
        msgs.append(f"feed-forward + PD (Kp {kp:g}, Kd {kd:g}) in MuJoCo peaks at "
                    f"{sim.peak_total_torque:.3f} N m > {sim.torque_limit:g} N m: no "
                    "headroom for the feedback")
    return EngineCheck(ff, float(res.max()), sim, code, msgs)
