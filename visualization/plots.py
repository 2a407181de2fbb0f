"""PNG plots of a validated trajectory: torques, singularity margins, joint positions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names


def _save(fig, path: Path) -> str:
    import matplotlib.pyplot as plt

    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    tmp.replace(path)
    return str(path)


def plot_trajectory(robot: Robot, out_dir: str | Path, t, theta, tau, position, quaternion,
                    psi, torque_limit: float, margin: float, title: str = "") -> list[str]:
    """Write <title>_torques.png, <title>_margins.png and <title>_joints.png into
    ``out_dir`` (per-trajectory names: plans written to one folder do not overwrite each
    other's plots)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    prefix = f"{title}_" if title else ""
    names = actuated_joint_names()
    files = []
    fig, ax = plt.subplots(figsize=(9, 4.8))
    for j in range(9):
        ax.plot(t, tau[:, j], lw=1.2, label=names[j])
    for s in (1, -1):
        ax.axhline(s * torque_limit, color="r", ls="--", lw=1.0)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("actuator torque [N m] (Pinocchio)")
    ax.set_title(f"{title}: torques, limit +-{torque_limit:g} N m (red)", fontsize=10)
    ax.legend(ncol=5, fontsize=7)
    files.append(_save(fig, out / f"{prefix}torques.png"))

    cfg = robot_ik(position, Rotation.from_quat(quaternion).as_matrix(), psi, robot)
    fig, ax = plt.subplots(figsize=(9, 4.8))
    for i in range(3):
        ax.plot(t, cfg.margins.leg_type1[:, i], lw=1.0, label=f"leg {i} type I")
        ax.plot(t, cfg.margins.leg_type2[:, i], lw=1.0, ls="--", label=f"leg {i} type II")
    ax.plot(t, cfg.margins.platform, "k", lw=1.5, label="platform")
    ax.axhline(margin, color="r", ls="--", lw=1.0)
    ax.set_ylim(0, 1)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("singularity margin (0 singular .. 1)")
    ax.set_title(f"{title}: singularity margins, threshold {margin:g} (red)", fontsize=10)
    ax.legend(ncol=4, fontsize=7)
    files.append(_save(fig, out / f"{prefix}margins.png"))

    fig, ax = plt.subplots(figsize=(9, 4.8))
    for j in range(9):
        ax.plot(t, np.degrees(theta[:, j]), lw=1.2, label=names[j])
    for i in range(3):
        ax.plot(t, np.degrees(psi[:, i]), "k", ls=":", lw=1.0,
                label="cranks psi" if i == 0 else None)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("angle [deg]")
    ax.set_title(f"{title}: actuated angles and crank angles (dotted)", fontsize=10)
    ax.legend(ncol=5, fontsize=7)
    files.append(_save(fig, out / f"{prefix}joints.png"))
    return files
