"""The ``sixplus3 commission`` commands: ``zero``, ``directions``, ``jog``, ``theta``
(docs/commissioning.md)."""

from __future__ import annotations

import json
import math

import click

from sixplus3.cli.app import (
    FLOAT,
    INT,
    check_output,
    current_robot,
    emit,
    fail,
    json_default,
    main,
    request_fast_exit,
)


@main.group()
def commission() -> None:
    """Commission the prototype: zero offsets, motor directions, read-back counts
    (docs/commissioning.md)."""


def _counts(values: tuple[float, ...]) -> list[int]:
    if any(not math.isfinite(v) or v != round(v) or abs(v) > 2.0**53 for v in values):
        fail(f"encoder counts must be nine whole numbers, got {list(values)}")
    return [int(v) for v in values]


@commission.command()
@click.option("--log", "log_file", default=None, type=click.Path(dir_okay=False),
              help="A log in the drive's units (counts) taken with the robot resting in the "
                   "known pose: every sample is used.")
@click.option("--counts", nargs=9, type=FLOAT, default=None, metavar="A0 B0 C0 ... C2",
              help="Or the nine motors' counts read in the known pose, legs 0..2 each A, B, C.")
@click.option("--theta", nargs=9, type=FLOAT, default=None, metavar="A0 ... C2",
              help="The known pose's actuated angles [deg] (default: the robot's home, as "
                   "the home jig holds it).")
@click.option("-o", "--out", "out_file", required=True, type=click.Path(dir_okay=False),
              help="The robot file with the offsets (YAML).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def zero(log_file: str | None, counts: tuple[float, ...] | None,
         theta: tuple[float, ...] | None, out_file: str, as_json: bool) -> None:
    """Zero offsets from the encoder counts read in a known pose, into a robot file."""
    import numpy as np

    from sixplus3.control.file.drive_log import JOINTS, read_log
    from sixplus3.identification.commission import known_pose, zero_offsets
    from sixplus3.identification.report import robot_yaml

    robot = current_robot()
    if (log_file is None) == (counts is None):
        fail("give the counts either as --log LOG (drive units) or as --counts (nine)")
    if log_file is not None:
        lg = read_log(log_file, robot)
        if lg.counts is None:
            fail(f"{log_file} is in joint units: zeroing needs the drive's counts "
                 "(columns {joint}_counts)")
        assert lg.counts is not None
        raw = lg.counts
    else:
        assert counts is not None
        raw = np.array([_counts(counts)])
    pose = known_pose(robot, None if theta is None else np.array(theta))
    z = zero_offsets(robot, raw, pose)
    emit(robot_yaml(z.robot, "sixplus3 commission zero: offsets from "
                    + (f"{len(raw)} readings of {log_file}" if log_file else "--counts")
                    + (" at --theta" if theta else " at the home jig")), out_file)
    out = {"offsets_rad": z.offsets.tolist(), "spread_counts": z.spread.tolist(),
           "theta_known_deg": np.degrees(z.theta_known).tolist(), "robot": out_file}
    if as_json:
        click.echo(json.dumps(out, default=json_default))
        return
    for j, name in enumerate(JOINTS):
        click.echo(f"  {name}: offset {z.offsets[j]:+.6f} rad ({math.degrees(z.offsets[j]):+.4f}"
                   f" deg), counts {z.counts[j]:.1f} (spread {int(z.spread[j])})")


@commission.command()
@click.argument("log_file", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "out_file", default=None, type=click.Path(dir_okay=False),
              help="Write the robot file with the reversed motors corrected (YAML).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def directions(log_file: str, out_file: str | None, as_json: bool) -> None:
    """Name reversed motors from a log of each motor jogged in turn from the zeroed pose.

    Exit codes: 0 every judged motor turns the right way (or -o wrote the corrected
    robot); 1 a motor is reversed and no -o was given; 2 bad input."""
    request_fast_exit()
    from sixplus3.control.file.drive_log import JOINTS, read_log
    from sixplus3.identification.commission import GAIN, check_directions
    from sixplus3.identification.report import robot_yaml

    robot = current_robot()
    res = check_directions(robot, read_log(log_file, robot))
    names = [JOINTS[j] for j in res.reversed]
    if out_file is not None and res.reversed:
        emit(robot_yaml(res.robot, f"sixplus3 commission directions: {', '.join(names)} "
                        f"reversed (from {log_file})"), out_file)
    if as_json:
        click.echo(json.dumps({
            "reversed": names, "unjudged": [JOINTS[j] for j in res.unjudged],
            "error_as_logged_n_m": res.error_as_logged.tolist(),
            "error_reversed_n_m": res.error_reversed.tolist(),
            "total_before_n_m": res.total_before, "total_after_n_m": res.total_after},
            default=json_default))
    else:
        for j, name in enumerate(JOINTS):
            if j in res.unjudged:
                verdict = (f"not judged: moved {math.degrees(res.excursion[j]):.2f} deg "
                           "(jog it by 2 deg or more)")
            else:
                ratio = res.error_as_logged[j] / res.error_reversed[j]
                verdict = ("REVERSED" if j in res.reversed else "ok") + (
                    f" (model error {res.error_as_logged[j]:.3f} N m as logged, "
                    f"{res.error_reversed[j]:.3f} reversed: x{ratio:.2f}; reversed "
                    f"when >= x{GAIN:g})")
            click.echo(f"  {name}: {verdict}")
        click.echo(f"model torque error over the log: {res.total_before:.3f} N m RMS as "
                   f"logged" + (f", {res.total_after:.3f} with {', '.join(names)} reversed"
                                if names else ""))
    if res.reversed and out_file is None:
        raise SystemExit(1)


@commission.command()
@click.option("--plant", "plant_file", required=True, type=click.Path(dir_okay=False),
              help="The plant robot file (its motors' offsets and directions are the "
                   "truth the lab does not know).")
@click.option("-o", "--out", "out_file", required=True, type=click.Path(dir_okay=False),
              help="The jog log, in the drive's units.")
@click.option("--amplitude", default=5.0, show_default=True, type=FLOAT,
              help="Each motor's jog [deg], in (0, 28].")
@click.option("--each", default=0.8, show_default=True, type=FLOAT,
              help="Seconds per jog (out and back), in [0.2, 30].")
@click.option("--seed", default=0, show_default=True, type=INT)
def jog(plant_file: str, out_file: str, amplitude: float, each: float, seed: int) -> None:
    """Simulate the commissioning jogs on a plant (MuJoCo): each motor in turn from the
    home jig, the others holding; the log in the drive's units, as its drives count."""
    from sixplus3.control.drive.plant import run_jog
    from sixplus3.control.file.drive_log import write_log
    from sixplus3.robot_description.robot import load_robot

    plant = load_robot(plant_file)
    if not 0.0 < amplitude <= 28.0:
        fail(f"--amplitude must be in (0, 28] deg, got {amplitude:g}")
    check_output(out_file, (plant_file,))
    lg = run_jog(plant, amplitude=math.radians(amplitude), each=each, seed=seed)
    write_log(out_file, lg, plant, {"plant": plant.name, "seed": seed}, units="drive")
    click.echo(f"wrote {out_file}: {len(lg.t)} samples, {lg.duration:.2f} s", err=True)


@commission.command(context_settings={"ignore_unknown_options": True})  # negative counts
@click.argument("counts", nargs=9, type=FLOAT)
def theta(counts: tuple[float, ...]) -> None:
    """The joint angles [deg] of nine counts read back from the drives (what
    'feed --start-counts' checks the file's start against)."""
    import numpy as np

    from sixplus3.identification.commission import counts_to_theta

    th = counts_to_theta(current_robot(), np.array(_counts(counts)))
    click.echo(" ".join(f"{math.degrees(v):.6f}" for v in th))


__all__ = ["commission"]
