"""Solver adapters: the NLP of a given size built once per process, and IPOPT's settings.

:func:`ipopt_solver` returns a :class:`SolverEntry` from a bounded per-process cache
(:data:`SOLVERS`, keyed by the robot's hash, the NLP's size and the solver options).  An
entry carries its own lock: one solve at a time per built solver, because the solver
and its iteration relay hold per-solve state.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np

from sixplus3.cache import BoundedCache
from sixplus3.dynamics.codegen import compiled_functions, single_threaded_solver_blas
from sixplus3.errors import InputError
from sixplus3.planner.options import PlannerOptions
from sixplus3.planner.pfl import pfl_points
from sixplus3.planner.tcp_rows import tcp_function
from sixplus3.planner.transcription import build_nlp

if TYPE_CHECKING:
    from sixplus3.planner.problem import Problem

log = logging.getLogger(__name__)


class IterationRelay(ca.Callback):
    """IPOPT's per-iteration hook (CasADi's ``iteration_callback``): passes the iteration
    number and the iterate's scaled variables and constraint values to ``listener`` (set
    per solve, None: off), and stops the solve after ``limit`` iterations.

    Only x, f and g are taken (the multipliers are declared empty, so CasADi does not
    copy them); a failing listener is switched off rather than stopping the solve.
    """

    def __init__(self, nx: int, ng: int) -> None:
        ca.Callback.__init__(self)
        self.nx, self.ng = nx, ng
        self.listener: Callable[[int, np.ndarray, np.ndarray], None] | None = None
        #: stop the solve (IPOPT's User_Requested_Stop) after this many iterations
        self.limit: int | None = None
        self.count = 0
        self.construct("iteration_relay", {})

    def get_n_in(self) -> int:
        return int(ca.nlpsol_n_out())

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return str(ca.nlpsol_out(i))

    def get_name_out(self, i: int) -> str:
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name == "x":
            return ca.Sparsity.dense(self.nx)
        if name == "g":
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg: Any) -> list[int]:
        k = self.count  # the first call is IPOPT's iteration 0 (the starting point)
        self.count += 1
        if self.listener is not None:
            try:
                self.listener(k, np.array(arg[0]).ravel(), np.array(arg[2]).ravel())
            except Exception as exc:  # noqa: BLE001 - a reporter's bug must not change the plan
                log.warning("the iteration listener raised %s: %s; it gets no more "
                            "iterations of this solve", type(exc).__name__, exc)
                self.listener = None
        return [1 if self.limit is not None and k >= self.limit else 0]


@contextlib.contextmanager
def keyboard_interrupts() -> Iterator[None]:
    """Let a Ctrl-C during an IPOPT solve stop the planner.

    CasADi turns a KeyboardInterrupt raised inside IPOPT into a failed solve
    (``NonIpopt_Exception_Thrown``); the planner's fallbacks would take that for a failed
    start and go on to plan and write files.  The interrupt is noted here and raised once
    the solver has returned.  Only where Python's default SIGINT handler is in place (the
    main thread; not where SIGINT is ignored, e.g. a Dask worker).
    """
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    seen: list[int] = []

    def note(signum: int, frame: Any) -> None:
        seen.append(signum)
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, note)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if seen:
        raise KeyboardInterrupt


def ipopt_settings(opt: PlannerOptions, warm_start: bool) -> dict[str, Any]:
    """IPOPT's options for the planner (each choice measured, BENCHMARKS.md), with the
    caller's ``opt.ipopt_options`` over them."""
    ipopt: dict[str, Any] = {
        "max_iter": opt.max_iter, "tol": opt.tol, "acceptable_tol": 10 * opt.tol,
        "acceptable_iter": 5, "constr_viol_tol": opt.constr_viol_tol,
        "acceptable_constr_viol_tol": opt.constr_viol_tol,
        "hessian_approximation": "limited-memory",
        # 3 pairs instead of IPOPT's 6: fewer back-solves per iteration, and a lower
        # median solve time on the suite and on random tasks
        "limited_memory_max_history": 3,
        # MUMPS's own row/column scaling cost ~25% of each iteration and did not reduce
        # the iteration count on the task suite
        "mumps_permuting_scaling": 0, "mumps_scaling": 0,
        # MUMPS's approximate minimum fill ordering: its factorisations and back-solves
        # took 38% less time than with its automatic choice, same iterates (AMD, PORD,
        # METIS and QAMD were slower)
        "mumps_pivot_order": 2,
        "print_level": 5 if opt.verbose else 0, "sb": "yes"}
    if warm_start:
        ipopt.update({"warm_start_init_point": "yes", "mu_init": 1e-5,
                      "warm_start_bound_push": 1e-7, "warm_start_slack_bound_push": 1e-7,
                      "warm_start_mult_bound_push": 1e-7})
    ipopt.update(dict(opt.ipopt_options))  # the caller's, over the planner's
    return ipopt


@dataclass
class SolverEntry:
    """A built solver, its iteration relay (which must outlive it) and its lock."""

    solver: ca.Function
    relay: IterationRelay
    lock: threading.Lock = field(default_factory=threading.Lock)


#: built NLP solvers per process, least recently used evicted (each holds a CasADi
#: function of a few MB; a process that plans many task sizes keeps the last 16)
SOLVERS: BoundedCache[SolverEntry] = BoundedCache(16)


def ipopt_solver(problem: Problem, warm_start: bool = False) -> SolverEntry:
    """IPOPT on the NLP of ``problem``'s size (:func:`transcription.build_nlp`).

    The node functions are the compiled ones of :mod:`dynamics.codegen` (mapped over the
    points on two threads) when a C compiler is available, otherwise CasADi's
    interpreted SX functions (expanded).  The structure depends only on the intervals
    of every segment (:meth:`Problem.segment_intervals`) and the options: every
    task-specific value is a bound or a parameter; a task with platform-space limits
    adds their rows (:mod:`sixplus3.planner.tcp_rows`).
    """

    opt = problem.options
    compiled = compiled_functions(problem.robot)
    key = (problem.robot.hash, tuple(problem.segment_intervals()), opt.max_iter, opt.tol,
           opt.constr_viol_tol, opt.regularisation, opt.verbose, opt.ipopt_options,
           bool(compiled), warm_start, problem.motion_limits.has_tcp, bool(problem.pfl),
           problem.pfl_links if problem.pfl else ())
    return SOLVERS.get(key, lambda: _build(problem, compiled, warm_start))


def _build(problem: Problem, compiled: dict[str, ca.Function],
           warm_start: bool) -> SolverEntry:

    opt = problem.options
    node = compiled.get("node", problem.sr.node)
    tcp = (tcp_function(problem.robot.tool.xyz) if problem.motion_limits.has_tcp
           else None)
    pfl = (tuple(p.function(problem.robot) for p in pfl_points(problem.robot,
                                                                problem.pfl_links))
           if problem.pfl else ())
    tr = build_nlp(node, 2 if compiled else 1,
                   tuple(int(n) for n in problem.segment_intervals()), opt.regularisation,
                   tcp, pfl)
    relay = IterationRelay(tr.nw, tr.ng)
    settings: dict[str, Any] = {"expand": not compiled, "print_time": False,
                "ipopt": ipopt_settings(opt, warm_start), "iteration_callback": relay}
    single_threaded_solver_blas()
    try:
        solver = ca.nlpsol("planner", "ipopt", tr.nlp, settings)
    except RuntimeError as exc:
        if not opt.ipopt_options:
            raise
        reason = str(exc).strip().splitlines()[-1].split(": ", 1)[-1]
        raise InputError(f"IPOPT rejected ipopt_options {dict(opt.ipopt_options)}: "
                         f"{reason}", value=dict(opt.ipopt_options),
                         valid="IPOPT's options") from None
    return SolverEntry(solver, relay)


__all__ = ["SOLVERS", "IterationRelay", "SolverEntry", "ipopt_settings", "ipopt_solver",
           "keyboard_interrupts"]
