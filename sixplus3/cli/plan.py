"""The ``sixplus3`` planning commands: ``plan``, ``move-to-start`` and ``demo``."""

from __future__ import annotations

import math
import os
from typing import Any

import click

from sixplus3.cli.app import FLOAT, NUMERIC_ARGS, bars, current_robot, fail, main, verbosity


def _check_rate(rate: float) -> None:
    from sixplus3.motion import check_rate

    check_rate(rate, name="--rate")


def _load_task_or_example(task_file: str) -> Any:
    """A task file, or the name of an installed example (when no such file exists)."""
    from pathlib import Path

    from sixplus3 import examples
    from sixplus3.planner.task import load_task

    if not Path(task_file).exists() and task_file in examples.names():
        return examples.load(task_file)
    return load_task(task_file)


def _run_plan(task: Any, out_dir: str, rate: float, html: bool, locked: bool) -> Any:
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.options import PlannerOptions
    from sixplus3.progress import ConsoleProgress

    # quiet: no reporter at all, so the planner computes nothing for one
    reporter = ConsoleProgress() if bars() else None
    try:
        res = run_plan(task, out_dir, current_robot(), rate=rate, html=html,
                       options=PlannerOptions(lock_redundancy=locked), progress=reporter)
    finally:
        if reporter is not None:
            reporter.close()
    click.echo(f"done in {res.seconds['total']:.1f} s: {res.csv}")
    return res


@main.command()
@click.argument("task_file", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "out_dir", default="out", show_default=True,
              type=click.Path(file_okay=False), help="Output directory.")
@click.option("--rate", default=1000.0, show_default=True, type=FLOAT, help="Controller rate [Hz].")
@click.option("--no-html", is_flag=True, help="Skip the MeshCat page.")
@click.option("--locked", is_flag=True, help="Lock the crank angles at their home angles.")
@click.option("--pfl", "pfl", default=None, metavar="REGION[,REGION...]",
              help="Power and force limiting (ISO/TS 15066) for these body regions, added "
                   "to the task's: skull, face, neck, back, chest, abdomen, pelvis, "
                   "upper_arm, lower_arm, hand, thigh, lower_leg (docs/safety.md).")
@click.option("--pfl-links", "pfl_links", default=None, metavar="LINK[,LINK...]",
              help="The leg links power and force limiting holds at, in place of the "
                   "task's (default: every reachable link, 'legs'; '' none; a site's "
                   "required links hold whatever this says): legs, proximal, body, crankB, "
                   "distalB, crankC, distalC, or leg<0-2>_<link> (docs/safety.md).")
@verbosity
def plan(task_file: str, out_dir: str, rate: float, no_html: bool, locked: bool,
         pfl: str | None, pfl_links: str | None) -> None:
    """Plan TASK_FILE (YAML, or the name of an installed example such as tilt60_x):
    plan -> smooth -> validate -> the trajectory file, its MeshCat page and plots."""

    _check_rate(rate)
    task = _load_task_or_example(task_file)
    if pfl is not None:
        from dataclasses import replace

        from sixplus3.robot_description.body_regions import regions

        names = [r.name for r in regions(list(task.pfl) + [r.name for r in regions(pfl)])]
        if not names:
            fail("--pfl names no body region")
        task = replace(task, pfl=tuple(names))
    if pfl_links is not None:
        from dataclasses import replace

        from sixplus3.robot_description.leg_links import link_names

        task = replace(task, pfl_links=link_names(
            [n.strip() for n in pfl_links.split(",") if n.strip()]))
    _run_plan(task, out_dir, rate, not no_html, locked)  # limits checked before the solve


@main.command("move-to-start", context_settings=NUMERIC_ARGS)
@click.argument("task_file", type=click.Path(dir_okay=False))
@click.option("--theta", nargs=9, type=FLOAT, required=True, metavar="A0 B0 C0 ... C2",
              help="The robot's current actuated angles [deg], legs 0..2 each A, B, C.")
@click.option("-o", "--out", "out_dir", default="out", show_default=True,
              help="Output directory.")
@click.option("--rate", default=1000.0, show_default=True, type=FLOAT, help="Controller rate [Hz].")
@verbosity
def move_to_start_cmd(task_file: str, theta: tuple[float, ...], out_dir: str,
                      rate: float) -> None:
    """Plan from the robot's current state to a task's start state (at rest)."""
    import numpy as np

    from sixplus3.planner.task import move_to_start

    _check_rate(rate)
    if not all(math.isfinite(v) for v in theta):
        fail(f"--theta must be 9 finite angles [deg], got {list(theta)}")
    task = move_to_start(_load_task_or_example(task_file), np.radians(theta), current_robot())
    _run_plan(task, out_dir, rate, False, False)


@main.command()
@click.option("-o", "--out", "out_dir", default="out", show_default=True,
              type=click.Path(file_okay=False), help="Output directory.")
@verbosity
def demo(out_dir: str) -> None:
    """Main job on built-in defaults: plan, smooth, validate and show a 30 deg tilt;
    then compile what a first wrench, identify check, commission directions,
    lead-through and contact guard run (once per install: 'sixplus3 warmup')."""
    from sixplus3.control.pipeline import demo_task
    from sixplus3.planner.task import task_from_dict

    res = _run_plan(task_from_dict(demo_task(current_robot())), out_dir, 1000.0, True, False)
    _warm(res.csv)


def _warm(trajectory: Any) -> None:
    import time

    from sixplus3.cli.warmup import warm

    t0 = time.perf_counter()
    click.echo("compiling the kernels the interaction commands use, once per install "
               "(sixplus3 warmup) ...")
    warm(current_robot(), trajectory, say=click.echo if bars() else (lambda _s: None))
    click.echo(f"compiled in {time.perf_counter() - t0:.1f} s")


@main.command()
@click.option("--trajectory", default=None, type=click.Path(dir_okay=False),
              help="A trajectory file to build a contact guard on too (default: none).")
@verbosity
def warmup(trajectory: str | None) -> None:
    """Compile ahead of first use what the interaction commands run: the wrench
    estimator, identify check, commission directions, lead-through, the contact guard
    (numba's kernels into their cache, the observer's model to C).  'sixplus3 demo'
    ends with it."""
    if trajectory is not None:  # an unreadable or foreign file: one line, before any work
        from sixplus3.control.file.trajectory_parse import parse
        from sixplus3.control.file.trajectory_read import read_bytes

        parse(read_bytes(trajectory), os.path.basename(trajectory))
    _warm(trajectory)
