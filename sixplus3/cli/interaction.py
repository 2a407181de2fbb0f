"""The ``sixplus3 wrench`` and ``wrench-resolution`` commands (docs/interaction.md)."""

from __future__ import annotations

import json
from typing import Any

import click

from sixplus3.cli.app import (
    FLOAT,
    check_output,
    check_png,
    current_robot,
    emit,
    json_default,
    main,
    request_fast_exit,
)


@main.command()
@click.argument("log", type=click.Path())
@click.option("-o", "--out", "out_file", default=None, type=click.Path(dir_okay=False),
              help="Write the wrench CSV here (t, fx, fy, fz, mx, my, mz, their standard "
                   "deviations and friction bands, the crank residual, the contact flag).")
@click.option("--at", "at", type=click.Choice(["centre", "tcp"]), default="centre",
              show_default=True, help="Reduce the wrench to the platform centre or the TCP.")
@click.option("--gain", default=150.0, show_default=True, type=FLOAT,
              help="The momentum observer's gain [1/s] (95 % of a step in 3/gain s).")
@click.option("--noise", default=0.005, show_default=True, type=FLOAT,
              help="The torque monitor's noise, one standard deviation [N m].")
@click.option("--model-sigma", default=0.01, show_default=True, type=FLOAT,
              help="The model's torque error, one standard deviation [N m per joint].")
@click.option("--plot", "plot_file", default=None, type=click.Path(dir_okay=False),
              help="A PNG of the wrench over time with its uncertainty band.")
@click.option("--parameters", "parameters_file", default=None,
              type=click.Path(dir_okay=False),
              help="An identification's parameters.npz (identify estimate --report DIR): "
                   "the parameters' confidence enters each sample's uncertainty.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def wrench(log: str, out_file: str | None, at: str, gain: float, noise: float,
           model_sigma: float, plot_file: str | None, parameters_file: str | None,
           as_json: bool) -> None:
    """The wrench a person applies to the platform, from a drive log alone (a momentum
    observer on the closed-loop dynamics; the direct residual for comparison)."""
    request_fast_exit()
    from sixplus3.control.file.drive_log import read_log
    from sixplus3.interaction.observer.wrench import estimate

    check_output(out_file, (log,))
    check_png(plot_file, "--plot")
    check_output(plot_file, (log,))
    robot = current_robot()
    cov = None
    if parameters_file is not None:
        cov = _load_parameters(parameters_file)
    est = estimate(read_log(log, robot), robot, gain=gain, at=at, monitor_noise=noise,
                   model_sigma=model_sigma, parameter_cov=cov)
    if out_file is not None:
        emit(_csv(est), out_file, (log,))
    if plot_file is not None:
        _plot(est, plot_file, robot.name)
    summary = {"log": log, "robot": robot.name, **est.summary()}
    if as_json:
        click.echo(json.dumps(summary, default=json_default))
        return
    click.echo(f"{log}: wrench at the platform {'centre' if at == 'centre' else 'TCP'} over "
               f"{len(est.t)} samples; max |f| {summary['max_force_n']:.3f} N, max |m| "
               f"{summary['max_moment_n_m']:.4f} N m; contact in "
               f"{summary['contact_samples']} samples")
    s, b = summary["median_std"], summary["max_friction_band"]
    click.echo("  standard deviation (median) f " + " ".join(f"{x:.3f}" for x in s[:3])
               + " N, m " + " ".join(f"{x:.4f}" for x in s[3:]) + " N m")
    click.echo("  dry friction band at rest (up to) f " + " ".join(f"{x:.3f}" for x in b[:3])
               + " N, m " + " ".join(f"{x:.4f}" for x in b[3:]) + " N m: a hold cannot "
               "feel less than this")
    click.echo(f"  crank residual up to {summary['max_crank_residual_n_m']:.4f} N m (a model "
               "error or a force on a crank)")


def _load_parameters(path: str) -> Any:
    import io

    import numpy as np

    from sixplus3.errors import InputError
    from sixplus3.fileio import read_bytes

    try:
        with np.load(io.BytesIO(read_bytes(path, "parameters file", 64 << 20)),
                     allow_pickle=False) as z:
            return np.array(z["index"]), np.array(z["cov"])
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{path} is not an identification's parameters.npz "
                         f"({type(exc).__name__})", value=path,
                         valid="identify estimate --report DIR's parameters.npz") from None


def _csv(est: Any) -> str:
    cols = ["t", "fx", "fy", "fz", "mx", "my", "mz"]
    head = cols + [f"std_{c}" for c in cols[1:]] + [f"band_{c}" for c in cols[1:]] + \
        ["crank0", "crank1", "crank2", "contact"]
    lines = [f"# sixplus3 wrench: {est.at}, base frame, N and N m; " + "; ".join(est.notes),
             ",".join(head)]
    for k in range(len(est.t)):
        row = [est.t[k], *est.wrench[k], *est.std[k], *est.band[k], *est.crank[k]]
        lines.append(",".join(repr(float(x)) for x in row) + f",{int(est.contact[k])}")
    return "\n".join(lines) + "\n"


def _plot(est: Any, path: str, name: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sixplus3.fileio import save_figure

    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    colors = ("tab:red", "tab:green", "tab:blue")
    for row, (lo, unit) in enumerate(((0, "N"), (3, "N m"))):
        ax = axes[row]
        for k in range(3):
            c = lo + k
            lab = ("f" if row == 0 else "m") + "xyz"[k]
            ax.plot(est.t, est.wrench[:, c], color=colors[k], lw=1, label=lab)
            half = 4 * est.std[:, c] + est.band[:, c]
            ax.fill_between(est.t, est.wrench[:, c] - half, est.wrench[:, c] + half,
                            color=colors[k], alpha=0.15, lw=0)
        ax.set_ylabel(f"[{unit}]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    on = est.contact
    axes[0].fill_between(est.t, 0, 1, where=on, transform=axes[0].get_xaxis_transform(),
                         color="k", alpha=0.07, lw=0)
    axes[1].set_xlabel("t [s]")
    fig.suptitle(f"{name}: external wrench at the platform {est.at} (shaded: 4 std + dry "
                 "friction band; grey: contact)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)


@main.command("wrench-resolution")
@click.option("-o", "--out", "out_file", required=True, type=click.Path(dir_okay=False),
              help="The map (PNG).")
@click.option("--step", default=0.01, show_default=True, type=FLOAT, help="Grid step [m].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def wrench_resolution(out_file: str, step: float, as_json: bool) -> None:
    """The smallest force the robot can feel, at home and over the constant-orientation
    workspace at the home height (a map), at rest and while moving."""
    import numpy as np

    from sixplus3.errors import InputError
    from sixplus3.interaction.observer.resolution import plot_resolution_map, resolution

    if not 0.002 <= step <= 0.05:
        raise InputError(f"--step must be in [0.002, 0.05] m, got {step:g}", value=step,
                         valid="[0.002, 0.05] m")
    check_png(out_file, "-o")
    robot = current_robot()
    home = resolution(robot, robot.home_position)
    stats = plot_resolution_map(robot, out_file, step=step)
    out = {"home_at_rest": home.at_rest.tolist(), "home_moving": home.moving.tolist(),
           "map": stats, "file": out_file}
    if as_json:
        click.echo(json.dumps(out, default=json_default))
        return
    click.echo(f"at home, at rest: f {np.round(home.at_rest[:3], 3).tolist()} N, m "
               f"{np.round(home.at_rest[3:], 4).tolist()} N m; while moving: f "
               f"{np.round(home.moving[:3], 3).tolist()} N, m "
               f"{np.round(home.moving[3:], 4).tolist()} N m")
    click.echo(f"map {out_file}: {stats['points']} poses; at rest {stats['at_rest_n'][0]:.2f}"
               f"-{stats['at_rest_n'][2]:.2f} N (median {stats['at_rest_n'][1]:.2f}); "
               f"moving {stats['moving_n'][0]:.3f}-{stats['moving_n'][2]:.3f} N")


__all__ = ["wrench", "wrench_resolution"]


@main.command()
@click.argument("log", type=click.Path())
@click.option("-o", "--out", "out_file", required=True, type=click.Path(dir_okay=False),
              help="The task file (YAML) to write.")
@click.option("--pfl", "pfl", default=None, metavar="REGION[,REGION...]",
              help="The body regions the replay must be safe for (the task's pfl: power "
                   "and force limiting rows in the plan; docs/safety.md).")
@click.option("--people", default=None, type=click.Choice(["collaborative"]),
              help="Named platform limits for people in the task.")
@click.option("--stop", is_flag=True, help="Stop at each paused waypoint (default: pass "
                                           "through it).")
@click.option("--pause", default=0.3, show_default=True, type=FLOAT,
              help="A pause: the platform still at least this long [s].")
@click.option("--speed", default=0.005, show_default=True, type=FLOAT,
              help="Still: the tool point slower than this [m/s].")
@click.option("--force", is_flag=True, help="Replace an existing task file.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def teach(log: str, out_file: str, pfl: str | None, people: str | None, stop: bool,
          pause: float, speed: float, force: bool, as_json: bool) -> None:
    """Teach a task from a guided motion's drive LOG: the poses where the person paused
    become waypoints (cranks free), to be planned time-optimally under the site's limits
    for people: 'sixplus3 plan TASK' (docs/leadthrough.md)."""
    import os

    import yaml

    from sixplus3.control.file.drive_log import read_log
    from sixplus3.interaction.lead.teach import teach as teach_log
    from sixplus3.robot_description.body_regions import regions

    check_output(out_file, (log,), force)
    if os.path.exists(out_file) and not force:
        from sixplus3.cli.app import fail

        fail(f"{out_file} exists: add --force to replace it")
    robot = current_robot()
    names = tuple(r.name for r in regions(pfl)) if pfl is not None else ()
    if pfl is not None and not names:  # as plan --pfl '' refuses: never a silent no-PFL
        from sixplus3.cli.app import fail

        fail("--pfl names no body region")
    taught = teach_log(read_log(log, robot), robot, speed=speed, pause=pause)
    name = os.path.splitext(os.path.basename(out_file))[0] or "taught"
    doc = taught.task(name=name, stop=stop, pfl=names, people=people,
                      source=os.path.basename(log))
    text = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
    from sixplus3.fileio import atomic_write

    atomic_write(out_file, text.encode())
    out = {"task": out_file, "waypoints": len(taught.times),
           "pauses": int(taught.paused.sum()), "times_s": taught.times.tolist()}
    if as_json:
        click.echo(json.dumps(out))
    else:
        click.echo(f"{log}: {out['waypoints']} waypoints ({out['pauses']} pause(s)) written "
                   f"to {out_file}; plan it with 'sixplus3 plan {out_file}'")
