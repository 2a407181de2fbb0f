"""What one point's exact Hessian costs compiled, against the Jacobian the planner uses.

    .venv/bin/python benchmarks/study_compiled_hessian.py [--repeat 200]

A structured solver (FATROP, acados/HPIPM, SQP with an exact Hessian) needs the Hessian
of the Lagrangian, and today's rows give it through one point's function
``SymbolicRobot.node_p`` (70 rows of (x, xd, u, tau): the torque balance through the
closed-form passive angles, the theta_ddot ties, the limits).  Session 20 estimated its
compiled cost from instruction counts; this measures it:

- the Hessian of lam' node_p over the point's 36 variables (upper triangle), an SX
  function with common subexpressions eliminated, generated to C (38 MB) and compiled
  with the planner's quick flags (``dynamics.compiler.QUICK_CFLAGS``, gcc -O0), cached in
  ``~/.cache/sixplus3`` by its source's hash (the first run compiles it).  The
  optimised flags (gcc -O1) are out of reach here: gcc was killed when it had used the
  machine's 23 GB.
- the planner's node function and its Jacobian, from both of the planner's builds
  (gcc -O0, the quick one; gcc -O1, the one it plans with);
- each evaluated at random points near home, one point per call, median of
  ``--repeat`` calls (CasADi's call overhead included, the same for all).

Then the per-iteration cost of a plan's points (nodes and midpoints: 2N + 1) follows for
a one-segment task (N = 20) and a three-segment one (N = 38).
"""

from __future__ import annotations

import argparse
import statistics
import time

import casadi as ca
import numpy as np

from sixplus3.dynamics.codegen import _source, cached_library, ensure_optimised
from sixplus3.dynamics.compiler import CFLAGS, QUICK_CFLAGS
from sixplus3.dynamics.symbolic import home_x, symbolic_robot
from sixplus3.robot_description.robot import Robot


def hessian_function(node_p: ca.Function) -> ca.Function:
    """(x, xd, u, tau, p, lam) -> upper triangle of d2(lam' node_p)/dz2, z = (x, xd, u, tau)."""
    x, xd, u, tau = (ca.SX.sym(n, 9) for n in ("x", "xd", "u", "tau"))
    p = ca.SX.sym("p", node_p.size1_in(4))
    lam = ca.SX.sym("lam", node_p.size1_out(0))
    z = ca.vertcat(x, xd, u, tau)
    H = ca.triu(ca.hessian(ca.dot(lam, node_p(x, xd, u, tau, p)), z)[0])
    return ca.Function("hess_node_p", [x, xd, u, tau, p, lam], [H], {"cse": True})


def library(name: str, src: str, flags: tuple[str, ...]):
    """:func:`cached_library`, with the time it took (a compile unless it was cached)."""
    t = time.perf_counter()
    lib = cached_library(name, src, flags)
    print(f"{name} with {' '.join(flags)}: ready in {time.perf_counter() - t:.0f} s "
          "(compiled unless cached)", flush=True)
    return lib


def median_call(f: ca.Function, args: list, repeat: int) -> float:
    """Median wall time [us] of one call (after one warm-up)."""
    f(*args)
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f(*args)
        times.append(time.perf_counter() - t)
    return 1e6 * statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=200)
    args = ap.parse_args()
    if not 1 <= args.repeat <= 100_000:
        ap.error(f"--repeat {args.repeat}: valid: 1 to 100000 calls per point")
    robot = Robot.default()
    if not ensure_optimised(robot):
        raise SystemExit("the planner's optimised library is not available (no gcc?)")
    sr = symbolic_robot(robot)
    t = time.perf_counter()
    hf = hessian_function(sr.node_p)
    build = time.perf_counter() - t
    cg = ca.CodeGenerator(f"{hf.name()}.c", {"with_header": False})
    cg.add(hf)
    hess = ca.external(hf.name(), str(library(hf.name(), cg.dump(), QUICK_CFLAGS)))
    print(f"Hessian: {hf.n_instructions():,} SX instructions, {hf.sparsity_out(0).nnz()} "
          f"nonzeros (upper triangle), built in {build:.1f} s; the node function "
          f"{sr.node_p.n_instructions():,} instructions")
    src = _source(sr.node_p)
    builds = {}
    for flags in (QUICK_CFLAGS, CFLAGS):
        ext = ca.external("node_p", str(library("node", src, flags)))
        builds[flags[0]] = (ext, ext.jacobian())
    rng = np.random.default_rng(0)
    params = np.array(sr.params).ravel()
    rows = []
    for _ in range(5):
        x = home_x(robot) + np.r_[rng.normal(0, 0.02, 3), rng.normal(0, 0.2, 6)]
        pt = [x, rng.normal(0, 0.5, 9), rng.normal(0, 20.0, 9), rng.normal(0, 3.0, 9),
              params]
        lam = rng.normal(0, 1.0, 70)
        row = []
        for ext, jac in builds.values():
            row += [median_call(ext, pt, args.repeat),
                    median_call(jac, [*pt, np.zeros(70)], args.repeat)]
        rows.append([*row, median_call(hess, [*pt, lam], args.repeat)])
    med = [statistics.median(c) for c in zip(*rows, strict=True)]
    names = ("node function, -O0", "its Jacobian, -O0", "node function, -O1 (the planner's)",
             "its Jacobian, -O1 (the planner's)", "the Hessian of lam' node, -O0")
    print("| one point | median [us] | per iteration, N = 20 (41 points) [ms] "
          "| N = 38 (77 points) [ms] |")
    print("| --- | ---: | ---: | ---: |")
    for name, us in zip(names, med, strict=True):
        print(f"| {name} | {us:.0f} | {41 * us / 1e3:.1f} | {77 * us / 1e3:.1f} |")
    print(f"Hessian -O0 / Jacobian -O0: {med[4] / med[1]:.2f}; "
          f"Hessian -O0 / Jacobian -O1: {med[4] / med[3]:.2f}")


if __name__ == "__main__":
    main()
