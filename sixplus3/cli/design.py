"""The ``sixplus3`` design commands: ``design optimize | layout | figures``, ``report`` and
``atlas``."""

from __future__ import annotations

import json
import math
from typing import Any

import click

from sixplus3.cli.app import FLOAT, INT, bars, current_robot, fail, main, verbosity
from sixplus3.cli.names import READINGS


@main.group()
def design() -> None:
    """Optimal leg design and workspace (paper §V)."""


def _reading_option(f: Any) -> Any:
    return click.option("--reading", default="paper-mirror", show_default=True,
                        help="Reading of the paper's conventions (see docs/design.md): "
                        "one of " + ", ".join(READINGS))(f)


def _reading(name: str) -> Any:
    from sixplus3.design import readings

    if name not in readings.READINGS:
        fail(f"unknown reading {name!r}: choose one of {', '.join(sorted(readings.READINGS))}")
    return readings.READINGS[name]


@design.command("optimize")
@click.option("--coarse-step", default=0.01, show_default=True, type=FLOAT,
              help="Stage-1 grid of the design variables [m].")
@click.option("--fine-step", default=0.001, show_default=True, type=FLOAT,
              help="Stage-2 grid around the best coarse design [m].")
@click.option("--ws-step", "ws_steps", default=(0.01, 0.005, 0.0025), show_default=True,
              type=FLOAT, multiple=True,
              help="Workspace grid of the half-plane [m]; repeat to re-optimise on each.")
@_reading_option
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object per grid.")
@verbosity
def design_optimize(coarse_step: float, fine_step: float, ws_steps: tuple[float, ...],
                    reading: str, as_json: bool) -> None:
    """Two-stage grid search of (l2 = l3, l4 = l5, ex = fx) maximising the usable area,
    re-run on every workspace grid, with the ridge of near-optimal designs."""
    from sixplus3.design.search import PAPER_DESIGN, check_steps, optimize

    rd = _reading(reading)
    # every grid before the first search: no partial output for a bad one (InputError)
    check_steps(coarse_step, fine_step, *ws_steps)
    if not as_json:
        click.echo(f"reading '{rd.name}': {rd.description}")
        click.echo(f"paper        l2 = {PAPER_DESIGN[0]:.3f}  l4 = {PAPER_DESIGN[1]:.3f}  "
                   f"ex = {PAPER_DESIGN[2]:.3f} m")
    for ws_step in ws_steps:
        res = optimize(coarse_step, fine_step, ws_step, rd, progress=bars() and not as_json)
        rg = res.ridge
        if as_json:
            out = {"found": res.found, "l2": res.l2, "l4": res.l4, "ex": res.ex,
                   "area_m2": res.area_m2, "paper_design_area_m2": res.paper_design_area_m2,
                   "evaluations": res.evaluations, "point_evaluations": res.point_evaluations,
                   "seconds": res.seconds, "reading": rd.name, "ws_step": ws_step,
                   "ridge": None if rg is None else {
                       "tolerance": rg.tolerance, "count": rg.count, "l2": rg.l2,
                       "l4": rg.l4, "ex": rg.ex, "l2_over_ex": rg.l2_over_ex},
                   "local_optima": [dict(zip(("l2", "l4", "ex", "area_m2"), v, strict=True))
                                    for v in res.local_optima]}
            click.echo(json.dumps(out, default=lambda x: None))
            continue
        click.echo(f"grid {ws_step * 1000:g} mm:")
        if res.found:
            click.echo(f"  optimum    l2 = {res.l2:.3f}  l4 = {res.l4:.3f}  ex = {res.ex:.3f} m"
                       f"   area {res.area_m2:.5f} m^2")
        else:
            click.echo("  optimum    none: no feasible design has a counted point")
        click.echo(f"  paper's design: area {res.paper_design_area_m2:.5f} m^2 (our model)")
        for v in res.local_optima:
            if (v[0], v[1], v[2]) == (res.l2, res.l4, res.ex):
                continue
            click.echo(f"  also       l2 = {v[0]:.3f}  l4 = {v[1]:.3f}  ex = {v[2]:.3f} m   "
                       f"area {v[3]:.5f} m^2 (refined from another coarse seed)")
        if rg is not None:
            click.echo(f"  ridge      {rg.line()}")
        click.echo(f"  {res.evaluations} designs ({res.feasible_designs} feasible), "
                   f"{res.point_evaluations:,} point evaluations in {res.seconds:.1f} s")


@design.command("layout")
@click.option("--turns", default="0:45:2.5", show_default=True, metavar="START:STOP:STEP",
              help="Axis turns gamma to sweep [deg].")
@click.option("--phases", default="-20:20:10", show_default=True, metavar="START:STOP:STEP",
              help="Platform phase offsets to sweep [deg], from the robot's own phase.")
@click.option("--step", default=0.02, show_default=True, type=FLOAT,
              help="COW grid pitch, x, y and z [m].")
@click.option("--legs", type=click.Choice(["both", "paper", "other-basin"]), default="both",
              show_default=True, help="Which §V legs to study.")
@click.option("--out", "out_dir", default="layout", show_default=True,
              type=click.Path(file_okay=False), help="Output directory (table, figure).")
@click.option("--workers", default=2, show_default=True, type=INT,
              help="LocalCluster worker processes (1-4).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="A Dask scheduler address (tcp://host:8786), or 'synchronous'.")
def design_layout(turns: str, phases: str, step: float, legs: str, out_dir: str,
                  workers: int, scheduler: str | None) -> None:
    """The whole-robot layout study: the paper's leg in its §V assembly, the
    interference-free 2 g COW against the axis turn and the platform phase (docs/design.md,
    "Layout").  The base robot is --robot's (default: the built robot) with its own
    layout replaced by each of the sweep's."""
    from pathlib import Path

    from sixplus3 import fileio
    from sixplus3.design import layout as lay
    from sixplus3.design.cluster import check_scheduler, check_workers

    st = lay.LayoutSettings(turns_deg=_sweep("--turns", turns),
                            phases_deg=_sweep("--phases", phases), step=step,
                            z_step=step).check()
    check_workers(workers)
    check_scheduler(scheduler)
    base = current_robot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    which = ("paper", "other-basin") if legs == "both" else (legs,)
    n = len(st.turns_deg) * len(st.phases_deg) * len(which)
    where = f"LocalCluster of {workers} workers" if scheduler is None else scheduler
    click.echo(f"layout study: {n} layouts, COW grid {step * 100:g} cm; {where}")
    study = lay.layout_study(base, st, which, scheduler=scheduler, workers=workers,
                             progress=bars())
    click.echo(study.report())
    table = out / "layout.json"
    fileio.atomic_write(table, json.dumps(
        {"robot": base.as_dict(), "settings": {"turns_deg": list(st.turns_deg),
                                               "phases_deg": list(st.phases_deg),
                                               "step_m": st.step},
         "points": [p.as_dict() for p in study.points]}, indent=1,
        default=lambda x: None).encode() + b"\n")
    fig = out / "layout_volume.png"
    lay.plot_study(study, fig)
    click.echo(f"wrote {table}\nwrote {fig}")


def _sweep(name: str, text: str) -> tuple[float, ...]:
    """START:STOP:STEP (inclusive) or one number [deg], as a tuple; bad text exits 2."""
    parts = str(text).split(":")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        fail(f"{name} must be START:STOP:STEP or one number [deg], got {text[:40]!r}")
    if len(vals) == 1:
        vals = [vals[0], vals[0], 1.0]
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals) or vals[2] <= 0 \
            or vals[1] < vals[0] or (vals[1] - vals[0]) / vals[2] > 400:
        fail(f"{name} must be START:STOP:STEP with START <= STOP, STEP > 0 and at most "
             f"400 values [deg], got {text[:40]!r}")
    n = int(math.floor((vals[1] - vals[0]) / vals[2] + 1e-9)) + 1
    return tuple(round(vals[0] + k * vals[2], 9) for k in range(n))


@design.command("figures")
@click.option("--out", "out_dir", default="figures", show_default=True,
              type=click.Path(file_okay=False), help="Output directory.")
@_reading_option
@click.option("--ws-step", default=0.0025, show_default=True, type=FLOAT,
              help="Half-plane grid of the leg figures [m].")
def design_figures(out_dir: str, reading: str, ws_step: float) -> None:
    """Write the §V figures (det J/K, tau_ext, COW, encoder resolution) as PNG."""
    from sixplus3.design.figures import make_figures

    if not (math.isfinite(ws_step) and 0.0005 <= ws_step <= 0.05):
        fail(f"--ws-step must be in [0.0005, 0.05] m, got {ws_step!r}")
    rd = _reading(reading)
    s = make_figures(out_dir, rd, ws_step=ws_step)
    robot = current_robot()
    click.echo(f"figures of the paper's leg design (l2, l4, ex) = {s.design} in the reading "
               f"'{rd.name}' (mode {rd.mode}, ey = {rd.ey:g} m): the paper's figures, not the "
               f"robot in use ({robot.name}: mode {robot.mode.name}, ey = {robot.leg.ey:g} m); "
               "'sixplus3 report' gives that robot's own design objective")
    for f in s.files:
        click.echo(f"wrote {f}")
    click.echo(f"counted area {s.counted_area_m2:.4f} m^2; COW projected area / footprint: "
               + ", ".join(f"{k} {v:.2f}" for k, v in s.cow_ratios.items())
               + f" (paper {s.paper_cow_ratio}); worst encoder resolution "
               f"{s.worst_resolution_m:.2e} m (paper {s.paper_resolution_m:.1e} m)")


@main.command()
@click.option("--ws-step", default=0.005, show_default=True, type=FLOAT,
              help="Workspace grid step of the usable-area report [m].")
def report(ws_step: float) -> None:
    """A report of the robot's leg design (sample configurations, usable area)."""
    from sixplus3.design.report import leg_report

    click.echo(leg_report(current_robot(), ws_step=ws_step))


@main.command()
@click.option("-o", "--out", "out_dir", default="out/atlas", show_default=True,
              type=click.Path(file_okay=False), help="Output directory (atlas.nc, PNGs).")
@click.option("--step", default=0.02, show_default=True, type=FLOAT,
              help="Position grid step [m].")
@click.option("--azimuth-step", default=15.0, show_default=True, type=FLOAT,
              help="Tilt-direction step [deg] (tilt-axis azimuths 0..360).")
@click.option("--torsion", "torsions", multiple=True, type=FLOAT,
              help="Torsion angle [deg] (repeat for several; default 0).")
@click.option("--max-tilt", default=180.0, show_default=True, type=FLOAT,
              help="Largest tilt searched [deg].")
@click.option("--resolution", default=1.0, show_default=True, type=FLOAT,
              help="Bisection resolution of the tilt [deg].")
@click.option("--z", "z_range", nargs=2, type=FLOAT, default=None,
              help="Only heights in [ZMIN, ZMAX] [m] (default: the reachable region).")
@click.option("--workers", default=2, show_default=True, type=INT,
              help="Dask LocalCluster worker processes (one thread each).")
@click.option("--scheduler", default=None,
              help="A Dask scheduler address (tcp://host:8786) instead of a LocalCluster; "
              "'synchronous' runs in this process.")
@click.option("--chunk", default=48, show_default=True, type=INT,
              help="Positions per Dask task.")
@click.option("--accel-g", default=0.0, show_default=True, type=FLOAT,
              help="Dynamic criterion: the platform must also accelerate at this many g "
              "in every direction from rest within the torque limit (0: static only).")
@click.option("--no-figures", is_flag=True, help="Write only the data file.")
@verbosity
def atlas(out_dir: str, step: float, azimuth_step: float, torsions: tuple[float, ...],
          max_tilt: float, resolution: float, z_range: tuple[float, float] | None,
          workers: int, scheduler: str | None, chunk: int, accel_g: float,
          no_figures: bool) -> None:
    """The orientation-workspace atlas: the largest tilt in every direction at every
    position, cranks free vs locked (NetCDF + maps; docs/atlas.md)."""
    import time
    from pathlib import Path

    import numpy as np

    from sixplus3.design import atlas as at
    from sixplus3.design import atlas_data as ad
    from sixplus3.design import cluster

    try:
        import dask.distributed  # noqa: F401
        import h5netcdf  # noqa: F401
        import xarray  # noqa: F401
    except ImportError as exc:
        fail(f"the atlas needs the 'atlas' extra ({exc.name} is missing): "
             "pip install 'sixplus3[atlas]' (make install includes it)")
    st = ad.AtlasSettings(step=step, azimuth_step_deg=azimuth_step,
                          torsions_deg=tuple(torsions) or (0.0,), max_tilt_deg=max_tilt,
                          resolution_deg=resolution, accel_g=accel_g).check()
    at.check_run(workers, chunk)
    cluster.check_scheduler(scheduler)
    robot = current_robot()
    xs, ys, zs = ad.position_grid(robot, st.step, z_range)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    npos = len(xs) * len(ys) * len(zs)
    where = f"LocalCluster of {workers} workers" if scheduler is None else scheduler
    click.echo(f"atlas of {robot.name}: {npos} positions ({len(xs)} x {len(ys)} x {len(zs)},"
               f" {st.step * 100:g} cm) x {len(st.azimuths_deg)} directions x "
               f"{len(st.torsions_deg)} torsion(s), cranks free and locked; {where}")
    t0 = time.perf_counter()
    ds = at.compute_atlas(robot, st, scheduler=scheduler, workers=workers, chunk=chunk,
                          grid=(xs, ys, zs), progress=bars())
    path = ad.save(ds, out / "atlas.nc")
    click.echo(f"wrote {path} ({time.perf_counter() - t0:.1f} s)")
    if not no_figures:
        polar = at.home_polar(robot, st)
        for f in ad.figures(ds, out, robot, polar):
            click.echo(f"wrote {f}")
        click.echo("at home, largest tilt over directions: free "
                   f"{np.nanmin(polar['free']):.1f} deg (min) .. {np.nanmax(polar['free']):.1f}"
                   f" (max); locked {np.nanmin(polar['locked']):.1f} .. "
                   f"{np.nanmax(polar['locked']):.1f} deg")
    vol = ad.volumes(ds)
    t = next(iter(vol["free"]))
    click.echo("volume where every direction tilts at least [L]: "
               + "; ".join(f"{k:g} deg: free {vol['free'][t][k]:.2f}, locked "
                           f"{vol['locked'][t][k]:.2f}" for k in ad.THRESHOLDS_DEG)
               + f" (zero-tilt workspace: free {vol['free'][t]['zero tilt']:.2f}, locked "
               f"{vol['locked'][t]['zero tilt']:.2f})")
    click.echo(ad.headline(ds))
