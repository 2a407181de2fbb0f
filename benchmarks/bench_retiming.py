"""What the re-timing along the path costs a plan (BENCHMARKS.md, "Re-timing along the
path").

    .venv/bin/python benchmarks/bench_retiming.py [--tasks gentle_translate translate]
        [--repeat 2] [--free tilt60_x ...] [--contact]

Plans each example in process ``--repeat`` times (``translate`` under 0.25 m/s, the
others with their own limits) and prints the planner's wall time, the time of
``timing.platform_limited`` alone (the uniform stretch, the re-timing and their checks;
the first call in a process also imports cvxpy), the duration and which one was kept.

``--free NAMES``: the re-timing applied to those examples' own (joint-limited) plans,
which the planner does not do: their durations, uniform and re-timed.
``--contact``: the hand plan of tests/test_guard.py (a 12 cm move there and back under
``pfl: [hand]``) with the uniform stretch (the product) and re-timed (forced), each hit
by a free hand at t = 0.12 s on the soft (300/6) and stiff (3000/30) drive: the
contact's speed, its transient against the hand's limit, and the guard's modes.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import sixplus3.planner.strategy as strategy
from sixplus3.planner.ocp import plan
from sixplus3.planner.task import load_task
from sixplus3.robot_description.robot import Robot

ROOT = Path(__file__).parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="+", default=["gentle_translate", "translate"])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--free", nargs="*", default=[])
    ap.add_argument("--contact", action="store_true")
    args = ap.parse_args()
    if args.free:
        free_plans(args.free)
    if args.contact:
        contact()
    if args.free or args.contact:
        return
    robot = Robot.default()
    spent: list[float] = []
    inner = strategy.platform_limited

    def timed(problem, sol):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        out = inner(problem, sol)
        spent.append(time.perf_counter() - t0)
        return out

    strategy.platform_limited = timed  # type: ignore[assignment]
    print("| task | run | plan wall [s] | platform_limited [s] | duration [s] | kept |")
    print("|---|---|---|---|---|---|")
    for name in args.tasks:
        task = load_task(ROOT / "examples" / f"{name}.yaml")
        if not any(k.startswith("tcp") for k in task.limits):
            task = dataclasses.replace(task, limits={**task.limits, "tcp_speed": 0.25})
        for run in range(args.repeat):
            t0 = time.perf_counter()
            sol = plan(task, robot)
            wall = time.perf_counter() - t0
            kept = ("re-timed" if sol.active_limits and
                    sol.active_limits[-1].startswith("re-timed") else "uniform")
            print(f"| {name} | {run + 1} | {wall:.2f} | {spent[-1]:.2f} | "
                  f"{sol.final_time:.4f} | {kept} |", flush=True)


def _captured() -> dict[str, object]:
    """The problem and the plan the planner hands to ``platform_limited`` (captured)."""
    seen: dict[str, object] = {}
    inner = strategy.platform_limited

    def capture(problem, sol):  # type: ignore[no-untyped-def]
        seen["problem"], seen["sol"] = problem, sol
        return inner(problem, sol)

    strategy.platform_limited = capture  # type: ignore[assignment]
    return seen


def free_plans(names: list[str]) -> None:
    from sixplus3.planner.retiming import retimed

    robot = Robot.default()
    seen = _captured()
    print("| example | plan [s] | re-timed [s] | change | passes its check |")
    print("|---|---|---|---|---|")
    for name in names:
        sol = plan(load_task(ROOT / "examples" / f"{name}.yaml"), robot)
        new = retimed(seen["problem"], seen["sol"])  # type: ignore[arg-type]
        if new is None:
            print(f"| {name} | {sol.final_time:.4f} | no law | | |")
            continue
        print(f"| {name} | {sol.final_time:.4f} | {new.final_time:.4f} | "
              f"{new.final_time / sol.final_time - 1:+.1%} | {new.is_feasible()} |", flush=True)


def contact() -> None:
    import tempfile

    from sixplus3.control.drive.person import contact_from_dict
    from sixplus3.control.pipeline import run_plan
    from sixplus3.interaction.people.person import run_contact
    from sixplus3.planner import timing
    from sixplus3.planner.retiming import retimed
    from sixplus3.planner.task import task_from_dict

    robot = Robot.default()
    doc = {"name": "move", "nodes_per_segment": 6, "pfl": ["hand"], "waypoints": [
        {"position": [-0.06, 0.0, 0.58]}, {"position": [0.06, 0.0, 0.58]},
        {"position": [-0.06, 0.0, 0.58]}]}

    def forced(problem, sol):  # type: ignore[no-untyped-def]
        uniform = timing.tcp_limited(problem, sol)
        local = retimed(problem, sol)
        local = None if local is None else timing.tcp_limited(problem, local)
        ok = local is not None and local.is_feasible() and local.final_time < uniform.final_time
        return local if ok else uniform

    print("| plan | duration [s] | drive | contact speed [m/s] | transient [N] (limit) "
          "| modes |")
    print("|---|---|---|---|---|---|")
    product = strategy.platform_limited
    for label, fn in (("uniform (the product)", product), ("re-timed (forced)", forced)):
        strategy.platform_limited = fn  # type: ignore[assignment]
        with tempfile.TemporaryDirectory() as tmp:
            res = run_plan(task_from_dict(doc), Path(tmp), robot, html=False, plots=False)
            for drive, (kp, kd) in (("soft", (300.0, 6.0)), ("stiff", (3000.0, 30.0))):
                c = contact_from_dict({"region": "hand", "kind": "free", "at": 0.12})
                r = run_contact(res.csv, robot, robot, c, guard=True, kp=kp, kd=kd,
                                after=0.3)
                print(f"| {label} | {res.solution.final_time:.4f} | {drive} | "
                      f"{r.speed:.2f} | {r.peak_transient:.0f} ({r.limit_transient:.0f}) "
                      f"| {', '.join(r.modes)} |", flush=True)
    strategy.platform_limited = product  # type: ignore[assignment]


if __name__ == "__main__":
    main()
