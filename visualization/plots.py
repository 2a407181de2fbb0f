"""PNG plots of a validated trajectory: torques, rates, singularity margins, joint and
platform excursions.

Every title names the robot (name and hash) and the limits the file was planned to; the
joint and platform plots show each motion relative to its start (a millimetre
excursion at a height of 580 mm, or a few degrees at 127 deg, is then visible); where
the nine joints share a panel, a leg is a colour and a joint (A, B, C) a line style."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.fileio import save_figure
from sixplus3.kinematics.robot import robot_ik
from sixplus3.motion import Motion
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names

#: A leg's colour where the nine joints share a panel, and a joint's line style.
LEG_COLOURS = ("tab:blue", "tab:orange", "tab:green")
JOINT_STYLES = ("-", "--", "-.")


def subtitle(robot: Robot, limits: Limits, planned_torque: float | None = None) -> str:
    """One line naming the robot and the limits: what a reader of a plot must know."""
    parts = [f"torque {robot.limits.torque:g} N m"
             + (f" (planned to {planned_torque:g})" if planned_torque is not None else ""),
             f"speed {limits.velocity:.3g} rad/s", f"acc. {limits.acceleration:g} rad/s^2",
             f"margin {limits.margin:g}"]
    if limits.has_tcp:
        parts.append(f"platform {limits.tcp_speed:g} m/s, {limits.tcp_acceleration:g} m/s^2")

    return "\n".join(textwrap.wrap(f"robot {robot.name} ({robot.hash[:8]}); limits: "
                                   + ", ".join(parts), 96))


def plot_trajectory(robot: Robot, out_dir: str | Path, motion: Motion, tau: Any,
                    poses: tuple[Any, Any, Any], title: str = "",
                    limits: Limits | None = None,
                    planned_torque: float | None = None) -> list[str]:
    """Write <title>_torques.png, <title>_rates.png, <title>_margins.png,
    <title>_joints.png and <title>_platform.png of ``motion`` into ``out_dir``
    (per-trajectory names: plans written to one folder do not overwrite each other).
    ``tau`` (n, 9) the torques [N m] and ``poses`` the platform's (position (n, 3),
    quaternion (n, 4), crank angles (n, 3)) at its samples (a validation report's).

    Torques, speeds and accelerations are drawn one panel per leg (its joints A, B, C),
    with the hardware limits (red, dashed) and the torque planned to (orange, dotted);
    legends sit outside the axes so that no limit line is hidden.  ``limits``: those the
    file was planned to (default: the robot's), named in every title; the margins are
    drawn against theirs."""
    # deferred: matplotlib loads only when this runs
    import matplotlib

    matplotlib.use("Agg")
    # deferred: matplotlib loads only when this runs
    import matplotlib.pyplot as plt

    lim = limits if limits is not None else robot.limits
    t = motion.t
    position, quaternion, psi = poses
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    prefix = f"{title}_" if title else ""
    fig = _Figure(plt, title, subtitle(robot, lim, planned_torque))
    files = [_torques(fig, t, tau, robot.limits.torque, planned_torque,
                      out / f"{prefix}torques.png"),
             _rates(fig, robot.limits, t, tau, motion.theta_dot, motion.theta_ddot,
                    out / f"{prefix}rates.png"),
             _margins(fig, robot, t, position, quaternion, psi, lim.margin,
                      out / f"{prefix}margins.png"),
             _joints(fig, robot.limits, t, motion.theta, psi, out / f"{prefix}joints.png"),
             _platform(fig, t, position, quaternion, out / f"{prefix}platform.png")]
    return files


class _Figure:
    """What every figure of :func:`plot_trajectory` shares: pyplot, the title, the
    subtitle (the robot and the limits), the joints' names and styles."""

    def __init__(self, plt: Any, title: str, sub: str) -> None:
        self.plt, self.title, self.sub = plt, title, sub
        self.names = actuated_joint_names()
        # joints A, B, C of a leg: colour and line style both differ (B and C move alike)
        self.styles = [{"color": "tab:blue", "ls": "-"}, {"color": "tab:green", "ls": "--"},
                       {"color": "tab:purple", "ls": "-."}]


def _torques(f: _Figure, t: Any, tau: Any, hw: float, planned: float | None,
             path: Path) -> str:
    """The actuator torques, one panel per leg, with the hardware limit and the torque
    planned to."""
    fig, axes = f.plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for i, ax in enumerate(axes):
        for j in range(3 * i, 3 * i + 3):
            ax.plot(t, tau[:, j], lw=1.2, label=f.names[j], **f.styles[j % 3])
        for sgn in (1, -1):
            ax.axhline(sgn * hw, color="r", ls="--", lw=1.0,
                       label="hardware limit" if sgn == 1 else None)
            if planned is not None:
                ax.axhline(sgn * planned, color="orange", ls=":", lw=1.2,
                           label="planned to" if sgn == 1 else None)
        ax.set_ylabel("torque [N m]", fontsize=8)
        ax.set_ylim(-1.08 * hw, 1.08 * hw)
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    axes[-1].set_xlabel("t [s]")
    peak = float(np.abs(tau).max())
    axes[0].set_title(f"{f.title}: actuator torques, peak {peak:.3g} of {hw:.3g} "
                      f"({100 * peak / hw:.1f} %)\n{f.sub}", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


def _rates(f: _Figure, lim: Limits, t: Any, tau: Any, theta_dot: Any, theta_ddot: Any,
           path: Path) -> str:
    """Joint speeds, accelerations, jerk between samples and torque rate, with their
    limits."""
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    jerk = np.diff(theta_ddot, axis=0) / dt
    trate = np.diff(np.asarray(tau), axis=0) / dt
    tm = 0.5 * (np.asarray(t)[1:] + np.asarray(t)[:-1])
    fig, axes = f.plt.subplots(4, 1, figsize=(9, 9.5), sharex=True)
    panels = ((axes[0], t, theta_dot, lim.velocity, "speed [rad/s]", "hardware limit"),
              (axes[1], t, theta_ddot, lim.acceleration, "acceleration [rad/s^2]",
               "hardware limit"),
              (axes[2], tm, jerk, lim.jerk, "jerk [rad/s^3]", "jerk limit"),
              (axes[3], tm, trate, lim.torque_rate, "torque rate [N m/s]",
               "planner's bound (not a gate limit)"))
    for ax, tt, values, hw, label, what in panels:
        for j in range(9):
            ax.plot(tt, values[:, j], lw=1.0, label=f.names[j], color=LEG_COLOURS[j // 3],
                    ls=JOINT_STYLES[j % 3])
        limit_line = None
        for sgn in (1, -1):
            line = ax.axhline(sgn * hw, color="r", ls="--", lw=1.0, label=what)
            limit_line = limit_line or line
        ax.set_ylabel(label, fontsize=8)
        top = max(1.08 * hw, 1.05 * float(np.abs(values).max()) if values.size else 0.0)
        ax.set_ylim(-top, top)
        ax.legend(handles=[limit_line], loc="upper right", fontsize=7)
    handles = axes[0].get_lines()[:9]
    fig.legend(handles=handles, labels=[h.get_label() for h in handles],
               loc="center right", fontsize=7)
    axes[-1].set_xlabel("t [s]")
    axes[0].set_title(
        f"{f.title}: joint speeds (peak {np.abs(theta_dot).max() / lim.velocity:.0%} of "
        f"the limit), accelerations ({np.abs(theta_ddot).max() / lim.acceleration:.0%}),"
        f"\njerk between samples ({np.abs(jerk).max() / lim.jerk:.0%}) and torque rate "
        f"({np.abs(trate).max() / lim.torque_rate:.0%} of the planner's bound)\n{f.sub}",
        fontsize=9)
    fig.subplots_adjust(left=0.12, right=0.84, top=0.91, bottom=0.06, hspace=0.12)
    return save_figure(fig, path)


def _margins(f: _Figure, robot: Robot, t: Any, position: Any, quaternion: Any, psi: Any,
             margin: float, path: Path) -> str:
    """The seven singularity margins along the motion, with the threshold."""
    cfg = robot_ik(position, Rotation.from_quat(quaternion).as_matrix(), psi, robot)
    fig, ax = f.plt.subplots(figsize=(9, 4.8))
    for i in range(3):
        ax.plot(t, cfg.margins.leg_type1[:, i], lw=1.0, label=f"leg {i} type I")
        ax.plot(t, cfg.margins.leg_type2[:, i], lw=1.4, ls=":", label=f"leg {i} type II")
    ax.plot(t, cfg.margins.platform, "k", lw=1.5, label="platform")
    ax.axhspan(0.0, margin, color="r", alpha=0.12, lw=0)
    ax.axhline(margin, color="r", ls="-", lw=2.0, alpha=0.8, label="threshold")
    ax.set_ylim(0, 1)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("singularity margin (0 singular .. 1)")
    ax.set_title(f"{f.title}: singularity margins, threshold {margin:g} (red)\n{f.sub}",
                 fontsize=9)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path)


def _joints(f: _Figure, lim: Limits, t: Any, theta: Any, psi: Any, path: Path) -> str:
    """Each actuated and crank angle relative to its start, one panel per leg."""
    th_deg, psi_deg = np.degrees(np.asarray(theta)), np.degrees(np.asarray(psi))
    room = min(float(np.degrees(np.asarray(theta) - lim.theta_min).min()),
               float(np.degrees(lim.theta_max - np.asarray(theta)).min()))
    fig, axes = f.plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for i, ax in enumerate(axes):
        for j in range(3 * i, 3 * i + 3):
            ax.plot(t, th_deg[:, j] - th_deg[0, j], lw=1.2,
                    label=f"{f.names[j]} (from {th_deg[0, j]:.1f})", **f.styles[j % 3])
        ax.plot(t, psi_deg[:, i] - psi_deg[0, i], "k", ls=":", lw=1.2,
                label=f"crank psi {i} (from {psi_deg[0, i]:.1f})")
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.set_ylabel("from the start [deg]", fontsize=8)
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    axes[-1].set_xlabel("t [s]")
    axes[0].set_title(f"{f.title}: each actuated and crank angle relative to its start "
                      f"(legend: start [deg])\nclosest to the actuated range "
                      f"{np.degrees(lim.theta_min):g}..{np.degrees(lim.theta_max):g} deg: "
                      f"{room:.1f} deg\n{f.sub}", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)


def _platform(f: _Figure, t: Any, position: Any, quaternion: Any, path: Path) -> str:
    """The platform's centre and rotation relative to its start."""
    pos = 1000 * np.asarray(position)
    fig, axes = f.plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for k, c in enumerate("xyz"):
        axes[0].plot(t, pos[:, k] - pos[0, k], lw=1.2, label=f"{c} (from {pos[0, k]:.1f})")
    rot = Rotation.from_quat(quaternion)
    rel = (rot[0].inv() * rot).as_rotvec(degrees=True)  # in the start's frame
    for k, c in enumerate("xyz"):
        axes[1].plot(t, rel[:, k], lw=1.2, label=f"about {c}")
    axes[0].set_ylabel("centre from the start [mm]", fontsize=8)
    axes[1].set_ylabel("rotation from the start [deg]\n(rotation vector, start frame)",
                       fontsize=8)
    axes[1].set_xlabel("t [s]")
    for ax in axes:
        ax.axhline(0.0, color="0.6", lw=0.6)
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    start_rpy = np.degrees(rot[0].as_euler("xyz"))
    axes[0].set_title(f"{f.title}: platform pose relative to its start\n(start: centre [mm] "
                      f"in the legend, roll/pitch/yaw {start_rpy[0]:.1f}/{start_rpy[1]:.1f}/"
                      f"{start_rpy[2]:.1f} deg)\n{f.sub}", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)
