"""What the torque balance's derivatives cost, today's form against the lifted one.

    .venv/bin/python benchmarks/study_lifted_rows.py

Today's 9 torque-balance rows (rows 0-9 of ``SymbolicRobot.node_p``: the closed-form
inverse kinematics composed with the tree's Newton-Euler pass) against two lifted forms
of :mod:`sixplus3.dynamics.lifted`, with the legs' 27 joint values, rates and
accelerations as variables: tied by the closed forms (81 closure rows and the 9 balance
rows), or implicitly (the 27 loop-closure rows of the tree and their velocity and
acceleration forms, and the tree's 36 equations of motion with 27 closure forces as
variables), on the default robot.  For each:
the rows' function, its Jacobian and the Hessian of a multiplier-weighted sum of its rows
(what IPOPT or FATROP would evaluate at every iteration), as CasADi SX functions with
common subexpressions eliminated: their instruction counts, the Jacobian's and the
Hessian's nonzeros, the time to build them, and the time of one evaluation (interpreted,
the median of 200).  The two forms agree where the closure rows hold
(tests/test_planner_structure.py).
"""

from __future__ import annotations

import statistics
import time

import casadi as ca
import numpy as np

from sixplus3.dynamics.lifted import NQ, implicit_functions, lifted_functions
from sixplus3.dynamics.symbolic import N_SETUP, NX, home_x, setup_parameters, symbolic_robot
from sixplus3.robot_description.robot import Robot


def _timed(f: ca.Function, args: list) -> float:
    ts = []
    for _ in range(200):
        t = time.perf_counter()
        f(*args)
        ts.append(time.perf_counter() - t)
    return statistics.median(ts) * 1e6


def measure(name: str, rows: ca.SX, vars_: list[ca.SX], params: list[ca.SX],
            point: list[np.ndarray]) -> None:
    z = ca.vertcat(*vars_)
    lam = ca.SX.sym("lam", rows.numel())
    t0 = time.perf_counter()
    F = ca.Function("F", [*vars_, *params], [rows], {"cse": True})
    J = ca.Function("J", [*vars_, *params], [ca.jacobian(rows, z)], {"cse": True})
    t_j = time.perf_counter() - t0
    H = ca.Function("H", [*vars_, *params, lam], [ca.hessian(ca.dot(lam, rows), z)[0]],
                    {"cse": True})
    t_h = time.perf_counter() - t0 - t_j
    lam0 = np.ones(rows.numel())
    print(f"| {name} | {rows.numel()} x {z.numel()} | {F.n_instructions():,} | "
          f"{J.n_instructions():,} ({J.sparsity_out(0).nnz()} nz) | "
          f"{H.n_instructions():,} ({H.sparsity_out(0).nnz()} nz) | {t_j:.1f} / {t_h:.1f} | "
          f"{_timed(F, point):.0f} / {_timed(J, point):.0f} / "
          f"{_timed(H, [*point, lam0]):.0f} |", flush=True)


def main() -> None:
    robot = Robot.default()
    sr = symbolic_robot(robot)
    p = setup_parameters(robot)
    rng = np.random.default_rng(0)
    x0 = home_x(robot) + np.r_[rng.normal(0, 0.02, 3), rng.normal(0, 0.2, 6)]
    xd0, xdd0, tau0 = rng.normal(0, 0.5, 9), rng.normal(0, 20, 9), rng.normal(0, 3, 9)
    x, xd, xdd, tau = (ca.SX.sym(n, NX) for n in ("x", "xd", "xdd", "tau"))
    setup = ca.SX.sym("p", N_SETUP)
    print("| form | rows x variables | function [instr.] | Jacobian [instr.] | Hessian "
          "[instr.] | build J / H [s] | evaluate f / J / H [us] |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
    today = sr.node_p(x, xd, xdd, tau, setup)[0:9]
    measure("today: 9 balance rows", today, [x, xd, xdd, tau], [setup],
            [x0, xd0, xdd0, tau0, p])
    F = lifted_functions(robot)
    qv, qd, qdd = (ca.SX.sym(n, NQ) for n in ("qv", "qd", "qdd"))
    lifted = ca.vertcat(F["closure"](x, xd, xdd, qv, qd, qdd),
                        F["balance"](x, xd, xdd, tau, qv, qd, qdd, setup))
    lifted_point = [x0, xd0, xdd0, tau0, *(np.array(v).ravel()
                                           for v in F["lift"](x0, xd0, xdd0)), p]
    measure("lifted: 81 closure + 9 balance rows", lifted, [x, xd, xdd, tau, qv, qd, qdd],
            [setup], lifted_point)
    for part, rows, vars_ in (
            ("lifted: the 81 closure rows", F["closure"](x, xd, xdd, qv, qd, qdd),
             [x, xd, xdd, qv, qd, qdd]),
            ("lifted: the 9 balance rows", F["balance"](x, xd, xdd, tau, qv, qd, qdd, setup),
             [x, xd, xdd, tau, qv, qd, qdd])):
        args = [x0, xd0, xdd0, *( [tau0] if "balance" in part else []),
                *(np.array(v).ravel() for v in F["lift"](x0, xd0, xdd0))]
        measure(part, rows, vars_, [setup], [*args, p])
    G = implicit_functions(robot)
    lam = ca.SX.sym("lam", NQ)
    lam0 = rng.normal(0, 10, NQ)
    q0 = [np.array(v).ravel() for v in F["lift"](x0, xd0, xdd0)]
    closure = G["closure"](x, xd, xdd, qv, qd, qdd)
    dynamics = G["dynamics"](x, xd, xdd, tau, qv, qd, qdd, lam, setup)
    measure("implicit: 81 closure + 36 dynamics rows", ca.vertcat(closure, dynamics),
            [x, xd, xdd, tau, qv, qd, qdd, lam], [setup], [x0, xd0, xdd0, tau0, *q0, lam0, p])
    measure("implicit: the 81 loop-closure rows", closure, [x, xd, xdd, qv, qd, qdd], [setup],
            [x0, xd0, xdd0, *q0, p])
    measure("implicit: the 36 dynamics rows", dynamics, [x, xd, xdd, tau, qv, qd, qdd, lam],
            [setup], [x0, xd0, xdd0, tau0, *q0, lam0, p])


if __name__ == "__main__":
    main()
