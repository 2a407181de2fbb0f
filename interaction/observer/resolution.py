"""How small a force the robot can feel: the force resolution at a pose, and its map
over the constant-orientation workspace (docs/interaction.md, "Resolution")."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sixplus3.errors import Sixplus3Error
from sixplus3.fileio import save_figure
from sixplus3.interaction.observer.wrench import MODEL_SIGMA, N_SIGMA, torque_sigma
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.robot_fk import ik_jacobian
from sixplus3.robot_description.robot import Robot, require_robot


@dataclass
class Resolution:
    """Per direction (fx, fy, fz [N], mx, my, mz [N m]): the smallest wrench the robot
    feels while moving (N_SIGMA standard deviations of the estimate) and at rest (plus
    the dry friction band of every joint at rest)."""

    moving: np.ndarray  # (6,)
    at_rest: np.ndarray  # (6,)


def resolution(robot: Robot, position: Any, rotation: Any = None, psi: Any = None,
               gain: float = 150.0,
               monitor_noise: float = 0.005, model_sigma: float = MODEL_SIGMA,
               n_sigma: float = N_SIGMA) -> Resolution:
    """The force resolution at one pose (home orientation and cranks by default)."""
    robot = require_robot(robot)
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    psi = np.asarray(robot.home_psi if psi is None else psi, dtype=float)
    cfg = robot_ik(np.asarray(position, dtype=float), R, psi, robot)
    J = ik_jacobian(cfg)[0]
    A = J.T[:6]
    dt = 1e-3
    var = np.full(9, torque_sigma(robot, monitor_noise) ** 2 * gain * dt / 2.0
                  + model_sigma ** 2)
    std = np.sqrt((A ** 2) @ var)
    band = np.abs(A) @ robot.motors.coulomb_per_joint
    return Resolution(moving=n_sigma * std, at_rest=n_sigma * std + band)


def resolution_map(robot: Robot, z: float | None = None, half: float = 0.15,
                   step: float = 0.01) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x (nx,), y (ny,), F (ny, nx, 2)): the largest of the three force components'
    resolution at rest and while moving, on the plane z (home by default) of the
    constant-orientation workspace (home orientation and cranks); NaN where the pose is
    unreachable or singular."""

    robot = require_robot(robot)
    z = robot.home_position[2] if z is None else z
    xs = np.arange(-half, half + 1e-12, step) + robot.home_position[0]
    ys = np.arange(-half, half + 1e-12, step) + robot.home_position[1]
    F = np.full((len(ys), len(xs), 2), np.nan)
    for i, y in enumerate(ys):
        for j, x in enumerate(xs):
            try:
                r = resolution(robot, (x, y, z))
            except Sixplus3Error:
                continue
            if np.all(np.isfinite(r.at_rest)):
                F[i, j] = (r.at_rest[:3].max(), r.moving[:3].max())
    return xs, ys, F


def plot_resolution_map(robot: Robot, path: str, z: float | None = None,
                        step: float = 0.01) -> dict[str, Any]:
    # deferred: matplotlib loads only when this runs
    import matplotlib

    matplotlib.use("Agg")
    # deferred: matplotlib loads only when this runs
    import matplotlib.pyplot as plt


    xs, ys, F = resolution_map(robot, z, step=step)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    for k, (ax, title) in enumerate(zip(axes, ("at rest (dry friction band + noise)",
                                               "while moving (noise and model)"),
                                        strict=True)):
        im = ax.pcolormesh(xs * 1e3, ys * 1e3, F[:, :, k], shading="nearest", cmap="viridis")
        fig.colorbar(im, ax=ax, label="smallest force felt, worst axis [N]")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_aspect("equal")
    zz = robot.home_position[2] if z is None else z
    fig.suptitle(f"{robot.name}: force resolution at z = {zz * 1e3:.0f} mm, home "
                 "orientation and cranks", fontsize=11)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
    ok = np.isfinite(F[:, :, 0])
    return {"z_m": zz, "points": int(ok.sum()),
            "at_rest_n": [float(np.nanmin(F[:, :, 0])), float(np.nanmedian(F[:, :, 0])),
                          float(np.nanmax(F[:, :, 0]))],
            "moving_n": [float(np.nanmin(F[:, :, 1])), float(np.nanmedian(F[:, :, 1])),
                         float(np.nanmax(F[:, :, 1]))]}


__all__ = ["Resolution", "plot_resolution_map", "resolution", "resolution_map"]
_ = math
