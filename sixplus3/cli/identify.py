"""The ``sixplus3 identify`` commands: ``excite``, ``estimate``, ``check``, ``plant``
(docs/identification.md)."""

from __future__ import annotations

import json
import math
from typing import Any

import click

from sixplus3.cli.app import (
    FLOAT,
    INT,
    check_output,
    current_robot,
    emit,
    json_default,
    main,
    request_fast_exit,
)


@main.group()
def identify() -> None:
    """Identify the robot's dynamics from drive logs (docs/identification.md)."""


@identify.command()
@click.option("-o", "--out", "out_dir", required=True, type=click.Path(file_okay=False),
              help="Directory for excitation.csv.")
@click.option("--duration", default=10.0, show_default=True, type=FLOAT,
              help="The excitation lasts at least this long [s], in [0.2, 120].")
@click.option("--candidates", default=12, show_default=True, type=INT,
              help="Candidate tours planned (each a time-optimal plan), in [1, 200].")
@click.option("--waypoints", default=4, show_default=True, type=INT,
              help="Random poses per tour, in [1, 12].")
@click.option("--reach", default=0.06, show_default=True, type=FLOAT,
              help="The platform stays within this of home [m].")
@click.option("--tilt", default=25.0, show_default=True, type=FLOAT,
              help="Largest tilt and torsion [deg].")
@click.option("--torque-fraction", default=0.6, show_default=True, type=FLOAT,
              help="Share of the torque limit the tours may use, in [0.5, 1].")
@click.option("--seed", default=0, show_default=True, type=INT)
@click.option("--compare-examples", is_flag=True,
              help="Also plan every example and report their stacked condition number.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def excite(out_dir: str, duration: float, candidates: int, waypoints: int, reach: float,
           tilt: float, torque_fraction: float, seed: int, compare_examples: bool,
           as_json: bool) -> None:
    """Plan an excitation: a valid trajectory file that makes the base parameters
    identifiable (criterion: the condition number of the stacked base regressor)."""
    from sixplus3.cli.app import bars
    from sixplus3.identification.excite import ExcitationSettings
    from sixplus3.identification.excite import excite as run_excite

    st = ExcitationSettings(duration=duration, candidates=candidates, waypoints=waypoints,
                            reach=reach, tilt=tilt, torque_fraction=torque_fraction,
                            seed=seed)
    st.check()
    say = (lambda s: click.echo(s, err=True)) if bars() and not as_json else (lambda s: None)
    ex = run_excite(current_robot(), out_dir, st, say)
    comparison = _examples_condition(current_robot()) if compare_examples else None
    out = {"file": str(ex.path), "duration_s": ex.duration, "condition": ex.condition,
           "log_det": ex.log_det, "tours": len(ex.tours), "candidates_planned": ex.planned,
           "candidates_refused": ex.refused, "examples_condition": comparison}
    if as_json:
        click.echo(json.dumps(out, default=json_default))
        return
    versus = "" if comparison is None else f" (the examples concatenated: {comparison:.4g})"
    click.echo(f"wrote {ex.path}: {ex.duration:.2f} s, {len(ex.tours)} tours of "
               f"{ex.planned} planned ({ex.refused} refused); condition number of the "
               f"base regressor {ex.condition:.4g}{versus}; log det {ex.log_det:.1f}")


def _examples_condition(robot: Any) -> float:
    """The condition number of the examples' base regressor, stacked (each example
    planned; a comparison for the excitation)."""
    import math

    import numpy as np

    from sixplus3 import examples
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.identification.base import base_parameters
    from sixplus3.identification.estimate import condition_number
    from sixplus3.identification.excite import base_regressor
    from sixplus3.planner.ocp import plan
    from sixplus3.planner.smoothing import smooth

    base = base_parameters(robot)
    dyn = ClosedLoopDynamics(robot)
    blocks = []
    for name in examples.names():
        task = examples.load(name)
        if task.payload is not None or task.mounting is not None or task.tool is not None:
            continue  # another setup: another robot
        try:
            sm = smooth(plan(task, robot), rate=1000.0)
        except Exception:  # noqa: BLE001 - an example this robot cannot plan: left out
            continue
        blocks.append(base_regressor(dyn, base, sm.theta, sm.theta_dot, sm.theta_ddot, 1000.0))
    return condition_number(np.vstack(blocks)) if blocks else math.inf


@identify.command()
@click.argument("logs", nargs=-1, required=True, type=click.Path())
@click.option("-o", "--out", "out_file", required=True, type=click.Path(dir_okay=False),
              help="The identified robot file (YAML).")
@click.option("--report", "report_dir", default=None, type=click.Path(file_okay=False),
              help="Also write the report here (table, plots, summary.json).")
@click.option("--validation", "validation_log", default=None, type=click.Path(),
              help="A log the estimate does not use: the report's cross-validation.")
@click.option("--cutoff", default=None, type=FLOAT,
              help="The filter's cut-off [Hz] (default: from the motion's bandwidth).")
@click.option("--prior-weight", default=None, type=FLOAT,
              help="Weight of the prior towards the nominal parameters (default 1e-7).")
@click.option("--force", is_flag=True, help="Replace an existing output file.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def estimate(logs: tuple[str, ...], out_file: str, report_dir: str | None,
             validation_log: str | None, cutoff: float | None, prior_weight: float | None,
             force: bool, as_json: bool) -> None:
    """Estimate the robot's parameters from logs and write the identified robot file
    (physically consistent; every command takes it with --robot)."""
    import os

    from sixplus3.control.file.drive_log import read_log
    from sixplus3.identification.estimate import PRIOR_WEIGHT
    from sixplus3.identification.identify import identify as run_identify
    from sixplus3.identification.report import write_report, write_robot

    check_output(out_file, tuple(logs) + (validation_log,))
    if os.path.exists(out_file) and not force:
        from sixplus3.errors import InputError

        raise InputError(f"{out_file} exists: add --force to replace it", value=out_file,
                         valid="a new file")
    robot = current_robot()
    read = [read_log(p, robot) for p in logs]
    val = read_log(validation_log, robot) if validation_log else None
    idf = run_identify(read, robot, cutoff=cutoff,
                       prior_weight=PRIOR_WEIGHT if prior_weight is None else prior_weight)
    path = write_robot(out_file, idf, [lg.name for lg in read])
    summary = idf.summary()
    if report_dir is not None:
        summary = write_report(report_dir, idf, read, robot, val)
    elif val is not None:
        from sixplus3.identification.identify import check as run_check

        summary["cross_validation"] = {
            lab: run_check(val, rob).rms.tolist() for lab, rob in
            (("nominal", robot), ("identified", idf.robot))}
    summary["robot_file"] = str(path)
    if as_json:
        from sixplus3.fileio import strict_json

        click.echo(strict_json(summary))
        return
    cuts = ", ".join(f"{c:.0f}" for c in idf.cutoffs)
    click.echo(f"wrote {path}: {idf.base.rank} base parameters from {idf.rows} rows, "
               f"condition {idf.condition:.4g}, filter {cuts} Hz, {idf.seconds:.1f} s")
    click.echo("  torque residual RMS per joint [N m]: identified "
               + _per_joint(idf.residual_rms) + "; nominal " + _per_joint(idf.nominal_rms))
    _say_not_measured(idf.residual_rms)
    if "cross_validation" in summary:
        cv = summary["cross_validation"]
        ident = cv["identified"]["rms_n_m"] if isinstance(cv["identified"], dict) \
            else cv["identified"]
        nom = cv["nominal"]["rms_n_m"] if isinstance(cv["nominal"], dict) else cv["nominal"]
        click.echo("  cross-validation on " + str(validation_log) + ": identified "
                   + _per_joint(ident) + "; nominal " + _per_joint(nom))
        _say_not_measured(ident)
    if report_dir is not None:
        click.echo(f"  report: {report_dir}/summary.json, parameters.csv, plots")


def _per_joint(values: Any) -> str:
    """Nine figures; one that was not measured (NaN) reads n/a."""
    return " ".join(f"{float(x):.4f}" if x is not None and math.isfinite(float(x)) else "n/a"
                    for x in values)


def _say_not_measured(values: Any) -> None:
    from sixplus3.identification.identify import not_measured

    for name, why in not_measured([math.nan if v is None else float(v)
                                   for v in values]).items():
        click.echo(f"  {name}: n/a, {why}")


@identify.command("check")
@click.argument("log", type=click.Path())
@click.option("--cutoff", default=None, type=FLOAT, help="The filter's cut-off [Hz].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def check_cmd(log: str, cutoff: float | None, as_json: bool) -> None:
    """Per-joint RMS of the measured minus the predicted torque of the robot (--robot)
    on a log: compare the nominal and an identified robot on a new log."""
    request_fast_exit()
    from sixplus3.control.file.drive_log import read_log
    from sixplus3.identification.identify import check as run_check
    from sixplus3.identification.identify import not_measured

    robot = current_robot()
    c = run_check(read_log(log, robot), robot, cutoff)
    out = {"log": log, "robot": robot.name, "robot_hash": robot.hash,
           "rms_n_m": c.rms.tolist(), "peak_n_m": c.peak.tolist(), "rms_all_n_m": c.rms_all,
           "rows": c.rows, "cutoff_hz": c.cutoff_hz}
    out["not_measured"] = not_measured(c.rms)
    if as_json:
        from sixplus3.fileio import strict_json

        click.echo(strict_json(out))
        return
    click.echo(f"{log} on robot {robot.name} ({robot.hash[:12]}): torque error RMS "
               f"{c.rms_all:.4f} N m over {c.rows} rows of moving joints (filter "
               f"{c.cutoff_hz:.0f} Hz)")
    click.echo("  per joint [N m]: " + _per_joint(c.rms))
    _say_not_measured(c.rms)


@identify.command()
@click.option("-o", "--out", "out_file", required=True, type=click.Path(dir_okay=False),
              help="The plant robot file (YAML).")
@click.option("--seed", default=0, show_default=True, type=INT)
@click.option("--mass", default=0.3, show_default=True, type=FLOAT,
              help="Each link's mass and inertia scaled within 1 +- this.")
@click.option("--rotor", default=0.4, show_default=True, type=FLOAT,
              help="Each rotor inertia scaled within 1 +- this.")
@click.option("--friction", default=3.0, show_default=True, type=FLOAT,
              help="Each joint's friction multiplied by a factor in [1, this].")
def plant(out_file: str, seed: int, mass: float, rotor: float, friction: float) -> None:
    """Write a perturbed plant (a robot as a real build differs from its model) for
    'sixplus3 simulate FILE --plant PLANT --log LOG'."""
    from sixplus3.identification.plants import perturbed_plant
    from sixplus3.identification.report import robot_yaml

    p = perturbed_plant(current_robot(), seed, mass=mass, rotor=rotor, friction=friction)
    emit(robot_yaml(p, f"sixplus3 plant: seed {seed}, mass +-{mass:g}, rotor +-{rotor:g}, "
                       f"friction x[1, {friction:g}]"), out_file)


__all__ = ["identify"]
