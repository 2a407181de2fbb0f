"""Interpreted (CasADi SX VM) vs compiled (planner.codegen) constraint Jacobian.

    .venv/bin/python benchmarks/bench_codegen.py

Times the planner's per-point constraint function ``node`` and its Jacobian, mapped
over 41 points (a 20-interval task: nodes and midpoints) as the NLP evaluates them,
single-threaded, both from the same SX graph.  Also reports the size of the graphs and
the time to compile from scratch into a temporary cache (skip with --no-compile).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

from sixplus3.planner import codegen
from sixplus3.robot_description.robot import Robot


def per_call(f, args, repeat: int) -> float:
    f(*args)
    t0 = time.perf_counter()
    for _ in range(repeat):
        f(*args)
    return (time.perf_counter() - t0) / repeat


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-compile", action="store_true",
                    help="use the cached library instead of timing a fresh compilation")
    args = ap.parse_args()
    robot = Robot.default()
    sr = robot.symbolic()
    if not args.no_compile:
        with tempfile.TemporaryDirectory() as tmp:
            os.environ["SIXPLUS3_CACHE"] = tmp
            t0 = time.perf_counter()
            codegen._compiled(robot)  # uncached: generate and compile into tmp
            print(f"generate + compile (gcc {' '.join(codegen.CFLAGS)}): "
                  f"{time.perf_counter() - t0:.1f} s")
        del os.environ["SIXPLUS3_CACHE"]
    node_c = codegen.compiled_functions(robot)["node"]
    n = 41
    rng = np.random.default_rng(0)
    x = np.tile(np.r_[0.0, 0.0, 0.30, 0.1, -0.1, 0.05, 1.5, 1.6, 1.4][:, None], (1, n))
    ins = [x + 0.01 * rng.normal(size=(9, n)), rng.normal(size=(9, n)),
           10 * rng.normal(size=(9, n)), rng.normal(size=(9, n))]
    out = np.array(sr.node.map(n)(*ins))
    jac_sx, jac_c = sr.node.jacobian(), node_c.jacobian()
    print(f"node: {sr.node.n_instructions()} SX instructions; "
          f"its Jacobian: {jac_sx.n_instructions()}")
    rows = []
    for name, f in (("node", sr.node), ("node compiled", node_c),
                    ("Jacobian", jac_sx), ("Jacobian compiled", jac_c)):
        fm = f.map(n)
        a = ins + ([out] if name.startswith("Jacobian") else [])
        rows.append((name, per_call(fm, a, 20)))
    for name, t in rows:
        print(f"  {name:18s} x{n}: {t * 1e3:7.2f} ms  ({t / n * 1e6:6.1f} us per point)")
    print(f"speed-up of the Jacobian: {rows[2][1] / rows[3][1]:.1f}x, "
          f"of the function: {rows[0][1] / rows[1][1]:.1f}x")


if __name__ == "__main__":
    main()
