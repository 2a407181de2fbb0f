"""The stacked regressor of a motion, and the robot's base parameters.

Base parameters (Gautier 1990, numerical form; FloBaRoID and BIRDy do the same): the
torques of any motion depend on pi only through beta = pi_b + K pi_d, where pi_b are the
r independent columns of the regressor (QR with column pivoting of a regressor stacked
over random states) and pi_d the rest.  r is the number of identifiable combinations;
``combination(k)`` lists the parameters each base parameter stands for.
"""

from __future__ import annotations

import hashlib
import io
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from sixplus3.cache import cached
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.codegen import cache_dir
from sixplus3.dynamics.compiled_kinematics import CompiledKinematics
from sixplus3.dynamics.regressor import Layout, layout, regressor_batch
from sixplus3.errors import InputError, Sixplus3Error
from sixplus3.fileio import atomic_write
from sixplus3.kinematics.robot import RobotConfig, robot_ik_pose
from sixplus3.kinematics.robot_fk import ik_jacobian, robot_fk, robot_fk_batch
from sixplus3.kinematics.rotations import matrix_from_rotvec, rotvec_from_matrix
from sixplus3.robot_description.robot import Robot

#: Relative threshold on |R_kk| / |R_00| of the pivoted QR for a base column.
RANK_TOL = 1e-8
#: Random states stacked to find the base parameters.
BASE_SAMPLES = 400
#: Samples solved at once by the forward kinematics of a log (:func:`states_of`).
CHUNK_FK = 64


@dataclass(frozen=True)
class BaseParameters:
    """beta = pi[index] + K @ pi[dependent] (module doc)."""

    layout: Layout
    index: np.ndarray  #: (r,) the base columns of pi
    dependent: np.ndarray  #: (P - r,) the other columns
    K: np.ndarray  #: (r, P - r)

    @property
    def rank(self) -> int:
        return len(self.index)

    def beta(self, pi: np.ndarray) -> np.ndarray:
        pi = np.asarray(pi, dtype=float)
        return pi[self.index] + self.K @ pi[self.dependent]

    def reduce(self, Y: np.ndarray) -> np.ndarray:
        """The base regressor: the columns of ``Y`` (..., P) at :attr:`index`."""
        return Y[..., self.index]

    @property
    def matrix(self) -> np.ndarray:
        """(r, P) B with beta = B pi."""
        B = np.zeros((self.rank, self.layout.size))
        B[np.arange(self.rank), self.index] = 1.0
        B[:, self.dependent] = self.K
        return B

    def combination(self, k: int, tol: float = 1e-9) -> str:
        """Base parameter k as its combination of the named parameters."""
        names = self.layout.names
        terms = [names[self.index[k]]]
        for j, c in zip(self.dependent, self.K[k], strict=True):
            if abs(c) > tol:
                terms.append(f"{c:+.4g} {names[j]}")
        return " ".join(terms)


def poses_of(robot: Robot, theta: np.ndarray, chunk: int = CHUNK_FK,
             start: np.ndarray | None = None, give_up: bool = False
             ) -> tuple[np.ndarray, np.ndarray]:
    """(x (n, 9) minimal coordinates, converged (n,)) of a sequence of actuated angles,
    by forward kinematics on the robot's branch from home.  Sample after sample by the
    compiled Newton of :class:`~sixplus3.dynamics.compiled_kinematics.
    CompiledKinematics` (about 40 us a sample); where it stops (no convergence, or a
    jump), ``chunk`` samples by the batched method (:func:`poses_batched`), then the
    compiled one again.  ``start`` and ``give_up``: as :func:`poses_batched`."""
    theta = np.asarray(theta, dtype=float)
    n = len(theta)
    x = robot_fk(theta[0], robot).x if start is None else np.array(start, dtype=float)
    ck = cached(("compiled-kinematics", robot.hash), lambda: CompiledKinematics(robot))
    xs = np.tile(x, (n, 1))
    ok = np.zeros(n, dtype=bool)
    i = 0
    while i < n:
        k = ck.follow(theta[i:], x, xs[i:])
        ok[i:i + k] = True
        if k:
            x = xs[i + k - 1]
        i += k
        if i >= n:
            break
        sl = slice(i, min(n, i + chunk))
        xs[sl], ok[sl] = poses_batched(robot, theta[sl], chunk, start=x, give_up=give_up)
        if give_up and not ok[sl].all():
            break
        x = xs[sl.stop - 1]
        i = sl.stop
    return xs, ok


def poses_batched(robot: Robot, theta: np.ndarray, chunk: int = CHUNK_FK,
                  start: np.ndarray | None = None, give_up: bool = False
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(x (n, 9) minimal coordinates, converged (n,)) of a sequence of actuated angles,
    by forward kinematics on the robot's branch from home: ``chunk`` samples at a time,
    each chunk seeded from the last solution before it; a chunk is kept up to its first
    sample that does not converge or jumps from its neighbour (more than 5 cm or
    0.1 rad), and the rest is solved again from there (one sample at a time where it
    must).  ``start``: the pose (9,) just before the first sample to follow from
    (default: the forward kinematics of the first sample from home); ``give_up``: stop
    at the first sample with no pose (the rest is left unsolved), for a caller that
    only asks whether the whole sequence has one."""
    theta = np.asarray(theta, dtype=float)
    n = len(theta)
    x = robot_fk(theta[0], robot).x if start is None else np.array(start, dtype=float)
    xs = np.tile(x, (n, 1))
    ok = np.zeros(n, dtype=bool)
    i, size = 0, chunk
    dx_dtheta: np.ndarray | None = None  # at the last pose solved, for the seeds
    th_last = theta[0]
    while i < n:
        sl = slice(i, min(n, i + size))
        m = sl.stop - sl.start
        seeds = np.tile(x, (m, 1))
        if dx_dtheta is not None:  # first-order prediction from the last pose solved
            d = (theta[sl] - th_last) @ dx_dtheta.T  # (m, 9): dp, d omega, d psi
            seeds[:, 0:3] += d[:, 0:3]
            seeds[:, 6:9] += d[:, 6:9]
            R = matrix_from_rotvec(d[:, 3:6]) @ matrix_from_rotvec(x[3:6])
            seeds[:, 3:6] = np.reshape(rotvec_from_matrix(R), (m, 3))
        fk = robot_fk_batch(theta[sl], seeds, robot, margins=False)
        steps = np.abs(np.diff(np.vstack([x[None], fk.x]), axis=0)).max(axis=1)
        good = fk.converged & (steps < 0.1)
        k = m if good.all() else int(np.argmin(good))
        if k == 0:
            if size > 1:
                size = max(1, size // 4)
                continue
            ok[i] = False  # this sample has no pose near the last: left unsolved
            xs[i] = x
            if give_up:
                break
            i += 1
            continue
        xs[i:i + k], ok[i:i + k] = fk.x[:k], True
        x = fk.x[k - 1]
        th_last = theta[i + k - 1]
        last = np.zeros(m, dtype=bool)
        last[k - 1] = True
        try:
            dx_dtheta = np.linalg.inv(ik_jacobian(fk.cfg.take(last))[0])
        except np.linalg.LinAlgError:  # singular: seed from the pose alone
            dx_dtheta = None
        i += k
        size = chunk
    return xs, ok


def states_of(robot: Robot, theta: np.ndarray, chunk: int = CHUNK_FK
              ) -> tuple[np.ndarray, np.ndarray]:
    """(q (n, nq), converged (n,)) of a sequence of actuated angles (:func:`poses_of`,
    then the configurations at the poses found, :func:`configurations`)."""
    theta = np.asarray(theta, dtype=float)
    x, ok = poses_of(robot, theta, chunk)
    parts = [cfg.q for _, cfg, _ in configurations(robot, theta, x)]
    return np.concatenate(parts), ok


#: Samples per batch of the closed-form kinematics at known poses.
BATCH_Q = 1024


def configurations(robot: Robot, theta: np.ndarray, x: np.ndarray
                   ) -> Iterator[tuple[slice, RobotConfig, np.ndarray]]:
    """(samples, their RobotConfig, converged) at poses ``x`` that solve ``theta`` (from
    :func:`poses_of`): one Newton check per sample, in batches of :data:`BATCH_Q`."""
    for i in range(0, len(theta), BATCH_Q):
        sl = slice(i, min(len(theta), i + BATCH_Q))
        fk = robot_fk_batch(theta[sl], x[sl], robot, margins=False)
        yield sl, fk.cfg, fk.converged


def stacked_regressor(dyn: ClosedLoopDynamics, theta: np.ndarray, theta_dot: np.ndarray,
                      theta_ddot: np.ndarray, x_known: np.ndarray | None = None
                      ) -> np.ndarray:
    """(n, 9, P) the regressor of n states of ``dyn``'s robot given by their actuated
    angles; a state whose forward kinematics fails or that is singular is an InputError
    (a log that is not a motion of this robot).

    ``x_known`` (n, 9): the states' minimal coordinates when they are known (a planned
    motion's own, not a log's): each sample's forward kinematics then starts there, and
    a failure says that the plan, not a log, has no pose there."""
    assert dyn.robot is not None
    if x_known is not None:
        fk = robot_fk_batch(np.asarray(theta, float), np.asarray(x_known, float), dyn.robot,
                            margins=False)
        q, ok = fk.cfg.q, fk.converged
        if not ok.all():
            k = int(np.argmin(ok))
            raise InputError(f"the planned state {k} has no pose of this robot near the "
                             "plan's own (the smoothed motion left the plan's branch)",
                             value=k, valid="states the planner produced")
    else:
        q, ok = states_of(dyn.robot, theta)
    if not ok.all():
        k = int(np.argmin(ok))
        raise InputError(f"no pose of this robot has the logged angles of sample {k} (is "
                         "the log of another robot, or are its offsets wrong?)", value=k,
                         valid="angles of an assembly of this robot")
    Y, rcond = regressor_batch(dyn, q, theta_dot, theta_ddot)
    if not np.all(np.isfinite(Y)):
        k = int(np.argmax(~np.isfinite(Y).all(axis=(1, 2))))
        raise InputError(f"sample {k} is at a parallel singularity (rcond {rcond[k]:.2e})",
                         value=float(rcond[k]), valid="non-singular states")
    return Y


def random_states(robot: Robot, n: int, seed: int = 0
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, theta_dot, theta_ddot) of n random reachable states around home: positions
    within 8 cm, tilts within 25 deg, cranks within 30 deg of home, rates of 2 rad/s and
    accelerations of 50 rad/s^2 (RMS)."""
    rng = np.random.default_rng(seed)
    qs: list[np.ndarray] = []
    home = np.asarray(robot.home_position)
    tries = 0
    while len(qs) < n and tries < 50 * n:
        tries += 1
        p = home + rng.uniform(-0.08, 0.08, 3)
        rpy = rng.uniform(-math.radians(25), math.radians(25), 3)
        psi = np.asarray(robot.home_psi) + rng.uniform(-0.5, 0.5, 3)
        try:
            cfg = robot_ik_pose(p, rpy, psi, robot=robot)
        except Exception:  # noqa: BLE001 - unreachable: draw again
            continue
        q = np.asarray(cfg.q[0])
        if np.all(np.isfinite(q)):
            qs.append(q)
    if len(qs) < n:
        raise InputError("too few reachable random states", value=len(qs), valid=str(n))
    q = np.array(qs)
    return q, rng.normal(0.0, 2.0, (n, 9)), rng.normal(0.0, 50.0, (n, 9))


def base_parameters(robot: Robot, n: int = BASE_SAMPLES, seed: int = 0) -> BaseParameters:
    """The base parameters of ``robot``'s structure (module doc), from ``n`` random
    states (cached per process by the robot's hash)."""

    return cached(("base-parameters", f"{robot.hash}:{n}:{seed}"),
                  lambda: _stored_base_parameters(robot, n, seed))


#: Bump when :func:`_base_parameters` changes what it computes (the disk cache's key).
BASE_FORMAT = 1


def _stored_base_parameters(robot: Robot, n: int, seed: int) -> BaseParameters:
    """:func:`_base_parameters`, kept on disk beside the compiled planner functions
    (``codegen.cache_dir()``): the QR of 400 random states costs ~2 s, and every log
    command needs it.  The file is keyed by the robot's hash, ``n``, ``seed`` and
    :data:`BASE_FORMAT`; a missing, unreadable or inconsistent file is recomputed."""
    key = hashlib.sha256(f"{robot.hash}:{n}:{seed}:{BASE_FORMAT}".encode()).hexdigest()[:24]
    path = cache_dir() / f"base_parameters_{key}.npz"
    lay = layout(ClosedLoopDynamics(robot))
    try:
        with np.load(path) as z:
            idx, dep, K = z["index"], z["dependent"], z["K"]
        if (idx.ndim == 1 and dep.ndim == 1 and K.shape == (len(idx), len(dep))
                and len(idx) + len(dep) == lay.size and np.all(np.isfinite(K))):
            return BaseParameters(layout=lay, index=idx, dependent=dep, K=K)
    except (OSError, KeyError, ValueError):
        pass
    base = _base_parameters(robot, n, seed)
    try:
        buf = io.BytesIO()
        np.savez(buf, index=base.index, dependent=base.dependent, K=base.K)
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, buf.getvalue())
    except (OSError, Sixplus3Error):  # a read-only cache: compute each time
        pass
    return base


def _base_parameters(robot: Robot, n: int, seed: int) -> BaseParameters:
    dyn = ClosedLoopDynamics(robot)
    q, v, a = random_states(robot, n, seed)
    Y, _ = regressor_batch(dyn, q, v, a)
    Y = Y[np.isfinite(Y).all(axis=(1, 2))]
    W = Y.reshape(-1, Y.shape[-1])
    scale = np.linalg.norm(W, axis=0)
    scale[scale == 0] = 1.0
    _, R, piv = scipy.linalg.qr(W / scale, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    r = int(np.sum(d > RANK_TOL * d[0]))
    R1, R2 = R[:r, :r], R[:r, r:]
    K = scipy.linalg.solve_triangular(R1, R2)
    # undo the column scaling: W_b pi_b + W_d pi_d = W_b (pi_b + K' pi_d)
    idx, dep = piv[:r], piv[r:]
    K = K * scale[dep][None, :] / scale[idx][:, None]
    return BaseParameters(layout=layout(dyn), index=np.asarray(idx), dependent=np.asarray(dep),
                          K=K)


__all__ = ["BaseParameters", "base_parameters", "random_states", "stacked_regressor",
           "poses_batched", "states_of"]
