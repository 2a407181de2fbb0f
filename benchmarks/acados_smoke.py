"""Does acados (SQP with HPIPM, per-stage generated C) build and solve here?  A check for
the planner-v2 issue's next step, on a toy OCP; not a planner benchmark.

acados is not a project dependency.  PyPI's ``comma-deps-acados`` wheel (0.2.2.post92
when checked, 2026-11-25) ships acados, BLASFEO, HPIPM and their headers, with its own
CasADi 3.6.7 as the top-level package ``casadi``: installed next to the project's
CasADi 3.8.2 the two would overwrite each other, so it needs an environment of its own.
Its ``acados_template`` also looks for the source tree's layout
(``$ACADOS_SOURCE_DIR/interfaces/acados_template/acados_template``, ``lib``,
``include``, ``bin``), which the wheel does not have; a directory of links provides it:

    python3 -m venv /tmp/acv && /tmp/acv/bin/pip install comma-deps-acados
    W=/tmp/acv/lib/python3.11/site-packages/acados
    mkdir -p /tmp/asrc/interfaces/acados_template
    ln -s $W/acados_template /tmp/asrc/interfaces/acados_template/acados_template
    ln -s $W/install/lib /tmp/asrc/lib; ln -s $W/install/include /tmp/asrc/include
    ln -s $W/install/bin /tmp/asrc/bin
    cd /tmp && ACADOS_SOURCE_DIR=/tmp/asrc LD_LIBRARY_PATH=$W/install/lib \\
        /tmp/acv/bin/python /path/to/benchmarks/acados_smoke.py

It generates and compiles the solver of a double integrator (rest to rest in 1 s, 20
stages, the exact Hessian, SQP with HPIPM's partial condensing) in the current directory,
solves it, and checks the first control against the optimum of the piecewise-constant
problem, 6 N^2 / (tf^2 (N^2 - 1)) (1 - 1/N), to 1e-6.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np
from acados.acados_template import AcadosModel, AcadosOcp, AcadosOcpSolver


def main() -> None:
    model = AcadosModel()
    model.name = "double_integrator"
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    model.x, model.u = x, u
    model.f_expl_expr = ca.vertcat(x[1], u)
    model.cost_expr_ext_cost = u**2
    model.cost_expr_ext_cost_e = 0
    ocp = AcadosOcp()
    ocp.model = model
    N, tf = 20, 1.0
    ocp.dims.N, ocp.solver_options.tf = N, tf
    ocp.cost.cost_type = ocp.cost.cost_type_e = "EXTERNAL"
    ocp.constraints.x0 = np.zeros(2)
    ocp.constraints.lbu, ocp.constraints.ubu = np.array([-10.0]), np.array([10.0])
    ocp.constraints.idxbu = np.array([0])
    ocp.constraints.lbx_e = ocp.constraints.ubx_e = np.array([1.0, 0.0])
    ocp.constraints.idxbx_e = np.array([0, 1])
    ocp.solver_options.qp_solver = "PARTIAL_CONDENSING_HPIPM"
    ocp.solver_options.hessian_approx = "EXACT"
    ocp.solver_options.integrator_type = "ERK"
    ocp.solver_options.nlp_solver_type = "SQP"
    t = time.perf_counter()
    solver = AcadosOcpSolver(ocp, json_file="double_integrator.json")
    build = time.perf_counter() - t
    t = time.perf_counter()
    status = solver.solve()
    solve = time.perf_counter() - t
    u0 = float(solver.get(0, "u")[0])
    # minimum sum u_k^2 h from rest at 0 to rest at 1 with piecewise-constant u: the
    # optimal u is linear in k, u_k = a (1 - (2k + 1)/N) with a = 6 N^2 / (tf^2 (N^2 - 1))
    expected = 6 * N**2 / (tf**2 * (N**2 - 1)) * (1 - 1 / N)
    print(f"build {build:.2f} s, solve {1e3 * solve:.2f} ms, status {status}, "
          f"u0 {u0:.6f} (expected {expected:.6f})")
    if status != 0 or abs(u0 - expected) > 1e-6 * max(1.0, abs(expected)):
        raise SystemExit("acados did not find the optimum")


if __name__ == "__main__":
    main()
