"""Show that tests can fail: break the code a test guards, run the test, expect a failure.

    .venv/bin/python scripts/break_and_test.py [NAME ...]

Each entry below is one deliberate break (one text replacement in one module) and the
tests that must then fail.  The break is applied in place, the tests run in a fresh
pytest process, and the module is restored in a ``finally`` (the script refuses to start
on a tree with uncommitted changes, so nothing can be left broken by mistake).  It prints
one line per break: ``caught`` when every named test failed, ``MISSED`` otherwise, and
exits 1 if any was missed.  docs/testing.md records a run.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: name -> (file, text, broken text, tests that must fail)
BREAKS: dict[str, tuple[str, str, str, list[str]]] = {
    "build kind ignores a disabled code generation": (
        "dynamics/codegen.py",
        "    if not codegen_enabled():\n        log.info(\"planner code generation disabled",
        "    if False:\n        log.info(\"planner code generation disabled",
        ["tests/test_codegen.py::test_the_loaded_build_is_reported"]),
    "the dense check's torque cap halved": (
        "kinematics/checks.py", "    if cap_excess(tau_max, limits.torque) > 0:",
        "    if cap_excess(tau_max, 0.5 * limits.torque) > 0:",
        ["tests/test_planner.py::test_every_example_plans_within_its_limits[translate]"]),
    "the distal tubes' radius ignored by the collision model": (
        "kinematics/collision.py", "    leg = [c.link_radius, c.link_radius, c.crank_radius, "
        "c.distal_radius, c.crank_radius,\n           c.distal_radius]",
        "    leg = [c.link_radius, c.link_radius, c.crank_radius, 0.5 * c.distal_radius, "
        "c.crank_radius,\n           c.distal_radius]",
        ["tests/test_planner.py::test_clearance_and_home_x"]),
    "the paper design's area taken on another design": (
        "design/search.py",
        "    paper_area = float(evaluate(np.array([PAPER_DESIGN]), reading, grid)[0][0])",
        "    paper_area = float(evaluate(np.array([(0.30, 0.35, 0.20)]), reading, grid)[0][0])",
        ["tests/test_design.py::test_optimize_finds_the_best_design_of_its_grids"]),
    "the figure's counted area in the default reading": (
        "design/figures.py",
        "    cnt = counted_reading(s, load, reading).reshape(X.shape) & inside",
        "    cnt = counted_reading(s, load, Reading()).reshape(X.shape) & inside",
        ["tests/test_design.py::test_figures_are_written"]),
    "a spherical joint's tilt measured against its own side": (
        "kinematics/spherical.py", "            b = other @ ref[i, j, 1]",
        "            b = body @ ref[i, j, 1]",
        ["tests/test_robot_kinematics.py::test_home_and_spherical_joint_tilts"]),
    "the COW of robot check ignores the torque limit": (
        "design/cow.py", "    robot = require_robot(robot)\n    cow = compute_cow(robot, ",
        "    robot = require_robot(robot).replace(limits=type(robot.limits)())\n"
        "    cow = compute_cow(robot, ",
        ["tests/test_robot.py::test_robot_show_output_is_the_robot_file_format"]),
    "the mirrored assembly's mode swapped": (
        "robot_description/robot.py",
        '    "paper-mirror": (lambda: _paper_assembly("-+++", "paper-mirror"),',
        '    "paper-mirror": (lambda: _paper_assembly("-+-+", "paper-mirror"),',
        ["tests/test_named_robots.py::test_the_leg_reproduces_the_design_study"]),
    "the ridge's ratio of another column": (
        "design/search.py", "                 span(d[:, 0] / d[:, 2]))",
        "                 span(d[:, 0] / d[:, 1]))",
        ["tests/test_design.py::"
         "test_refining_every_near_best_seed_finds_the_ridge_and_the_papers_basin"]),
    "the waypoints' clearance bound ignored by the NLP": (
        "planner/nlp.py",
        "    if bounds.clearance is not None and bounds.clearance_waypoints is not None:",
        "    if False:",
        ["tests/test_planner_fallback.py::"
         "test_an_overlap_next_to_a_near_contact_waypoint_is_re_solved_not_given_up"]),
    "the implicit form's platform rows without the closure forces' sign": (
        "dynamics/lifted.py",
        "    platform = ca.vertcat(f_ff, E.T @ n_ff) - Cx[:, 0:6].T @ lam",
        "    platform = ca.vertcat(f_ff, E.T @ n_ff) + Cx[:, 0:6].T @ lam",
        ["tests/test_planner_structure.py::test_the_implicit_closures_reproduce_todays_torques"]),
    "the lifted balance without the motors": (
        "dynamics/lifted.py", "    balance = Jth.T @ (tau - motor) - Q",
        "    balance = Jth.T @ tau - Q",
        ["tests/test_planner_structure.py::"
         "test_the_lifted_torque_balance_is_todays_where_its_closures_hold"]),
    "the gate's torque cap with its own tolerance": (
        "control/gate/findings.py",
        '    out.append(finding("torque", "limit", "N m", lim.torque, '
        'cap_excess(atau, lim.torque),',
        '    out.append(finding("torque", "limit", "N m", lim.torque, '
        'atau - lim.torque * (1 + 1e-9),',
        ["tests/test_architecture.py::test_the_gate_and_the_dense_check_apply_one_rule"]),
}


def _dirty() -> bool:
    out = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                         cwd=ROOT, capture_output=True, text=True, check=True).stdout
    return bool(out.strip())


def run(name: str) -> bool:
    """Apply one break, run its tests, restore; True when every test failed."""
    rel, text, broken, tests = BREAKS[name]
    path = ROOT / rel
    original = path.read_text()
    if original.count(text) != 1:
        raise SystemExit(f"{name}: the text to break is not in {rel} exactly once")
    caught = True
    why = ""
    t0 = time.perf_counter()
    try:
        path.write_text(original.replace(text, broken))
        for test in tests:
            res = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x",
                                  "-p", "no:cacheprovider", test], cwd=ROOT,
                                 capture_output=True, text=True)
            caught &= res.returncode == 1
            why = why or next((ln[1:].strip() for ln in res.stdout.splitlines()
                               if ln.startswith("E ")), "")
    finally:
        path.write_text(original)
    print(f"{'caught' if caught else 'MISSED'}  {name} ({rel}; "
          f"{time.perf_counter() - t0:.0f} s)\n        {why[:150]}", flush=True)
    return caught


def main() -> int:
    if _dirty():
        print("refusing: the tree has uncommitted changes (commit or stash first)")
        return 2
    names = sys.argv[1:] or list(BREAKS)
    unknown = [n for n in names if n not in BREAKS]
    if unknown:
        print(f"unknown break(s) {unknown}; known: {list(BREAKS)}")
        return 2
    missed = [n for n in names if not run(n)]
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
