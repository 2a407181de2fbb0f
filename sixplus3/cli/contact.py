"""``sixplus3 simulate FILE --plant P --guard --contact C.yaml --log L``: a person in the
virtual prototype, the contact guard in the loop (docs/safety.md); ``sixplus3 simulate
--plant P --lead HAND.yaml --log L``: a hand guides the platform, lead-through in the
loop (docs/leadthrough.md)."""

from __future__ import annotations

import os
import sys
from typing import Any

import click

from sixplus3.cli.app import check_output, fail


def _stiffer_than_judged(kp: float, kd: float, person: bool) -> None:
    """Say so (stderr) when a person meets a drive stiffer than the loop the gate judged
    the contact with: the site's declared ``position_loop``, else the default drive
    (docs/safety.md, "The drive in the contact")."""
    from sixplus3.control.drive.loop import KD, KP  # deferred: the CLI starts light
    from sixplus3.robot_description import hardware  # deferred: the CLI starts light

    loop = hardware.active().position_loop
    judged = (KP, KD) if loop is None else (loop.kp, loop.kd)
    whose = "the default drive" if loop is None else "the site's position_loop"
    if person and (kp > judged[0] or kd > judged[1]):
        click.echo(f"note: this drive (Kp {kp:g}, Kd {kd:g}) is stiffer than the loop the "
                   f"contact was judged with ({whose}, Kp {judged[0]:g}, Kd "
                   f"{judged[1]:g}): the gate's limits hold for that loop; declare this "
                   "one in the site file (position_loop) to plan for it", err=True)


def simulate_contact(csv_file: str, robot: Any, plant_file: str | None,
                     log_file: str | None, contact_file: str | None, guard: bool, seed: int,
                     noise: float, hold: float, force: bool, kp: float, kd: float,
                     as_json: bool, reaction: str = "hold",
                     parameters_file: str | None = None) -> None:
    from sixplus3.control.drive.loop import DriveSettings
    from sixplus3.control.drive.person import read_contact
    from sixplus3.interaction.people.person import run_contact
    from sixplus3.robot_description.hardware import effective_limits
    from sixplus3.robot_description.robot import load_robot

    if plant_file is None or log_file is None:
        fail("--guard and --contact go with --plant and --log (the run on the plant is "
             "what the log records)")
        return
    check_output(log_file, tuple(f for f in (csv_file, plant_file, contact_file) if f))
    if os.path.exists(log_file) and not force:
        fail(f"{log_file} exists: add --force to replace it")
    plant = load_robot(plant_file)
    contact = read_contact(contact_file) if contact_file is not None else None
    cov = None
    if parameters_file is not None:
        if not guard:
            fail("--parameters goes with --guard")
        from sixplus3.cli.interaction import _load_parameters

        cov = _load_parameters(parameters_file)
    _stiffer_than_judged(kp, kd, contact is not None)
    run = run_contact(csv_file, robot, plant, contact, guard=guard, kp=kp, kd=kd,
                      after=max(hold, 0.5), reaction=reaction, parameter_cov=cov,
                      drive=DriveSettings(seed=seed, torque_noise=noise))
    _logged(run, log_file, robot, plant, seed, noise, csv_file, as_json)
    assert run.log is not None
    if not as_json:
        click.echo(f"{csv_file} on plant {plant.name}, guard {'on' if guard else 'off'}: "
                   f"{len(run.log.t)} ticks logged to {log_file}")
        if contact is None:
            click.echo(f"  nobody in the way: false alarm {run.false_alarm}; modes "
                       f"{' -> '.join(run.modes) or '(the plan followed)'}")
        elif run.onset is None:
            click.echo("  the platform never reached the person")
        else:
            def ms(v: float | None) -> str:
                return "never" if v is None else f"{1e3 * v:.0f} ms"

            click.echo(f"  {run.kind} contact with the {run.region} at {run.onset:.3f} s, "
                       f"{run.speed:.3f} m/s along its normal")
            click.echo(f"  peak transient force {run.peak_transient:.1f} N (limit "
                       f"{run.limit_transient:g}); force at the end {run.quasi_static:.1f} N "
                       f"(quasi-static limit {run.limit_quasi_static:g})")
            click.echo(f"  detected after {ms(run.detection_delay)}"
                       + (f" (placed on {run.site})" if run.site else "")
                       + f"; point stopped after {ms(run.stop_time)}; modes "
                       f"{' -> '.join(run.modes) or '-'}")
        click.echo(f"  peak |tau| asked of the drives {run.peak_command:.2f} N m (applied "
                   f"within {effective_limits(robot).torque:g})")
        for e in run.events:
            click.echo(f"  guard: {e}")
    sys.exit(0 if run.within_limits and not run.false_alarm else 1)


def simulate_lead(csv_file: str | None, lead_file: str | None, robot: Any,
                  plant_file: str | None, log_file: str | None, seed: int, noise: float,
                  force: bool, kp: float, kd: float, as_json: bool) -> None:
    from sixplus3.control.drive.hand import read_hand
    from sixplus3.interaction.people.hand import run_lead
    from sixplus3.robot_description.robot import load_robot

    if lead_file is None:
        fail("give a trajectory FILE to simulate, or --lead HAND.yaml (with --plant and "
             "--log) for lead-through")
        return
    if csv_file is not None:
        fail("--lead takes no trajectory FILE: the hand decides the motion")
    if plant_file is None or log_file is None:
        fail("--lead goes with --plant and --log (the run on the plant is what the log "
             "records)")
        return
    check_output(log_file, (lead_file, plant_file))
    if os.path.exists(log_file) and not force:
        fail(f"{log_file} exists: add --force to replace it")
    plant = load_robot(plant_file)
    hand = read_hand(lead_file)
    from sixplus3.robot_description.hardware import effective_limits

    # the envelope: the robot's limits tightened by the site's (--hardware,
    # $SIXPLUS3_HARDWARE), the gate's one authority; lead-through commands within it
    limit = effective_limits(robot).torque
    run = run_lead(robot, plant, hand, kp=kp, kd=kd, seed=seed, torque_noise=noise)
    out = _logged(run, log_file, robot, plant, seed, noise, lead_file, as_json)
    if not as_json:
        def num(v: float | None, fmt: str) -> str:
            return "(not reached)" if v is None else format(v, fmt) + " N"

        click.echo(f"lead-through on plant {plant.name}: {out['ticks']} ticks logged to "
                   f"{log_file} (guided {100 * out['lead_share']:.0f} % of the time)")
        click.echo(f"  breakaway force {num(out['breakaway_n'], '.2f')}; force at 0.1 m/s "
                   f"{num(out['force_at_0.1_m_s_n'], '.2f')}; largest force "
                   f"{out['max_force_n']:.1f} N, torque {out['max_torque_n_m']:.2f} N m")
        click.echo(f"  moved {1e3 * out['drift_m']:.1f} mm and {out['max_angle_deg']:.1f} deg "
                   f"at most, top speed {out['max_speed_m_s']:.3f} m/s; rms distance to the "
                   f"hand {1e3 * out['rms_lag_m']:.1f} mm")
        click.echo(f"  smallest singularity margin {out['min_margin']:.3f}; walls met in "
                   f"{out['walls_met']} updates; least energy the hand put in "
                   f"{out['port_energy_min_j']:.3f} J")
        click.echo(f"  peak |tau| asked of the drives {out['peak_command_n_m']:.2f} N m "
                   f"(applied {out['peak_applied_n_m']:.2f}, limit {limit:g})")
        for e in out["events"][:10]:
            click.echo(f"  lead-through: {e}")
    sys.exit(0 if out["peak_command_n_m"] <= limit else 1)


def _logged(run: Any, log_file: str, robot: Any, plant: Any, seed: int, noise: float,
            source: str, as_json: bool) -> dict[str, Any]:
    """Write the run's drive log atomically (with its plant, seed and source), print the
    summary as one JSON object when asked, and return the summary."""
    from sixplus3.control.file.drive_log import write_log

    assert run.log is not None
    write_log(log_file, run.log, robot, {"plant": plant.name, "plant_hash": plant.hash,
                                         "seed": seed, "torque_noise_n_m": noise,
                                         "source": os.path.basename(source)})
    out: dict[str, Any] = run.summary()
    if as_json:
        from sixplus3.fileio import strict_json

        click.echo(strict_json(out))
    return out
