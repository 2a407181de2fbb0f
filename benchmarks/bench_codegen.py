"""Interpreted (CasADi SX VM) vs compiled (dynamics.codegen) constraint Jacobian.

    .venv/bin/python benchmarks/bench_codegen.py

Times the planner's per-point constraint function ``node`` and its Jacobian, mapped
over 41 points (a 20-interval task: nodes and midpoints) as the NLP evaluates them,
single-threaded, from the same SX graph: interpreted, the quick build (gcc -O0, what a
first run plans with) and the optimised build (gcc -O1, built in the background for the
next run).  Also reports the size of the graphs and each build's generate + compile time
(from scratch, into a temporary directory).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

from sixplus3.dynamics import codegen, compiler
from sixplus3.dynamics.symbolic import symbolic_robot
from sixplus3.robot_description.robot import Robot


def per_call(f, args, repeat: int) -> float:
    f(*args)
    t0 = time.perf_counter()
    for _ in range(repeat):
        f(*args)
    return (time.perf_counter() - t0) / repeat


def compile_into(directory, robot, flags) -> tuple[str, float]:
    """Generate and compile the planner's node library with ``flags``: (path, seconds)."""
    t0 = time.perf_counter()
    lib = compiler.compile_library(directory, "node", codegen._source(symbolic_robot(robot).node_p),
                                  flags)
    return str(lib), time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.parse_args()
    robot = Robot.default()
    sr = symbolic_robot(robot)
    n = 41
    rng = np.random.default_rng(0)
    x = np.tile(np.r_[0.0, 0.0, 0.30, 0.1, -0.1, 0.05, 1.5, 1.6, 1.4][:, None], (1, n))
    ins = [x + 0.01 * rng.normal(size=(9, n)), rng.normal(size=(9, n)),
           10 * rng.normal(size=(9, n)), rng.normal(size=(9, n))]
    out = np.array(sr.node.map(n)(*ins))
    print(f"node: {sr.node.n_instructions()} SX instructions; "
          f"its Jacobian: {sr.node.jacobian().n_instructions()}")
    funcs = [("interpreted", sr.node)]
    with tempfile.TemporaryDirectory() as tmp:
        for label, flags in (("quick", compiler.QUICK_CFLAGS), ("optimised", compiler.CFLAGS)):
            lib, secs = compile_into(Path(tmp), robot, flags)
            print(f"{label:9s} build (gcc {' '.join(flags)}): generate + compile {secs:.1f} s")
            ext = ca.external("node_p", lib)
            funcs.append((label, codegen._with_setup(robot, {"node": ext})["node"]))
        rows = []
        for label, f in funcs:
            t_f = per_call(f.map(n), ins, 20)
            t_j = per_call(f.jacobian().map(n), ins + [out], 20)
            rows.append((label, t_f, t_j))
        for label, t_f, t_j in rows:
            print(f"  {label:11s} x{n}: node {t_f * 1e3:7.2f} ms ({t_f / n * 1e6:6.1f} us per "
                  f"point), Jacobian {t_j * 1e3:7.2f} ms ({t_j / n * 1e6:6.1f} us per point)")
        base = rows[0][2]
        print("speed-up of the Jacobian over the interpreted one: "
              + ", ".join(f"{label} {base / t_j:.1f}x" for label, _, t_j in rows[1:]))


if __name__ == "__main__":
    main()
