"""Forged trajectory files shared by the gate's tests (imported by tests/test_gate.py and
tests/test_gate_attacks.py): consistent forgeries whose digest is recomputed, so that
only the physics can refuse them."""

from __future__ import annotations

import numpy as np

from sixplus3.control.file import file_format as ff
from sixplus3.control.file.file_format import COLUMNS, JOINTS
from sixplus3.control.file.trajectory_file import encode
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import home
from sixplus3.kinematics.robot_fk import robot_fk_batch
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()
POS = [COLUMNS.index(f"{j}_pos") for j in JOINTS]
TAU = [COLUMNS.index(f"{j}_tau") for j in JOINTS]
DYN = ClosedLoopDynamics(ROBOT)


def zigzag(rate: float, eps: float, joints=range(9), n: int = 24,
           robot: Robot = ROBOT) -> bytes:
    """The audit's forgery: every sample alternates by +-eps around home, velocities and
    accelerations 0, platform columns and torques recomputed, digest recomputed."""
    th = np.repeat(home(ROBOT).theta, n, axis=0)
    sign = np.where(np.arange(n) % 2 == 0, -1.0, 1.0)
    sign[[0, -1]] = 0.0
    for j in joints:
        th[:, j] += eps * sign
    x0 = np.r_[ROBOT.home_position, np.zeros(3), ROBOT.home_psi]
    fk = robot_fk_batch(th, np.repeat(x0[None], n, 0), ROBOT)
    tau, _ = DYN.actuated_inverse_dynamics_batch(fk.cfg.q, np.zeros((n, 9)),
                                                  np.zeros((n, 9)))
    data = np.zeros((n, len(COLUMNS)))
    data[:, 0] = np.arange(n) / rate
    data[:, POS] = th
    data[:, TAU] = tau
    data[:, 37:40] = fk.cfg.position
    data[:, 40:44] = rot.quat_from_matrix(fk.rotation)
    data[:, 44:47] = fk.cfg.psi
    header = {"format": ff.FORMAT, "rate_hz": float(rate), "samples": n,
              "duration_s": float(data[-1, 0]), "columns": COLUMNS,
              "robot": {"hash": robot.hash, "parameters": robot.as_dict()}}
    return encode(header, data)


