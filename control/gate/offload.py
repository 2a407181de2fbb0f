"""The validator's dynamics worker: the constrained inverse dynamics of a motion's points,
shared between the validating process and one forked worker process.

Why a process: the per-state Pinocchio calls hold the GIL, so a thread does not run them
in parallel.  docs/validation.md ("Speed") and BENCHMARKS.md ("The gate") measure it.
"""

from __future__ import annotations

import mmap
import os
import struct
import sys
import threading

import numpy as np

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.robot_description.robot import Robot

#: Motions of fewer points (samples + midpoints) are checked in one process: forking a
#: worker costs more than it saves below this.
OFFLOAD_MIN_POINTS = 2000
#: ... and above this (the shared states and results take ~1.2 kB per point) in one
#: process (a window of the validator has at most 2 x WINDOW - 1 points).
OFFLOAD_MAX_POINTS = 1_000_000
#: The worker's share of the points' dynamics: this process meanwhile computes the
#: midpoints' forward kinematics, checks the branch (a second forward kinematics), the
#: spherical joints and the clearance (measured balance on 2 cores:
#: benchmarks/bench_validate.py).
OFFLOAD_SHARE = 0.72


class Offload:
    """The constrained inverse dynamics of a motion's points (samples, then midpoints),
    range by range, shared between this process and a forked worker process.

    Why a process: the per-state Pinocchio calls hold the GIL, so a thread does not run
    them in parallel.  Why a fork, made early: the child starts with the modules and the
    robot's model already loaded (an interpreter started afresh spends ~0.5 s
    importing), and it must be made before numba starts its thread pool here (GNU
    OpenMP aborts a child forked after that).  So a worker is forked only on Linux, when
    this process runs no other thread and numba's threading layer is not started, for
    :data:`OFFLOAD_MIN_POINTS` to :data:`OFFLOAD_MAX_POINTS` points.

    The states (q, theta_dot, theta_ddot) and the results (tau, rcond) live in one
    anonymous shared mapping; the pipes carry only (start, stop) ranges and their
    acknowledgements.  The worker computes with numpy and Pinocchio only, and leaves with
    ``os._exit`` when the job pipe closes.  A range it did not acknowledge is computed
    here: the results never depend on whether a worker ran.
    """

    def __init__(self, robot: Robot, points: int) -> None:
        self.dyn = ClosedLoopDynamics(robot)
        nq = self.dyn.model.nq
        self.pid = 0
        self.to_child = self.from_child = -1
        self.pending: list[tuple[int, int]] = []
        widths = (nq, 9, 9, 9, 1, 81)
        fork = OFFLOAD_MIN_POINTS <= points <= OFFLOAD_MAX_POINTS and _may_fork()
        size = max(1, points * sum(widths))
        # shared with the worker (the array keeps the mapping alive), else private
        flat = (np.frombuffer(mmap.mmap(-1, 8 * size), dtype=np.float64) if fork
                else np.empty(size))
        cols = np.cumsum((0,) + widths) * points
        self.q, self.v, self.a, self.tau, rcond, inertia = (
            flat[cols[k]:cols[k + 1]].reshape(points, w) for k, w in enumerate(widths))
        self.rcond = rcond[:, 0]
        self.inertia = inertia.reshape(points, 9, 9)
        if fork:
            self._fork()

    def _fork(self) -> None:
        try:
            r_job, w_job = os.pipe()
            r_ack, w_ack = os.pipe()
        except OSError:
            return
        try:
            pid = os.fork()
        except OSError:
            for fd in (r_job, w_job, r_ack, w_ack):
                os.close(fd)
            return
        if pid == 0:  # the worker
            code = 0
            try:
                os.close(w_job)
                os.close(r_ack)
                while True:
                    msg = _read_exactly(r_job, 16)
                    if len(msg) < 16:
                        break
                    self.compute(*struct.unpack("<qq", msg))
                    os.write(w_ack, msg)
            except BaseException:  # noqa: BLE001 - the parent computes what is missing
                code = 1
            os._exit(code)
        os.close(r_job)
        os.close(w_ack)
        self.pid, self.to_child, self.from_child = pid, w_job, r_ack

    def compute(self, start: int, stop: int) -> None:
        """Points [start, stop) in this process."""
        if stop > start:
            sl = slice(start, stop)
            m_red = np.empty((stop - start, 9, 9))
            self.tau[sl], self.rcond[sl] = self.dyn.actuated_inverse_dynamics_batch(
                self.q[sl], self.v[sl], self.a[sl], inertia=m_red)
            self.inertia[sl] = m_red

    def submit(self, start: int, stop: int) -> None:
        """Points [start, stop) to the worker if there is one (else computed now)."""
        if stop > start and self.pid and self.to_child >= 0:
            try:
                os.write(self.to_child, struct.pack("<qq", start, stop))
                self.pending.append((start, stop))
                return
            except OSError:
                pass
        self.compute(start, stop)

    def wait(self) -> None:
        """Every submitted range done: acknowledged by the worker, or computed here."""
        if self.to_child >= 0:
            os.close(self.to_child)
            self.to_child = -1
        done = set()
        for _ in self.pending:
            msg = _read_exactly(self.from_child, 16) if self.from_child >= 0 else b""
            if len(msg) < 16:
                break
            done.add(struct.unpack("<qq", msg))
        for rng in self.pending:
            if rng not in done:
                self.compute(*rng)
        self.pending = []
        self.close()

    def close(self) -> None:
        for fd in (self.to_child, self.from_child):
            if fd >= 0:
                os.close(fd)
        self.to_child = self.from_child = -1
        if self.pid:
            os.waitpid(self.pid, 0)
            self.pid = 0


def _read_exactly(fd: int, size: int) -> bytes:
    out = b""
    while len(out) < size:
        chunk = os.read(fd, size - len(out))
        if not chunk:
            break
        out += chunk
    return out


def _may_fork() -> bool:
    """Linux, no other thread in this process, numba's thread pool not started, and
    not switched off (environment variable ``SIXPLUS3_NO_FORK=1``)."""
    if (sys.platform != "linux" or threading.active_count() != 1
            or os.environ.get("SIXPLUS3_NO_FORK", "") not in ("", "0")):
        return False
    # deferred: numba loads only when this runs
    import numba

    try:
        numba.threading_layer()
    except ValueError:  # no threading layer started yet
        return True
    return False


__all__ = ["OFFLOAD_MAX_POINTS", "OFFLOAD_MIN_POINTS", "OFFLOAD_SHARE", "Offload"]
