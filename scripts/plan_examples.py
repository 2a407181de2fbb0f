"""Plan every task of examples/ into OUT/<task>/ (CSV + JSON + HTML + plots).

    .venv/bin/python scripts/plan_examples.py [--out out] [--locked] [TASK.yaml ...]

The starting point for a lab's own batch: each task goes through plan -> smooth ->
validate -> write (control.pipeline.run_plan); an infeasible task is reported and skipped,
nothing is written for it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sixplus3.control.pipeline import run_plan
from sixplus3.errors import Sixplus3Error
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.task import load_task
from sixplus3.robot_description.robot import Robot, load_robot

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("tasks", nargs="*", type=Path,
                    default=sorted((ROOT / "examples").glob("*.yaml")))
    ap.add_argument("--out", type=Path, default=Path("out"))
    ap.add_argument("--locked", action="store_true", help="cranks locked at home angles")
    ap.add_argument("--robot", type=Path, default=None, help="robot file (default: paper's)")
    args = ap.parse_args()
    try:
        robot = load_robot(args.robot) if args.robot else Robot.default()
    except Sixplus3Error as exc:
        print(f"error: {exc}")
        return 2
    failures = 0
    for path in args.tasks:
        try:
            task = load_task(path)
            res = run_plan(task, args.out / task.name, robot,
                           options=PlannerOptions(lock_redundancy=args.locked), progress=print)
            print(f"{task.name}: {res.smoothed.duration:.4f} s -> {res.csv}")
        except Sixplus3Error as exc:
            failures += 1
            print(f"{path.name}: not planned: {exc}")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
