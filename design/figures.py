"""The paper's §V figures, regenerated with our model (PNG, matplotlib, headless).

Every figure's title says what it computes: design, reading of the conventions, grid.

- ``det_JK.png``        det J and det K over the design half-plane, type II curves black;
- ``tau_ext.png``       tau_ext saturated at 11 N m, the 10 N m contour black;
- ``cow.png``           the whole robot's constant-orientation workspace, layered, with
                        the footprint polygon and the actuated joints on each layer;
- ``resolution.png``    worst-case encoder resolution of P over the counted workspace.

Returns a summary (numbers quoted in docs/design.md) next to the files.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.design.cow import (
    COW,
    JOINT_RESOLUTION,
    LIMIT_SETS,
    PAPER_RATIO,
    compute_cow,
    encoder_resolution,
)
from sixplus3.design.readings import READINGS
from sixplus3.design.search import PAPER_DESIGN, Reading
from sixplus3.design.workspace import counted_reading
from sixplus3.fileio import save_figure
from sixplus3.kinematics.leg import leg_ik
from sixplus3.robot_description.geometry import LegGeometry, LegLoad
from sixplus3.robot_description.robot import Robot


@dataclass(frozen=True)
class FigureSummary:
    files: list[str]
    design: tuple[float, float, float]
    reading: str
    counted_area_m2: float
    cow_ratios: dict[str, float]
    paper_cow_ratio: float
    worst_resolution_m: float
    paper_resolution_m: float = 8.4e-6


def _grid_image(geometry: LegGeometry,
                step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Full (not halved) half-plane grid as an image: X (nx, ny), Y, flat points, mask."""
    r, l1 = geometry.dp, geometry.l1
    xs = np.arange(-r + step / 2, r, step)
    ys = np.arange(step / 2, l1 + r, step)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    inside = X**2 + (Y - l1) ** 2 <= r * r
    pts = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    return X, Y, pts, inside


def _disk_outline(ax: Any, geometry: LegGeometry) -> None:
    t = np.linspace(0, 2 * np.pi, 400)
    ax.plot(geometry.dp * np.cos(t), geometry.l1 + geometry.dp * np.sin(t), "k-", lw=0.6)
    ax.set_aspect("equal")
    ax.set_xlabel("x (along the actuated axis) [m]")
    ax.set_ylabel("y (distance from the axis) [m]")


def make_figures(out_dir: str | Path, reading: Reading | None = None,
                 design: tuple[float, float, float] = PAPER_DESIGN, ws_step: float = 0.0025,
                 cow_step: float = 0.01, cow_z_step: float = 0.05) -> FigureSummary:
    # deferred: matplotlib loads only when this runs
    import matplotlib

    matplotlib.use("Agg")
    # deferred: matplotlib loads only when this runs
    import matplotlib.pyplot as plt
    from matplotlib.colors import SymLogNorm, TwoSlopeNorm

    if reading is None:
        reading = READINGS["paper-mirror"]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    geometry = LegGeometry.symmetric(*design, ey=reading.ey, fy=-reading.ey)
    load = LegLoad()
    tag = (f"l2={design[0]:.3f}, l4={design[1]:.3f}, ex={design[2]:.3f} m; mode "
           f"{reading.mode}, ey={reading.ey:g} m; reading '{reading.name}' (the paper's "
           "design, not the default robot)")
    X, Y, pts, inside = _grid_image(geometry, ws_step)
    s = leg_ik(pts, geometry, reading.mode, load)
    ok = (s.ok & inside.ravel()).reshape(X.shape)
    files = []

    # --- det J and det K
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2))
    for ax, name, unit in ((axes[0], "det_J", "m^3"), (axes[1], "det_K", "m^6")):
        v = getattr(s, name).reshape(X.shape)
        vm = np.ma.masked_where(~ok, v)
        lim = np.nanpercentile(np.abs(v[ok]), 99) if ok.any() else 1.0
        pc = ax.pcolormesh(X, Y, vm, cmap="RdBu_r", shading="auto",
                           norm=SymLogNorm(linthresh=lim * 1e-3, vmin=-lim, vmax=lim))
        fig.colorbar(pc, ax=ax, label=f"{name.replace('_', ' ')} [{unit}]")
        # each panel's own zero set: det J = 0 is the type II singularity, det K = 0 the
        # type I (paper §IV)
        zero = np.ma.masked_where(~ok, v)
        ax.contour(X, Y, zero, levels=[0.0], colors="k", linewidths=1.5)
        _disk_outline(ax, geometry)
        kind = "type II" if name == "det_J" else "type I"
        ax.set_title(f"{name.replace('_', ' ')} (black: {name.replace('_', ' ')} = 0, "
                     f"{kind})", fontsize=10)
    fig.suptitle(f"det J and det K over the leg's half-plane (the paper's det_JK figure) - "
                 f"{tag}; grid {ws_step * 1000:g} mm", fontsize=9)
    fig.tight_layout()
    files.append(save_figure(fig, out / "det_JK.png", dpi=110))

    # --- tau_ext
    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    # Diverging, centred on the 10 N m limit: the structure inside the counted region
    # (blue) and how far outside it is (red, saturated at 20 N m) both stay visible.
    tau = np.ma.masked_where(~ok, np.minimum(s.tau_ext.reshape(X.shape), 20.0))
    low = float(np.floor(tau.min())) if ok.any() else 0.0
    pc = ax.pcolormesh(X, Y, tau, cmap="RdBu_r", shading="auto",
                       norm=TwoSlopeNorm(vmin=min(low, 9.0), vcenter=10.0, vmax=20.0))
    fig.colorbar(pc, ax=ax, label="tau_ext [N m] (centred on the 10 N m limit, saturated "
                 "at 20)")
    ax.contour(X, Y, np.ma.masked_where(~ok, s.tau_ext.reshape(X.shape)), levels=[10.0],
               colors="k", linewidths=1.5)
    cnt = counted_reading(s, load, reading).reshape(X.shape) & inside
    ax.contour(X, Y, cnt.astype(float), levels=[0.5], colors="w", linewidths=1.0,
               linestyles="--")
    _disk_outline(ax, geometry)
    area = float(cnt.sum()) * ws_step**2
    ax.set_title(f"tau_ext for F = F_g + 2mg B^3, m = 0.5 kg (black: 10 N m)\n"
                 f"white dashed: counted (theta in [0, {math.degrees(reading.theta_max):.0f}]"
                 f" deg, tau_ext <= 10): {area:.4f} m^2", fontsize=9)
    fig.suptitle(f"tau_ext over the leg's half-plane (the paper's WFW_optimal figure) - "
                 f"{tag}", fontsize=8)
    fig.tight_layout()
    files.append(save_figure(fig, out / "tau_ext.png", dpi=110))

    # --- encoder resolution over the counted workspace
    res = np.full(X.size, np.nan)
    usable = cnt.ravel() & (s.det_K != 0)
    if usable.any():
        res[usable] = encoder_resolution(JOINT_RESOLUTION, s.dtheta_dp()[usable])
    worst = float(np.nanmax(res)) if usable.any() else float("nan")
    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    pc = ax.pcolormesh(X, Y, np.ma.masked_invalid(res.reshape(X.shape)) * 1e6, cmap="magma",
                       shading="auto")
    fig.colorbar(pc, ax=ax, label="worst-case resolution of P [um]")
    _disk_outline(ax, geometry)
    ax.set_title(f"20-bit encoders, 72/34 belt: worst {worst * 1e6:.2f} um "
                 f"(paper: 8.4 um)", fontsize=9)
    fig.suptitle(f"{tag}", fontsize=8)
    fig.tight_layout()
    files.append(save_figure(fig, out / "resolution.png", dpi=110))

    # --- constant-orientation workspace of the whole robot, in the same reading: its
    # leg (design, ey), mode and theta rule (the paper's [0, 270] deg, counted its way)
    cow = compute_cow(cow_robot(reading, design), step=cow_step, z_step=cow_z_step,
                      reading=reading)
    ratios = {k: cow.ratio(k) for k in LIMIT_SETS}
    files.append(_cow_figure(plt, cow, out / "cow.png", ratios, reading))
    return FigureSummary(files=files, design=design, reading=reading.name,
                         counted_area_m2=area, cow_ratios=ratios, paper_cow_ratio=PAPER_RATIO,
                         worst_resolution_m=worst)


def cow_robot(reading: Reading, design: tuple[float, float, float] = PAPER_DESIGN) -> Robot:
    """The whole robot of a design reading: its leg (design, ey = -fy) in its mode, on
    the layout the paper states (the §V figures are the paper's; the default robot's
    axes are turned, docs/design.md "Layout")."""
    base = Robot.named("paper-as-stated")
    leg = LegGeometry.symmetric(*design, ey=reading.ey, fy=-reading.ey)
    return base.replace(geometry=replace(base.geometry, leg=leg), mode=reading.mode,
                        name=f"reading {reading.name}")


def _cow_figure(plt: Any, cow: COW, path: Path, ratios: dict[str, float],
                reading: Reading) -> str:
    # deferred: matplotlib loads only when this runs
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    fig = plt.figure(figsize=(12, 6.6))
    pts = Robot.named("paper-as-stated").geometry.actuated_joint_positions()
    poly = np.vstack([cow.footprint, cow.footprint[:1]])
    for col, key in enumerate(("reach", "torque")):
        ax = fig.add_subplot(1, 2, col + 1, projection="3d")
        X, Y = np.meshgrid(cow.xs, cow.ys, indexing="ij")
        for iz, z in enumerate(cow.zs):
            m = cow.masks[key][iz]
            if m.any():
                ax.contourf(X, Y, m.astype(float), levels=[0.5, 1.5], zdir="z",
                            offset=z, alpha=0.35, colors=[plt.cm.viridis(iz / len(cow.zs))])
            ax.plot(poly[:, 0], poly[:, 1], z, "k-", lw=0.6)
        ax.scatter(pts[:, 0], pts[:, 1], 0 * pts[:, 2], c="k", s=8)
        ax.set_zlim(0, cow.zs[-1])
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
        label = {"reach": "reachable (kinematic COW)",
                 "torque": "reach + theta in [0,270] + singularity-free + 2g within 10 N m"}
        ax.set_title(f"{label[key]}\nprojected area / footprint = {ratios[key]:.2f}"
                     f" (paper 5.03)", fontsize=9)
    norm = Normalize(vmin=0.0, vmax=float(cow.zs[-1]))
    cax = fig.add_axes((0.92, 0.15, 0.014, 0.6))
    fig.colorbar(ScalarMappable(norm=norm, cmap=plt.cm.viridis), cax=cax,
                 label="layer height z [m]")
    fig.suptitle(f"Constant-orientation workspace, reading '{reading.name}': mode {cow.mode}, "
                 f"ey = {reading.ey:g} m, theta in [0, 270] deg counted the reading's way; "
                 "platform horizontal, P_i on a 0.173 m triangle (psi = 90 deg),\n"
                 f"|a_j - a_i| = 0.143 m; layers every {cow.z_step * 100:.0f} cm, grid "
                 f"{cow.step * 100:.0f} cm; polygon: hull of the 9 actuated joints",
                 fontsize=8)
    fig.subplots_adjust(left=0.0, right=0.9, bottom=0.04, top=0.84, wspace=0.08)
    return save_figure(fig, path, dpi=110)


__all__ = ["FigureSummary", "make_figures"]
