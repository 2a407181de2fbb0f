"""The ``slow`` marker: ``make test-fast`` runs the unit-level tests (``-m "not slow"``),
``make test`` runs everything.

A test is slow when it plans (the NLP, the pipeline, the CLI's ``plan``), runs MuJoCo or
a whole identification, builds a wheel, or took more than about 3 s on this machine
(``pytest --durations=0``).  Whole modules of such tests are listed in
:data:`SLOW_MODULES`; single slow tests of otherwise fast modules in :data:`SLOW_TESTS`
(node ids without parameters).  A new test is fast until it is listed here: keep
``make test-fast`` under two minutes (docs/testing.md).
"""

from __future__ import annotations

import pytest

SLOW_MODULES = {
    "test_certificate", "test_commission", "test_exports", "test_gate_attacks",
    "test_identification", "test_interaction", "test_motion", "test_mujoco",
    "test_packaging", "test_pipeline", "test_planner", "test_planner_fallback",
    "test_planner_structure", "test_ros_replay", "test_tcp_limits", "test_true_words",
    "test_atlas", "test_safety", "test_docs_walkthrough", "test_guard", "test_leadthrough",
    "test_safety_report",
}
SLOW_TESTS = {
    "test_robot.py::test_a_plan_for_a_non_default_robot_is_refused_for_the_default",
    "test_robot.py::test_every_cache_is_keyed_by_the_robot",
    "test_named_robots.py::test_default_home_is_the_deepest_point_of_its_cow_of_at_least_15_litres",
    "test_named_robots.py::test_no_contact_over_the_default_cow_by_an_independent_distance",
    "test_named_robots.py::test_the_paper_assemblies_interfere_the_built_one_does_not",
    "test_progress.py::test_plan_quiet_and_verbose",
    "test_progress.py::test_listening_does_not_change_the_plan",
    "test_progress.py::test_a_starts_iteration_cap_stops_ipopt_there",
    "test_progress.py::test_a_failing_reporter_does_not_stop_the_plan",
    "test_codegen.py::test_the_planner_runs_mumps_blas_on_one_thread_unless_the_user_says",
    "test_codegen.py::test_a_killed_background_build_is_seen_as_dead_and_cleaned_up",
    "test_codegen.py::test_the_loaded_build_is_reported",
    "test_codegen.py::test_first_build_is_quick_and_the_optimised_one_follows",
    "test_codegen.py::test_optimised_on_demand_and_stale_markers",
    "test_codegen.py::test_quick_and_optimised_builds_agree_bit_for_bit",
    "test_design.py::test_refining_every_near_best_seed_finds_the_ridge_and_the_papers_basin",
    "test_architecture.py::test_robot_check_is_a_library_function_the_cli_prints",
    "test_architecture.py::test_the_gate_and_the_dense_check_apply_one_rule",
    "test_gate.py::test_the_dynamics_worker_changes_nothing",
    "test_gate.py::test_kill_9_at_random_moments_leaves_a_complete_file",
    "test_cli.py::test_robot_check_reports_the_model",
    "test_dynamics.py::test_unactuated_drop_conserves_energy_and_closures",
    "test_motion_value.py::test_one_plan_checks_each_input_once",
    "test_retiming.py::test_gentle_translate_cruises_at_its_limit",
    "test_retiming.py::test_the_exact_platform_acceleration_is_within_its_limit",
}


@pytest.fixture(autouse=True)
def catalogue_hardware():
    """The built-in catalogue's envelope in force before and after every test (a test
    that sets a site's hardware, or runs the CLI with --hardware, cannot leak it into the
    next: the drive loop's own limit and every controller's envelope read it)."""
    from sixplus3.robot_description import hardware

    hardware.use(None)
    yield
    hardware.use(None)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        module = item.path.stem
        test = f"{item.path.name}::{item.originalname}"
        if module in SLOW_MODULES or test in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
