"""The ``sixplus3 simulate`` command: a trajectory file replayed in MuJoCo (feed-forward
+ PD), on the model or a virtual prototype (``--plant``, ``--log``), with the contact
guard and a person (``--guard``, ``--contact``: :mod:`~sixplus3.cli.contact`), or a
simulated hand guiding the platform (``--lead``)."""

from __future__ import annotations

import json
import math
import os
import sys
from typing import Any

import click

from sixplus3.cli.app import (
    FLOAT,
    INT,
    check_output,
    drive_gains,
    fail,
    main,
    task_robot,
)


@main.command()
@click.argument("csv_file", type=click.Path(dir_okay=False), required=False)
@click.option("--task", "task_file", default=None, type=click.Path(dir_okay=False),
              help="Apply this task file's setup (payload, tool, mounting) to the robot.")
@click.option("--lead", "lead_file", default=None, type=click.Path(dir_okay=False),
              help="With --plant and --log, no FILE: a simulated hand (YAML) guides the "
                   "platform, lead-through in the loop (docs/leadthrough.md).")
@click.option("--ff-scale", default=1.0, show_default=True, type=FLOAT,
              help="Scale the feed-forward torques by this factor, in [0, 2].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--torque-hold", type=click.Choice(["sample", "mean"]), default="mean",
              show_default=True,
              help="Feed-forward held over each tick: the 'mean' of both ends' torques, "
                   "or the 'sample''s own.")
@click.option("--plant", "plant_file", default=None, type=click.Path(dir_okay=False),
              help="Run the file on this robot file instead (a virtual prototype whose "
                   "masses, inertias and friction differ: docs/identification.md).")
@click.option("--log", "log_file", default=None, type=click.Path(dir_okay=False),
              help="With --plant: write the drives' log here (encoder and torque "
                   "quantised, seeded noise).")
@click.option("--seed", default=0, show_default=True, type=INT,
              help="With --plant: the seed of the torque monitor's noise.")
@click.option("--noise", default=0.005, show_default=True, type=FLOAT,
              help="With --plant: the torque monitor's noise, one standard deviation "
                   "[N m at the joint].")
@click.option("--hold", default=0.0, show_default=True, type=FLOAT,
              help="With --plant: keep holding the last sample this long [s].")
@click.option("--wrench", "wrench_file", default=None, type=click.Path(dir_okay=False),
              help="With --plant: an external wrench on the platform over time (CSV "
                   "t,fx,fy,fz,mx,my,mz; base frame, about the platform centre).")
@click.option("--guard", "guard", is_flag=True,
              help="With --plant: the contact guard in the loop (docs/safety.md).")
@click.option("--contact", "contact_file", default=None, type=click.Path(dir_okay=False),
              help="With --plant: a person in the way (YAML: region, kind free|clamp, at "
                   "[s], normal, point tcp|centre|a leg link such as leg0_Ds2; "
                   "docs/safety.md).")
@click.option("--reaction", type=click.Choice(["hold", "yield"]), default="hold",
              show_default=True,
              help="With --guard: after a stop, hold the pose or yield (a compliant hold).")
@click.option("--parameters", "parameters_file", default=None,
              type=click.Path(dir_okay=False),
              help="With --guard: an identification's parameters.npz; its confidence "
                   "enters the guard's thresholds.")
@click.option("--force", is_flag=True, help="Replace an existing --log file.")
@drive_gains
def simulate(csv_file: str | None, task_file: str | None, lead_file: str | None,
             ff_scale: float, as_json: bool,
             torque_hold: str, plant_file: str | None, log_file: str | None, seed: int,
             noise: float, hold: float, wrench_file: str | None, guard: bool,
             contact_file: str | None, reaction: str, parameters_file: str | None,
             force: bool, kp: float, kd: float) -> None:
    """Replay a trajectory file in MuJoCo at its rate: feed-forward + PD.

    The file is validated first (a defective file is not simulated: exit 2).  Reports
    the tracking error, the PD share of the torque and the peak total torque; exit 1 if
    that peak is over the hardware limit.  With --plant, the file runs on that robot (a
    virtual prototype) and --log writes what its drives measured; --lead HAND.yaml
    (no FILE) runs lead-through there instead, a simulated hand guiding the platform.
    """
    from sixplus3.control.drive.simulation import simulate_file

    robot = task_robot(task_file)
    if lead_file is not None or csv_file is None:
        from sixplus3.cli.contact import simulate_lead

        simulate_lead(csv_file, lead_file, robot, plant_file, log_file, seed, noise, force,
                      kp, kd, as_json)
        return
    if guard or contact_file is not None:
        from sixplus3.cli.contact import simulate_contact

        simulate_contact(csv_file, robot, plant_file, log_file, contact_file, guard, seed,
                         noise, hold, force, kp, kd, as_json, reaction, parameters_file)
        return
    if parameters_file is not None:
        fail("--parameters goes with --guard")
    if plant_file is not None or log_file is not None or wrench_file is not None:
        _simulate_plant(csv_file, robot, plant_file, log_file, seed, noise, hold, force,
                        kp, kd, as_json, wrench_file)
        return
    rep, sim = simulate_file(csv_file, robot, kp, kd, ff_scale, torque_hold)
    if sim is None:
        what = "is not a valid motion" if rep.exit_code == 2 else "violates a limit"
        click.echo(f"refused: {csv_file} {what} (the gate's verdict; nothing simulated): "
                   + "; ".join(rep.messages())[:1500], err=True)
        sys.exit(rep.exit_code or 2)
    assert sim is not None
    if as_json:
        click.echo(json.dumps(sim.summary()))
    else:
        click.echo(f"{csv_file}: {sim.samples} ticks at {sim.rate_hz:g} Hz, Kp {kp:g}, "
                   f"Kd {kd:g}, feed-forward x{ff_scale:g} held per tick as "
                   f"'{sim.torque_hold}'; MuJoCo step {sim.timestep_s * 1e3:g} ms "
                   "(implicitfast)")
        click.echo(f"  tracking error: max {math.degrees(sim.max_tracking_error_rad):.4f} "
                   f"deg, rms {math.degrees(sim.rms_tracking_error_rad):.4f} deg, final "
                   f"{math.degrees(sim.final_tracking_error_rad):.4f} deg")
        click.echo(f"  PD share {100 * sim.pd_share:.2f}% (max |tau_PD| "
                   f"{sim.max_pd_torque:.3f} N m); peak |tau| commanded at the ticks "
                   f"{sim.peak_total_torque:.3f} N m "
                   f"(limit {sim.torque_limit:g}); closure residual "
                   f"{sim.max_closure_residual_m:.1e} m")
    sys.exit(0 if sim.within_torque_limit else 1)


def _simulate_plant(csv_file: str, robot: Any, plant_file: str | None,
                    log_file: str | None,
                    seed: int, noise: float, hold: float, force: bool, kp: float,
                    kd: float, as_json: bool, wrench_file: str | None = None) -> None:
    from sixplus3.control.drive.plant import run_on_plant
    from sixplus3.control.file.drive_log import write_log
    from sixplus3.robot_description.robot import load_robot

    if plant_file is None or log_file is None:
        fail("--plant and --log go together (the plant's run is what the log records)")
        return
    check_output(log_file, (csv_file, plant_file))
    if os.path.exists(log_file) and not force:
        fail(f"{log_file} exists: add --force to replace it")
    plant = load_robot(plant_file)
    profile = None
    if wrench_file is not None:
        from sixplus3.control.drive.plant import read_wrench_profile

        profile = read_wrench_profile(wrench_file)
    run = run_on_plant(csv_file, robot, plant, seed=seed, kp=kp, kd=kd, torque_noise=noise,
                       hold=hold, wrench=profile)
    write_log(log_file, run.log, robot, {"plant": plant.name, "plant_hash": plant.hash,
                                         "seed": seed, "torque_noise_n_m": noise,
                                         "source": os.path.basename(csv_file)})
    out = {"log": log_file, "samples": len(run.log.t), "peak_torque_n_m": run.peak_torque,
           "torque_limit_n_m": run.torque_limit, "within_limit": not run.saturated,
           "max_tracking_error_rad": run.max_tracking_error_rad}
    if as_json:
        click.echo(json.dumps(out))
    else:
        click.echo(f"{csv_file} on plant {plant.name}: {len(run.log.t)} ticks logged to "
                   f"{log_file}; peak |tau| applied {run.peak_torque:.3f} N m (limit "
                   f"{run.torque_limit:g}{', EXCEEDED' if run.saturated else ''}); "
                   f"tracking error max {math.degrees(run.max_tracking_error_rad):.4f} deg")
    sys.exit(1 if run.saturated else 0)
