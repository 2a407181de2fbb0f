"""Commissioning: the zero offsets and directions that map the drives' counts to joint
angles (docs/commissioning.md).

- :func:`zero_offsets`: with the robot held in a known pose (the home jig, or angles
  measured against the mechanical references), each motor's encoder count c gives its
  offset theta_0 = theta_known - d c / k (k counts per joint radian, d the direction):
  exact to the count's quantisation, 1 / k = 2.8 microrad.
- :func:`check_directions`: a log of each motor jogged in turn from that pose (the
  others holding) is compared with the robot's dynamic model.  A motor whose direction
  is wrong reads its angle mirrored about the pose and its torque with the wrong sign;
  its holding torque against gravity and its inertial torque then disagree with the
  model.  Each motor's reversal is tried in turn, and a reversal is named when it
  divides the model's torque error in that motor's column at least :data:`GAIN` times.
- :func:`counts_to_theta`: the drives' read-back counts as joint angles, for
  ``feed --start-counts``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sixplus3.control.file.drive_log import JOINTS, DriveLog, counts_per_rad
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.regressor import N_BODY, N_MOTOR, parameters, regressor_batch
from sixplus3.errors import InputError
from sixplus3.identification.base import configurations, poses_of
from sixplus3.identification.signals import filter_log
from sixplus3.kinematics.robot import home
from sixplus3.robot_description.robot import Robot, require_robot

#: Largest spread of one motor's counts over a zeroing log [joint rad] (the robot must
#: rest in the jig while they are read; 0.05 deg).
MAX_SPREAD = math.radians(0.05)
#: A reversal is named when it divides the model's torque error by at least this.
GAIN = 2.0
#: Smallest excursion [rad] of a jogged motor for its direction to be judged (2 deg).
MIN_JOG = math.radians(2.0)
#: Samples of the filtered log the direction check uses at most (evenly spaced).
MAX_ROWS = 600
#: [Hz] the direction check's filter (a jog lasts about a second).
JOG_CUTOFF = 20.0
#: [s] between the samples the forward kinematics follows (a crank can turn several
#: rad/s while one motor moves; FK seeds each sample from the last).
FK_PERIOD = 0.004
#: Samples the forward kinematics follows at a time (each chunk seeded from the last
#: solution; a chunk that fails is split, identification.base.poses_of).
FK_CHUNK = 64
#: [rad] a reversal's mirrored angles further than this from the logged ones are
#: followed again; nearer ones (a motor at rest at the pose, up to its noise) keep the
#: logged pose as the Newton seed of their configuration.
MOVED = 1e-3


def known_pose(robot: Robot, theta_deg: np.ndarray | None = None) -> np.ndarray:
    """The actuated angles [rad] of the known pose: the robot's home (its home
    position and crank angles, as the home jig holds it) or ``theta_deg`` (9) [deg]
    measured against the mechanical references."""
    robot = require_robot(robot)
    if theta_deg is None:
        return np.asarray(home(robot).theta[0], dtype=float)
    th = np.asarray(theta_deg, dtype=float).ravel()
    if th.shape != (9,) or not np.all(np.isfinite(th)) or np.abs(th).max() > 360:
        raise InputError("the known pose needs nine finite angles in [-360, 360] deg",
                         value=th.tolist() if th.size < 20 else th.size,
                         valid="9 angles [deg]")
    return np.radians(th)


@dataclass(frozen=True)
class Zeroing:
    offsets: np.ndarray  # (9,) [rad]
    counts: np.ndarray  # (9,) the counts used (the mean over the readings)
    spread: np.ndarray  # (9,) max - min of each motor's counts over the readings
    theta_known: np.ndarray  # (9,) [rad]
    robot: Robot  # the robot with these offsets


def zero_offsets(robot: Robot, counts: np.ndarray, theta_known: np.ndarray) -> Zeroing:
    """The zero offsets from the counts (m, 9) (or (9,)) read with the robot resting in
    the pose ``theta_known`` (9,) [rad] (module doc); InputError when the robot moved
    while they were read or an offset leaves one turn."""
    robot = require_robot(robot)
    c = np.atleast_2d(np.asarray(counts))
    if c.ndim != 2 or c.shape[1] != 9 or len(c) == 0:
        raise InputError("zeroing needs the nine motors' counts", value=list(c.shape),
                         valid="(m, 9) integer counts")
    if not np.all(np.isfinite(c)) or np.any(c != np.rint(c)) or np.abs(c).max() > 2.0**53:
        raise InputError("encoder counts must be whole numbers", value=None,
                         valid="integers")
    k = counts_per_rad(robot)
    spread = (c.max(axis=0) - c.min(axis=0)).astype(float)
    if np.any(spread / k > MAX_SPREAD):
        j = int(np.argmax(spread))
        raise InputError(f"{JOINTS[j]} moved while its counts were read ({int(spread[j])} "
                         f"counts, {math.degrees(spread[j] / k):.3f} deg): the robot must "
                         "rest in the known pose", value=int(spread[j]),
                         valid=f"<= {MAX_SPREAD * k:.0f} counts")
    mean = c.mean(axis=0)
    d = np.asarray(robot.motors.directions, dtype=float)
    offsets = np.asarray(theta_known, dtype=float) - d * mean / k
    far = np.abs(offsets) > 2 * math.pi
    if far.any():
        j = int(np.argmax(far))
        raise InputError(f"{JOINTS[j]}: its offset {offsets[j]:.3f} rad is more than a "
                         "turn: the drive's multi-turn count is not the one this robot "
                         "was built with (reset the absolute encoder's multi-turn data, "
                         "then read again)", value=float(offsets[j]),
                         valid="|offset| <= 2 pi rad")
    new = robot.replace(motors=replace(robot.motors,
                                       zero_offsets=tuple(float(o) for o in offsets)))
    return Zeroing(offsets=offsets, counts=mean, spread=spread,
                   theta_known=np.asarray(theta_known, dtype=float), robot=new)


def counts_to_theta(robot: Robot, counts: np.ndarray) -> np.ndarray:
    """The joint angles [rad] (9,) of the counts (9,) the drives read back."""
    robot = require_robot(robot)
    c = np.asarray(counts, dtype=float).ravel()
    if c.shape != (9,) or not np.all(np.isfinite(c)) or np.any(c != np.rint(c)):
        raise InputError("nine whole encoder counts", value=c.size, valid="9 integers")
    m = robot.motors
    return (np.asarray(m.directions, dtype=float) * c / counts_per_rad(robot)
            + np.asarray(m.zero_offsets))


@dataclass(frozen=True)
class Directions:
    reversed: tuple[int, ...]  # motors found reversed (0..8)
    #: (9,) [N m RMS] the model's torque error in each motor's own column, as logged
    error_as_logged: np.ndarray
    #: (9,) [N m RMS] the same with that motor alone reversed
    error_reversed: np.ndarray
    total_before: float  # [N m RMS] over all columns, as logged
    total_after: float  # ... with the reversals found
    excursion: np.ndarray  # (9,) [rad] each motor's range over the log
    unjudged: tuple[int, ...]  # motors that moved less than MIN_JOG
    robot: Robot  # the robot with the reversals corrected (offsets kept at the pose)


def _column_errors(dyn: ClosedLoopDynamics, pi: np.ndarray, step: int, th: np.ndarray,
                   x: np.ndarray, thd: np.ndarray, thdd: np.ndarray, tau: np.ndarray,
                   coul: np.ndarray) -> np.ndarray:
    """(9,) RMS of the measured minus the model's torque per motor [N m], on every
    ``step``-th sample, at the poses ``x`` (the forward kinematics followed every
    sample: a crank can turn fast while a single motor moves)."""
    assert dyn.robot is not None
    sl = slice(None, None, step)
    parts = list(configurations(dyn.robot, th[sl], x[sl]))
    if not all(conv.all() for _, _, conv in parts):
        return np.full(9, math.inf)  # no pose near the one followed: not this hypothesis
    q = np.concatenate([cfg.q for _, cfg, _ in parts])
    Y, _ = regressor_batch(dyn, q, thd[sl], thdd[sl])
    nb = dyn.model.njoints - 1
    idx = np.arange(9)
    Y[:, idx, N_BODY * nb + N_MOTOR * idx + 2] = coul[sl]
    return np.sqrt(np.mean((tau[sl] - Y @ pi) ** 2, axis=0))


def check_directions(robot: Robot, log: DriveLog) -> Directions:
    """The motors whose direction is reversed, from a log of each motor jogged in turn
    starting at the pose where the offsets were set (module doc).

    For each motor j, the model's torque error in j's own column is measured as logged
    and with j reversed (its angle mirrored about the log's first sample, its rate,
    acceleration and torque negated).  j is named reversed when reversing it divides
    that error by :data:`GAIN` or more; the reversals found together must also lower
    the error over all columns (checked).  A motor that moved less than :data:`MIN_JOG`
    is not judged."""
    robot = require_robot(robot)
    f = filter_log(log, JOG_CUTOFF, decimate=False,
                   coulomb_velocity=robot.motors.coulomb_velocity)
    assert f.coulomb is not None
    fk = max(1, int(round(FK_PERIOD * log.rate)))
    th, thd, thdd, tau, coul = (a[::fk] for a in (f.theta, f.theta_dot, f.theta_ddot,
                                                    f.tau, f.coulomb))
    step = max(1, len(th) // MAX_ROWS)
    ref = log.theta[0]
    excursion = log.theta.max(axis=0) - log.theta.min(axis=0)
    unjudged = tuple(int(j) for j in np.flatnonzero(excursion < MIN_JOG))
    dyn = ClosedLoopDynamics(robot)
    pi = parameters(dyn)

    x_logged, ok_logged = poses_of(robot, th, FK_CHUNK)

    def errors(flip: set[int]) -> np.ndarray:
        s = np.ones(9)
        s[list(flip)] = -1.0
        th_h = np.where(s < 0, 2 * ref - th, th)
        if not flip:
            x, ok = x_logged, ok_logged
        else:
            # a reversal changes only the samples where a flipped motor is off the pose
            # (each motor is jogged in turn): follow those again, from the logged pose
            # before them; the rest keep the logged poses
            moved = np.flatnonzero(np.any(np.abs(th_h - th) > MOVED, axis=1))
            x, ok = x_logged.copy(), ok_logged.copy()
            if len(moved):
                a, b = int(moved[0]), int(moved[-1]) + 1
                start = x_logged[a - 1] if a > 0 and ok_logged[a - 1] else None
                x[a:b], ok[a:b] = poses_of(robot, th_h[a:b], FK_CHUNK, start=start,
                                           give_up=True)
        if not ok.all():  # no pose of the robot has those angles: not this hypothesis
            return np.full(9, math.inf)
        return _column_errors(dyn, pi, step, th_h, x, s * thd, s * thdd, s * tau, s * coul)

    as_logged = errors(set())
    if not np.all(np.isfinite(as_logged)):
        raise InputError(f"{log.name}: no pose of this robot has the logged angles (are the "
                         "zero offsets set? commission zero first)", value=None,
                         valid="a jog log from the zeroed pose")
    rev = np.full(9, math.nan)
    for j in range(9):
        if j not in unjudged:
            rev[j] = errors({j})[j]
    flips = {j for j in range(9) if j not in unjudged and rev[j] * GAIN <= as_logged[j]}
    before = math.sqrt(float(np.mean(as_logged ** 2)))
    after = math.sqrt(float(np.mean(errors(flips) ** 2))) if flips else before
    if flips and not after < before:
        raise InputError(f"{log.name}: reversing {', '.join(JOINTS[j] for j in sorted(flips))}"
                         f" fits each motor's own torque better but the whole log worse "
                         f"({after:.3f} against {before:.3f} N m RMS): check the log (one "
                         "motor jogged at a time, from the zeroed pose)", value=None,
                         valid="a consistent jog log")
    m = robot.motors
    d = np.array(m.directions)
    offs = np.array(m.zero_offsets)
    for j in flips:  # the reading at the pose kept: theta_0' = 2 theta_ref - theta_0
        d[j] = -d[j]
        offs[j] = 2 * ref[j] - offs[j]
    fixed = robot.replace(motors=replace(m, directions=tuple(int(v) for v in d),
                                         zero_offsets=tuple(float(o) for o in offs)))
    return Directions(reversed=tuple(sorted(flips)), error_as_logged=as_logged,
                      error_reversed=rev, total_before=before, total_after=after,
                      excursion=excursion, unjudged=unjudged, robot=fixed)


__all__ = ["GAIN", "MAX_SPREAD", "MIN_JOG", "Directions", "Zeroing", "check_directions",
           "counts_to_theta", "known_pose", "zero_offsets"]
