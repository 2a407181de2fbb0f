"""The contact guard's offline tables (interaction/contact/guard.py's module doc): for every
sample k of a validated file's path, the reduced inertia, gravity, the time-scaling
terms, the velocity torque and its slope, the IK Jacobian, the stop table and the
observer's thresholds.  Nothing here runs per tick."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sixplus3.control.drive.command import Mode
from sixplus3.control.file.file_format import columns
from sixplus3.control.gate.stop import (
    TORQUE_SHARE,
    across_path,
    beta_interval,
    path_deceleration,
)
from sixplus3.control.report import ValidationReport
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.interaction.contact.parts import parameter_std2, velocity_slope
from sixplus3.interaction.envelope import DriveRate
from sixplus3.interaction.observer.momentum import MomentumObserver
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.robot_fk import ik_jacobian
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

#: The dry friction's share of the threshold, in the model's Coulomb torques: at a
#: reversal the plant's true dry friction swings over its whole band (+-f_c, both signs)
#: where the model's smooth law passes zero, and a plant's f_c is known to a few tens of
#: percent.
FRICTION_BAND = 2.5
#: [s] how far a drive may lag its reference (the threshold's window).
LAG = 0.02


@dataclass(frozen=True)
class ModelPrior:
    """How well the guard's robot is known (the threshold's model share, docs/safety.md,
    "An unidentified robot"): ``model_error``, the relative error of the inertial,
    velocity and gravity torques; ``friction``, the factor the plant's friction may be
    off by (the dry friction's band is (1 + friction) times the model's Coulomb torque,
    at least FRICTION_BAND; the viscous torque's error (friction - 1) times the model's
    at the plan's rates)."""

    model_error: float
    friction: float


#: An identified robot (``parameter_cov`` given): its parameters known to a few tens of
#: percent where they matter (the identification's own confidence enters through thr_p).
IDENTIFIED = ModelPrior(model_error=0.15, friction=1.0)
#: A robot that was not identified (the catalogue's, or a hand-written file): the stated
#: prior of a build's spread, ``identify plant``'s defaults: every link's mass and
#: inertia within +-30 %, rotors within +-40 %, friction up to 3 times the model's.  The
#: model error is the largest of these with a margin for the centres of mass.
UNIDENTIFIED = ModelPrior(model_error=0.5, friction=3.0)


@dataclass(frozen=True)
class PathTables:
    theta: np.ndarray  # (n, 9) the path's angles [rad]
    theta_d: np.ndarray  # (n, 9) its rates: theta'(s) [rad/s]
    M: np.ndarray  # (n, 9, 9) reduced inertia
    g: np.ndarray  # (n, 9) gravity torque
    a: np.ndarray  # (n, 9) M theta'
    b: np.ndarray  # (n, 9) tau - g
    b_cross: np.ndarray  # (n, 9) b without the path's acceleration along its tangent
    c: np.ndarray  # (n, 9) velocity torque at the plan's rates, without the friction
    D: np.ndarray  # (n, 9, 9) its slope in the rates
    J: np.ndarray  # (n, 9, 9) IK Jacobian
    vnorm: np.ndarray  # (n,) the plan's joint speed
    beta: np.ndarray  # (n,) the stop table [1/s]
    thr_base: np.ndarray  # (9,) the threshold's constant part [N m]
    thr_g: np.ndarray  # (n, 9) its share of gravity, and thr_p
    thr_p: np.ndarray  # (n, 9) the identified parameters' spread (0 without them)
    thr_k: np.ndarray  # (n, 9) its share of the motion (times sd^2)
    thr_a: np.ndarray  # (n, 9) its share of the path's acceleration (times |sdd|: a stop)


def path_tables(robot: Robot, rep: ValidationReport, rate: float, lim: Limits,
                share: float, gain: float, prior: ModelPrior, n_sigma: float,
                torque_noise: float, parameter_cov: tuple[np.ndarray, np.ndarray] | None
                ) -> PathTables:
    """The tables of the file the gate read into ``rep``, ticked at ``rate`` [Hz]
    (module doc)."""
    data = rep.data
    assert data is not None
    theta = columns(data, "pos")
    theta_d = columns(data, "vel")
    acc = columns(data, "acc")
    tau = columns(data, "tau")
    n = len(theta)
    dyn = ClosedLoopDynamics(robot)
    assert rep.position is not None and rep.quaternion is not None and rep.psi is not None
    cfg = robot_ik(rep.position, rot.matrix_from_quat(rep.quaternion), rep.psi, robot,
                   platform_margins=False)
    M = np.empty((n, 9, 9))
    g, _ = dyn.actuated_inverse_dynamics_batch(cfg.q, np.zeros((n, 9)), np.zeros((n, 9)),
                                               inertia=M)
    a = np.einsum("nij,nj->ni", M, theta_d)
    b = tau - g
    # the velocity terms alone (Coriolis, centripetal, friction), for the observer
    tau_v, _ = dyn.actuated_inverse_dynamics_batch(cfg.q, theta_d, np.zeros((n, 9)))
    # without the friction: evaluated at the measured rate each tick (its sign follows
    # the motion, a retract's too)
    c = tau_v - g - robot.motors.friction(theta_d)
    # the stop table: always the guard's own recomputation (control/gate/stop.py) at its
    # share and the envelope's limits, whatever the file's header says: the gate refuses
    # a header table that is not this one within rounding, and the guard trusts nothing
    # it reads either (a forged table that never stops, or pushes, never reaches a stop)
    b_cross = across_path(a, b, theta_d, acc)
    beta = path_deceleration(a, b_cross, g, theta_d, lim.torque, lim.acceleration, share)
    # the threshold: the observer's noise, the model's share, the dry friction band
    s_obs = torque_noise * math.sqrt(gain * (1.0 / rate) / 2.0)
    fc = robot.motors.coulomb_per_joint
    model_error = prior.model_error
    thr_base = n_sigma * max(s_obs, 1e-4) + max(FRICTION_BAND, 1.0 + prior.friction) * fc + 0.02
    # |M| |thetaddot|, not |M thetaddot|: an error in the inertia does not cancel
    # between joints the way the nominal terms may
    thr_k = model_error * (np.abs(c) + np.einsum("nij,nj->ni", np.abs(M), np.abs(acc)))
    # the robot may lag its reference by a few ticks (a soft drive): take each sample's
    # threshold as the largest over the samples it may still be at
    lag = max(1, int(round(LAG * rate)))
    thr_k = np.stack([thr_k[max(0, k - lag):k + 1].max(axis=0) for k in range(n)])
    # a stop's (or a retract's) own acceleration along the path, a_k sdd: its error
    # model_error |M| |theta'| |sdd|, which the plan's acceleration does not bound (a
    # plant heavier than the model, stopped hard: session 34's claims during a stop)
    thr_a = model_error * np.einsum("nij,nj->ni", np.abs(M), np.abs(theta_d))
    thr_a = np.stack([thr_a[max(0, k - lag):k + 1].max(axis=0) for k in range(n)])
    # an identification's confidence in its parameters (``parameter_cov``: the base
    # columns and the covariance of the base parameters, identify estimate --report's
    # parameters.npz): n_sigma standard deviations of the model torque at each planned
    # state, diag(Y_b Sigma Y_b^T), over the same window
    thr_p = np.zeros((n, 9))
    if parameter_cov is not None:
        sd = np.sqrt(parameter_std2(dyn, cfg.q, theta_d, acc, parameter_cov))
        thr_p = n_sigma * np.stack([sd[max(0, k - lag):k + 1].max(axis=0)
                                    for k in range(n)])
    # a friction known only within a factor: the viscous torque's error at the plan's
    # rates (the Coulomb share is in thr_base)
    visc = (prior.friction - 1.0) * np.abs(robot.motors.viscous_per_joint * theta_d)
    thr_g = model_error * np.abs(g) + thr_p + visc
    return PathTables(theta=theta, theta_d=theta_d, M=M, g=g, a=a, b=b, b_cross=b_cross, c=c,
                      D=velocity_slope(dyn, cfg.q, theta_d), J=ik_jacobian(cfg),
                      vnorm=np.linalg.norm(theta_d, axis=1), beta=beta,
                      thr_base=np.asarray(thr_base, dtype=float), thr_g=thr_g, thr_p=thr_p,
                      thr_k=thr_k, thr_a=thr_a)


@dataclass
class GuardState:
    """The contact guard's state while it runs a file (interaction/contact/guard.py): made anew
    by each ``reset``, the rest of the guard is its settings and its frozen tables."""

    rates: DriveRate  #: the drive's rate as the guard models it (envelope.DriveRate)
    motion: deque[tuple[float, float]]  #: the motion's threshold share over the last LAG
    last_ref: np.ndarray  #: the last reference commanded
    observer: MomentumObserver  #: the momentum observer (interaction/observer/momentum.py)
    s: float = 0.0  #: path position [samples]
    sd: float = 1.0  #: path speed [file seconds per second]
    sdd: float = 0.0  #: path acceleration
    t: float = 0.0  #: [s] since the start
    mode: Mode = Mode.FOLLOW
    events: list[str] = field(default_factory=list)
    prev: np.ndarray | None = None  #: the last good reading
    read: np.ndarray | None = None  #: the last tick's angles, when they were a reading
    since_good: int = 0  #: ticks since the last good reading
    vel: np.ndarray = field(default_factory=lambda: np.zeros(9))  #: the encoder's rate
    over: int = 0  #: ticks above the threshold in a row
    saturated: float = 0.0  #: [s] a drive at its limit
    sm: float = 0.0  #: the measured path speed (the rate along the path's tangent)
    clipped: bool = False  #: the last command would have saturated the drive
    since: float = 0.0
    quiet: float = 0.0
    contact: bool = False
    contact_site: str | None = None  #: "the platform" or "a leg", once there was one
    contact_t: float = 0.0
    fmax: float = 0.0  #: the largest force estimated since the contact [N]
    retract_from: float = 0.0
    rested: bool = False  #: a contact's stop has come to rest
    offset: np.ndarray = field(default_factory=lambda: np.zeros(9))  #: measured - path at rest


def thresholds(g: Any, k: int, motion: deque[tuple[float, float]]
               ) -> tuple[np.ndarray, np.ndarray]:
    """(where a contact is judged, whether there is one): the guard ``g``'s thresholds at
    sample k.  The motion's share is the reference's path speed and acceleration, the
    largest over the last LAG (``motion``, a deque of LAG ticks this appends to: the
    robot follows a stop's reference a few ticks late, its motion outlasts the
    reference's); the first leaves out the stop's own acceleration, which the guard's
    stop after a contact adds to every joint alike."""
    tb = g.tables
    st = g.st
    motion.append((max(st.sd ** 2, abs(st.sdd) / max(float(tb.beta[k]), 1.0)), abs(st.sdd)))
    f_k = max(m[0] for m in motion)
    f_a = max(m[1] for m in motion)
    thr_site = tb.thr_base + tb.thr_g[k] + tb.thr_k[k] * f_k
    return thr_site, thr_site + tb.thr_a[k] * f_a


def deceleration_at(a: np.ndarray, b_cross: np.ndarray, g: np.ndarray,
                    theta_d: np.ndarray, sd: float, torque: float, acceleration: float,
                    share: float = TORQUE_SHARE) -> float:
    """beta [1/s] that sample's joint speed may fall at, at the path speed ``sd`` itself:
    |sd^2 b_cross + g - beta a| within ``share`` of the torque limit on every joint
    (control/gate/stop.py's :func:`beta_interval`, the table's condition at one speed)
    and the joints' deceleration within the acceleration limit.  The table's beta_k
    holds at every speed in [0, 1]: where the plan runs near the torque limit it is
    small, while at a stop's own speed a far larger deceleration fits.  0 where none
    does."""
    cap = share * torque
    c = sd * sd * b_cross + g
    lo, hi = beta_interval(a[None], c[None], cap)
    if float(hi[0]) < max(float(lo[0]), 0.0) or bool(np.any((a == 0.0) & (np.abs(c) > cap))):
        return 0.0
    vmax = float(np.abs(theta_d).max())
    return min(float(hi[0]), acceleration / max(vmax, 1e-9), 1e6)


__all__ = ["FRICTION_BAND", "IDENTIFIED", "LAG", "UNIDENTIFIED", "GuardState", "ModelPrior",
           "PathTables", "deceleration_at", "path_tables", "thresholds"]
