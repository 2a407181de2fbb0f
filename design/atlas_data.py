"""The orientation atlas's data: the xarray dataset, its summaries, files and figures.

:func:`sixplus3.design.atlas.compute_atlas` computes the largest tilts; this module
covers the robot's reachable region with a grid (:func:`position_grid`) and turns
them into a self-describing dataset (:func:`build_dataset`), reads the volumes
and the headline from it, writes and reads it (NetCDF) and draws its figures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from sixplus3.design import _atlas_kernel as _kernel
from sixplus3.errors import InputError, check_number
from sixplus3.fileio import atomic_write_with, save_figure
from sixplus3.kinematics.checks import PSI_MAX, PSI_MIN
from sixplus3.robot_description.robot import Robot

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

#: Binding codes (the first check no candidate passes just beyond the largest tilt).
BINDING = ("none", "reach", "theta", "spherical", "leg margin", "clearance", "platform",
           "torque", "max tilt")
CRANKS = ("free", "locked")
#: The planner's crank range [deg].
PSI_RANGE_DEG = (math.degrees(PSI_MIN), math.degrees(PSI_MAX))
#: Volumes reported for "every direction tilts at least" these angles [deg].
THRESHOLDS_DEG = (30.0, 45.0, 60.0, 90.0)


@dataclass(frozen=True)
class AtlasSettings:
    """What the atlas computes; every value in the file's attributes."""

    step: float = 0.02  # position grid [m]
    azimuth_step_deg: float = 15.0  # tilt-axis azimuths 0, step, .. < 360 [deg]
    torsions_deg: tuple[float, ...] = (0.0,)  # [deg]
    max_tilt_deg: float = 180.0
    scan_deg: float = 15.0  # the scan step before bisection [deg]
    resolution_deg: float = 1.0  # bisection resolution [deg]
    psi_step_deg: float = 7.5  # per-leg crank grid of the free search [deg]
    #: the optional dynamic criterion: 0 (off) or a, the platform must be able to
    #: accelerate at a g in every direction from rest within the torque limit [g]
    accel_g: float = 0.0

    def check(self) -> AtlasSettings:
        vals = {"step": (self.step, 0.002, 0.2), "azimuth_step_deg": (self.azimuth_step_deg,
                                                                      1.0, 180.0),
                "max_tilt_deg": (self.max_tilt_deg, 1.0, 180.0),
                "scan_deg": (self.scan_deg, 0.5, 90.0),
                "resolution_deg": (self.resolution_deg, 0.01, 10.0),
                "psi_step_deg": (self.psi_step_deg, 1.0, 45.0),
                "accel_g": (self.accel_g, 0.0, 5.0)}
        for name, (v, lo, hi) in vals.items():
            check_number(f"atlas {name}", v, lo, hi)
        tors = tuple(self.torsions_deg)
        if not tors or len(tors) > 36 or not all(
                isinstance(t, (int, float)) and math.isfinite(t) and -180 <= t <= 180
                for t in tors):
            raise InputError(f"atlas torsions must be 1..36 angles in [-180, 180] deg, "
                             f"got {tors!r}", value=tors, valid="[-180, 180] deg")
        return self

    @property
    def azimuths_deg(self) -> np.ndarray:
        return np.arange(0.0, 360.0 - 1e-9, self.azimuth_step_deg)


# --------------------------------------------------------------------- the grid
def position_grid(robot: Robot, step: float,
                  z_range: tuple[float, float] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(xs, ys, zs) [m] of a grid covering the robot's reachable region: the box around
    every position where some leg-wise crank choice reaches the level platform, from
    the leg reach on a coarse grid, plus one step of margin.  ``z_range`` (zmin, zmax)
    [m] keeps the heights within it (an InputError if it is not 0 < zmin <= zmax <= 3
    or holds no height of the grid)."""
    if z_range is not None:
        ok = (len(z_range) == 2 and all(isinstance(v, (int, float)) and math.isfinite(v)
                                         for v in z_range)
              and 0 < z_range[0] <= z_range[1] <= 3)
        if not ok:
            raise InputError(f"z range must be 0 < ZMIN <= ZMAX <= 3 m, got {z_range!r}",
                             value=z_range, valid="0 < ZMIN <= ZMAX <= 3 m")
    g = robot.geometry
    # no leg reaches further than base radius + |D - A| + |P - D| from the centre
    extent = min(2.0, g.base_radius + g.leg.l1 + g.leg.dp + g.platform_radius
                 + g.platform_crank)
    coarse = 0.04
    axis = np.arange(-extent, extent + 1e-9, coarse)
    zs = np.arange(coarse, extent + 1e-9, coarse)
    X, Y = np.meshgrid(axis, axis, indexing="ij")
    packed = _kernel.pack(robot)
    grid = np.radians(np.arange(PSI_RANGE_DEG[0], PSI_RANGE_DEG[1] + 1e-9, 15.0))
    level = np.broadcast_to(np.eye(3), (X.size, 3, 3)).copy()
    inside = []
    for z in zs:
        pos = np.c_[X.ravel(), Y.ravel(), np.full(X.size, z)]
        stage, _ = _kernel.leg_grid(pos, level, grid, *packed)
        ok = np.all(stage.max(axis=1) >= 1, axis=1)  # every leg reaches, some crank
        if ok.any():
            inside.append(pos[ok])
    if not inside:
        raise InputError("no position reaches the level platform: the robot has no "
                         "workspace", value=robot.name, valid="a robot with a workspace")
    pts = np.vstack(inside)
    lo, hi = pts.min(axis=0) - coarse, pts.max(axis=0) + coarse
    lo[2] = max(lo[2], step)

    def ax(a: float, b: float) -> np.ndarray:
        # symmetric about 0 in x and y so the home position's column is on the grid
        return np.round(np.arange(math.floor(a / step), math.ceil(b / step) + 1) * step, 9)

    xs, ys, zs = ax(lo[0], hi[0]), ax(lo[1], hi[1]), ax(lo[2], hi[2])
    if z_range is not None:
        zmin, zmax = z_range
        zs = zs[(zs >= zmin - 1e-9) & (zs <= zmax + 1e-9)]
        if not len(zs):
            raise InputError(f"z range [{zmin}, {zmax}] m holds no grid height (the grid "
                             f"has {ax(lo[2], hi[2])[[0, -1]].round(3).tolist()} m)",
                             value=z_range, valid="a range over the grid's heights")
    return xs, ys, zs


def build_dataset(robot: Robot, st: AtlasSettings, xs: np.ndarray, ys: np.ndarray,
                  zs: np.ndarray, cat: dict[str, Any], shape: tuple[int, ...],
             wall: float, npos: int, workers: int | None) -> xr.Dataset:

    # deferred: xarray (optional) loads only when this runs
    import xarray as xr

    try:
        software = f"sixplus3 {version('sixplus3')}"
    except PackageNotFoundError:  # a plain copy of the sources
        software = "sixplus3"
    dims = ("cranks", "torsion", "azimuth", "x", "y", "z")
    tilt = cat["max_tilt"].reshape(shape).astype(np.float32)
    bind = cat["binding"].reshape(shape).astype(np.int8)
    psi = cat["psi"].reshape(*shape, 3).astype(np.float32)
    ds = xr.Dataset(
        {"max_tilt": (dims, tilt, {
            "units": "degree", "long_name": "largest admissible tilt",
            "description": "largest tilt about the horizontal axis at the given azimuth "
                           "(scan then bisection); NaN where the zero-tilt pose is "
                           "inadmissible"}),
         "binding": (dims, bind, {
             "long_name": "first check failing just beyond max_tilt",
             "flag_values": np.arange(len(BINDING), dtype=np.int8),
             "flag_meanings": " ".join(b.replace(" ", "_") for b in BINDING)}),
         "psi": ((*dims, "leg"), psi, {
             "units": "degree", "long_name": "crank angles of the admissible pose at "
                                             "max_tilt"})},
        coords={"cranks": ("cranks", list(CRANKS), {"description": "free: searched crank "
                                                    "angles; locked: the home angles"}),
                "torsion": ("torsion", np.asarray(st.torsions_deg, dtype=float),
                            {"units": "degree", "long_name": "rotation about the platform "
                             "normal, applied before the tilt"}),
                "azimuth": ("azimuth", st.azimuths_deg,
                            {"units": "degree", "long_name": "tilt-axis azimuth from +x"}),
                "x": ("x", np.asarray(xs), {"units": "m"}),
                "y": ("y", np.asarray(ys), {"units": "m"}),
                "z": ("z", np.asarray(zs), {"units": "m", "long_name": "platform centre "
                                            "height above the base"}),
                "leg": ("leg", np.arange(3))},
        attrs={"title": "sixplus3 orientation-workspace atlas",
               "software": software,
               "robot_name": robot.name, "robot_hash": robot.hash,
               "robot_mode": robot.mode.name, "home_position_m": list(robot.home_position),
               "home_psi_deg": np.degrees(robot.home_psi).tolist(),
               "limit_torque_Nm": robot.limits.torque,
               "limit_margin": robot.limits.margin,
               "limit_spherical_deg": math.degrees(robot.limits.spherical),
               "limit_theta_deg": [math.degrees(robot.limits.theta_min),
                                   math.degrees(robot.limits.theta_max)],
               "payload_kg": robot.payload.mass,
               "gravity": list(robot.gravity),
               "step_m": st.step, "azimuth_step_deg": st.azimuth_step_deg,
               "max_tilt_deg": st.max_tilt_deg, "scan_deg": st.scan_deg,
               "resolution_deg": st.resolution_deg, "psi_step_deg": st.psi_step_deg,
               "accel_g": st.accel_g,
               "torque_check": (f"the platform accelerates at {st.accel_g:g} g in every "
                                "direction from rest within limit_torque_Nm"
                                if st.accel_g > 0 else "static holding torque within "
                                "limit_torque_Nm"),
               "psi_range_deg": list(PSI_RANGE_DEG),
               "positions": npos, "wall_time_s": round(wall, 3),
               "workers": workers if workers is not None else "external scheduler",
               "definitions": "see sixplus3.design.atlas and docs/atlas.md"})
    return ds


# --------------------------------------------------------------------- summaries
def all_directions(ds: xr.Dataset) -> xr.DataArray:
    """Smallest over the azimuths of the largest tilt [deg]: how far the platform tilts
    in *every* direction (NaN outside the zero-tilt workspace)."""
    return ds["max_tilt"].min("azimuth", skipna=False)


def volumes(ds: xr.Dataset, thresholds_deg: ArrayLike = THRESHOLDS_DEG) -> dict[str, Any]:
    """{cranks: {torsion: {threshold: litres}}}: volume of the positions where every
    direction tilts at least each threshold (each grid cell counts step^3)."""
    step = float(ds.attrs["step_m"])
    alld = all_directions(ds)
    out: dict[str, Any] = {}
    for c in ds["cranks"].values.tolist():
        out[c] = {}
        for t in ds["torsion"].values.tolist():
            a = alld.sel(cranks=c, torsion=t).values
            row: dict[str | float, float] = {
                "zero tilt": float(np.isfinite(a).sum()) * step**3 * 1e3}
            for th in np.atleast_1d(np.asarray(thresholds_deg, dtype=float)).tolist():
                row[float(th)] = float((np.nan_to_num(a, nan=-1.0) >= th).sum()) * step**3 * 1e3
            out[c][float(t)] = row
    return out


def headline(ds: xr.Dataset, threshold_deg: float = 45.0) -> str:
    """One sentence: the volume where every direction tilts >= threshold, free vs locked
    (at zero torsion, or the first torsion)."""
    v = volumes(ds, (threshold_deg,))
    t = 0.0 if 0.0 in v["free"] else next(iter(v["free"]))
    return (f"with the cranks free, the platform tilts >= {threshold_deg:g} deg in every "
            f"direction over {v['free'][t][float(threshold_deg)]:.2f} L of workspace; "
            f"locked at home, {v['locked'][t][float(threshold_deg)]:.2f} L "
            f"(torsion {t:g} deg, {ds.attrs['step_m'] * 100:g} cm grid, "
            f"{ds.attrs['azimuth_step_deg']:g} deg directions)")


# --------------------------------------------------------------------- files and pictures
def save(ds: xr.Dataset, path: str | Path) -> Path:
    """Write the atlas as NetCDF-4 (h5netcdf) atomically: a temporary file renamed."""
    path = Path(path)
    if not path.parent.is_dir():
        raise InputError(f"output directory {str(path.parent)!r} does not exist",
                         value=str(path.parent), valid="an existing directory")

    atomic_write_with(path, lambda tmp: ds.to_netcdf(tmp, engine="h5netcdf"))
    return path


def load(path: str | Path) -> xr.Dataset:
    # deferred: xarray (optional) loads only when this runs
    import xarray as xr

    return xr.load_dataset(path, engine="h5netcdf")


def figures(ds: xr.Dataset, out_dir: str | Path, robot: Robot | None = None,
            polar: dict[str, Any] | None = None, layers: int = 6) -> list[Path]:
    """Per-layer maps of the all-direction tilt (free vs locked), the volume-vs-tilt
    curve, and the polar plot at home (``polar`` from :func:`home_polar`)."""
    # deferred: matplotlib loads only when this runs
    import matplotlib

    matplotlib.use("Agg")
    # deferred: matplotlib loads only when this runs
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    paths = []
    g = float(ds.attrs.get("accel_g", 0.0))
    dyn = f", accelerating at {g:g} g" if g > 0 else ""  # the optional torque criterion
    alld = all_directions(ds).isel(torsion=0)
    zs = ds["z"].values
    filled = [k for k in range(len(zs)) if np.isfinite(alld.isel(z=k).values).any()]
    pick = [filled[i] for i in np.unique(np.linspace(0, len(filled) - 1,
                                                     min(layers, len(filled))).astype(int))]
    if pick:
        fig, axes = plt.subplots(len(pick), 2, figsize=(8, 3.2 * len(pick)), squeeze=False)
        ext = [ds["x"].values[0], ds["x"].values[-1], ds["y"].values[0], ds["y"].values[-1]]
        vmax = float(np.nanmax(alld.values)) if np.isfinite(alld.values).any() else 90.0
        im = None
        for r, k in enumerate(pick):
            for c, mode in enumerate(CRANKS):
                ax = axes[r, c]
                a = alld.sel(cranks=mode).isel(z=k).values.T
                im = ax.imshow(a, origin="lower", extent=ext, vmin=0, vmax=vmax,
                               cmap="viridis", aspect="equal")
                ax.set_title(f"{mode}, z = {zs[k]:.2f} m", fontsize=9)
                ax.set_xlabel("x [m]")
                ax.set_ylabel("y [m]")
        # room on the right for the colour bar (its own axes: it covers no panel) and at
        # the top for the title (above the first row's panel titles)
        height = 3.2 * len(pick)
        fig.subplots_adjust(hspace=0.45, right=0.84, top=1 - 0.9 / height,
                            bottom=0.5 / height)
        if im is not None:
            cax = fig.add_axes((0.88, 0.5 / height + 0.05, 0.025, 0.8 - 1.4 / height))
            fig.colorbar(im, cax=cax, label="tilt in every direction [deg]")
        fig.suptitle(f"Largest tilt reached in every direction (min over azimuths){dyn}",
                     y=1 - 0.25 / height)
        paths.append(Path(save_figure(fig, out / "atlas_layers.png", dpi=110, tight=True)))
    # volume vs threshold
    th = np.arange(0.0, float(ds.attrs["max_tilt_deg"]) + 1e-9, 5.0)
    v = volumes(ds, th)
    t0 = next(iter(v["free"]))
    fig, ax = plt.subplots(figsize=(6, 4))
    for mode in CRANKS:
        ax.plot(th, [v[mode][t0][float(x)] for x in th], label=f"cranks {mode}")
    ax.set_xlabel("tilt reached in every direction [deg]")
    ax.set_ylabel("workspace volume [L]")
    if dyn:
        ax.set_title(dyn[2:].capitalize(), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend()
    paths.append(Path(save_figure(fig, out / "atlas_volumes.png", dpi=110, tight=True)))
    if polar is not None:
        fig = plt.figure(figsize=(5, 5))
        ax = fig.add_subplot(projection="polar")
        a = np.radians(np.r_[polar["azimuth"], polar["azimuth"][:1]])
        for mode in CRANKS:
            ax.plot(a, np.r_[polar[mode], polar[mode][:1]], label=f"cranks {mode}")
        ax.set_title(f"Largest tilt [deg] per tilt-axis azimuth at home{dyn}", fontsize=10)
        ax.legend(loc="lower left", bbox_to_anchor=(0.8, -0.1))
        paths.append(Path(save_figure(fig, out / "atlas_home_polar.png", dpi=110, tight=True)))
    return paths


__all__ = ["BINDING", "CRANKS", "PSI_RANGE_DEG", "THRESHOLDS_DEG", "AtlasSettings",
           "all_directions",
           "build_dataset", "figures", "headline", "load", "position_grid", "save",
           "volumes"]
