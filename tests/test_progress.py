"""Planning progress: IPOPT iterations through CasADi's callback, --quiet / --verbose
(issue: the lab's ecosystem, first run)."""

from __future__ import annotations

import io
import re
import time

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from sixplus3 import progress
from sixplus3.cli import main
from sixplus3.planner.ocp import plan
from sixplus3.planner.task import task_from_dict
from sixplus3.progress import ConsoleProgress

TASK = {"name": "progress_small",
        "waypoints": [{"position": [0, 0, 0.58]},
                      {"position": [0.03, 0.0, 0.61], "rpy": [10, 0, 0]}],
        "nodes_per_segment": 10}


class Recorder:
    def __init__(self) -> None:
        self.stages: list[str] = []
        self.iterations: list[tuple[int, float, float]] = []

    def stage(self, text: str) -> None:
        self.stages.append(text)

    def iteration(self, k: int, duration: float, violation: float) -> None:
        self.iterations.append((k, duration, violation))


@pytest.fixture(scope="module")
def both():
    task = task_from_dict(TASK)
    rec = Recorder()
    return plan(task), plan(task, progress=rec), rec


def test_listening_does_not_change_the_plan(both) -> None:
    quiet, heard, _ = both
    assert heard.source == quiet.source and heard.solves == quiet.solves
    assert heard.iterations == quiet.iterations
    np.testing.assert_array_equal(heard.x, quiet.x)
    assert heard.final_time == quiet.final_time


def test_every_ipopt_iteration_is_reported(both) -> None:
    _, sol, rec = both
    assert rec.iterations, "no iteration reported"
    # each solve restarts at IPOPT's iteration 0 (the starting point) and counts up by one
    starts = [i for i, it in enumerate(rec.iterations) if it[0] == 0]
    assert starts and starts[0] == 0
    runs = np.split(np.array([it[0] for it in rec.iterations]), starts[1:])
    for run in runs:
        np.testing.assert_array_equal(run, np.arange(len(run)))
    # one IPOPT solve per NLP solve: the last run is the last solve, with its count
    assert len(runs) >= sol.solves
    assert len(runs[-1]) - 1 == sol.iterations
    # the reported iterates: finite, the first solve ends (to IPOPT's tolerance) feasible
    arr = np.array(rec.iterations)
    assert np.isfinite(arr).all() and (arr[:, 1] > 0).all()
    assert arr[len(runs[0]) - 1, 2] < 1e-4
    # stages: the baseline, the NLP start and its outcome
    text = "\n".join(rec.stages)
    assert "baseline" in text and "NLP from" in text and "iterations" in text


def test_a_failing_reporter_does_not_stop_the_plan(both) -> None:
    quiet, _, _ = both

    class Broken(Recorder):
        def iteration(self, k, duration, violation):
            raise RuntimeError("reporter bug")

    sol = plan(task_from_dict(TASK), progress=Broken())
    np.testing.assert_array_equal(sol.x, quiet.x)


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_console_progress_levels() -> None:
    try:
        for level, tty, expect_lines, expect_bar in [(progress.NORMAL, False, 0, False),
                                                     (progress.NORMAL, True, 0, True),
                                                     (progress.VERBOSE, False, 3, False),
                                                     (progress.QUIET, True, 0, False)]:
            progress.set_level(level)
            stream = _Tty() if tty else io.StringIO()
            rep = ConsoleProgress(stream)
            rep.stage("stage one")
            for k in range(3):
                time.sleep(0.12)  # tqdm redraws at most every 0.1 s
                rep.iteration(k, 0.5 - 0.1 * k, 10.0 ** -k)
            rep.close()
            out = stream.getvalue()
            assert ("stage one" in out) == (level != progress.QUIET)
            assert len(re.findall(r"^    IPOPT iteration", out, re.M)) == expect_lines
            # the live line (tqdm, carriage returns) only on a terminal at the normal level
            assert ("\r" in out and "IPOPT iteration    2" in out) == expect_bar, out
    finally:
        progress.set_level(progress.NORMAL)
    with pytest.raises(ValueError, match="0, 1 or 2"):
        progress.set_level(5)


def test_plan_quiet_and_verbose(tmp_path) -> None:
    task = tmp_path / "t.yaml"
    task.write_text(yaml.safe_dump(TASK))
    run = CliRunner()
    quiet = run.invoke(main, ["plan", str(task), "-o", str(tmp_path / "q"), "--no-html",
                              "--quiet"])
    assert quiet.exit_code == 0, quiet.output
    # results only: the one closing line
    assert quiet.output.strip().splitlines() == [quiet.output.strip()]
    assert quiet.output.startswith("done in ")
    verbose = run.invoke(main, ["plan", str(task), "-o", str(tmp_path / "v"), "--no-html",
                                "-v"])
    assert verbose.exit_code == 0, verbose.output
    its = re.findall(r"IPOPT iteration +(\d+): duration +([0-9.]+) s", verbose.output)
    assert its and its[0][0] == "0"
    assert "NLP from" in verbose.output and "validated" in verbose.output
    # the level does not leak into the next command: normal shows stages, no iterations
    normal = run.invoke(main, ["plan", str(task), "-o", str(tmp_path / "n"), "--no-html"])
    assert normal.exit_code == 0, normal.output
    assert "NLP from" in normal.output and "IPOPT iteration" not in normal.output
    both = run.invoke(main, ["plan", str(task), "--quiet", "--verbose"])
    assert both.exit_code == 2 and "exclude each other" in both.output
    assert "Traceback" not in both.output


def test_a_starts_iteration_cap_stops_ipopt_there() -> None:
    """The cap of a start that a fallback follows (PlannerOptions.start_max_iter) is
    enforced through the same callback: IPOPT stops after it, reported as exceeded."""
    from sixplus3.errors import InfeasibleTaskError
    from sixplus3.planner.nlp import Bounds, solve_nlp
    from sixplus3.planner.problem import Problem
    from sixplus3.planner.statics import choose_static_psi
    from sixplus3.robot_description.robot import Robot

    rec = Recorder()
    problem = Problem(task_from_dict(TASK), Robot.default(), progress=rec)
    psi = choose_static_psi(problem.task, problem.robot, problem.limits, False, {0, 1})
    with pytest.raises(InfeasibleTaskError) as err:
        solve_nlp(problem, psi, Bounds(), max_iter=3)
    assert err.value.value == "Maximum_Iterations_Exceeded"
    assert [k for k, _, _ in rec.iterations] == [0, 1, 2, 3]
    # the cap is per solve: the next solve of the same NLP runs to convergence
    rec.iterations.clear()
    sol = solve_nlp(problem, psi, Bounds())
    assert sol.check is not None and len(rec.iterations) - 1 == sol.iterations > 3
