"""The planner's compiled functions: a quick build for the first run, the optimised one
built in the background for the next (issue: the lab's ecosystem, first run)."""

from __future__ import annotations

import os
import time

import casadi as ca
import numpy as np
import pytest

from sixplus3.dynamics import codegen, compiler
from sixplus3.dynamics.symbolic import symbolic_robot
from sixplus3.robot_description.robot import Robot

pytestmark = pytest.mark.skipif(not codegen.codegen_enabled(), reason="no C compiler")


@pytest.fixture(scope="module")
def source() -> str:
    # a small function of the real model (the margins, with its Jacobian): fast to compile
    return codegen._source(symbolic_robot(Robot.default()).margins)


def _build_with(flags, source: str, directory) -> str:
    return str(compiler.compile_library(directory, "margins", source, flags))


def test_quick_and_optimised_builds_agree_bit_for_bit(source, tmp_path) -> None:
    quick = ca.external("margins", _build_with(compiler.QUICK_CFLAGS, source, tmp_path))
    full = ca.external("margins", _build_with(compiler.CFLAGS, source, tmp_path))
    fq, ff = quick.jacobian(), full.jacobian()
    rng = np.random.default_rng(7)
    for _ in range(20):
        x = np.r_[rng.uniform(-0.1, 0.1, 2), rng.uniform(0.25, 0.4), rng.uniform(-1, 1, 3),
                  rng.uniform(0.8, 2.3, 3)]
        outs_q, outs_f = quick(x), full(x)
        for a, b in zip(outs_q, outs_f, strict=True):
            np.testing.assert_array_equal(np.array(a), np.array(b))
        for a, b in zip(fq(x, *outs_q), ff(x, *outs_f), strict=True):
            np.testing.assert_array_equal(np.array(a), np.array(b))


def test_first_build_is_quick_and_the_optimised_one_follows(source, tmp_path) -> None:
    quick = compiler.lib_path(tmp_path, "margins", source, compiler.QUICK_CFLAGS)
    full = compiler.lib_path(tmp_path, "margins", source, compiler.CFLAGS)
    libs = compiler.build_libraries({"margins": source}, tmp_path)
    assert libs == {"margins": quick}  # returned at once: the quick build
    deadline = time.monotonic() + 300
    while (not full.exists() or compiler.building(full)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert full.exists(), "the background build never finished"
    # the background build cleaned up: no marker, source, partial or quick library left
    assert sorted(p.name for p in tmp_path.iterdir()) == [full.name]
    # the next process gets the optimised library, with nothing to compile
    assert compiler.build_libraries({"margins": source}, tmp_path) == {"margins": full}


def test_optimised_on_demand_and_stale_markers(source, tmp_path) -> None:
    full = compiler.lib_path(tmp_path, "margins", source, compiler.CFLAGS)
    mark = full.with_suffix(".building")
    mark.write_text("started long ago\n")
    assert compiler.building(full)
    old = time.time() - compiler.BACKGROUND_STALE_S - 10
    os.utime(mark, (old, old))
    assert not compiler.building(full)  # a dead build's marker does not block
    # optimised=True: compiled here (the stale marker is ignored), nothing quick
    built = compiler.build_libraries({"margins": source}, tmp_path, optimised=True)
    assert built == {"margins": full}
    assert full.exists()
    assert not any(p.name.endswith((".c", ".part")) for p in tmp_path.iterdir())


def test_the_loaded_build_is_reported(monkeypatch) -> None:
    """build_kind names the libraries this process loaded (their flags in the names'
    hash): "optimised" exactly when every one is the optimised build; with code
    generation off, "interpreted".  Judged on this process's own record, so a background
    build landing in the shared cache meanwhile changes nothing."""
    robot = Robot.default()
    kind = codegen.build_kind(robot)
    assert kind in ("optimised", "quick")
    loaded = codegen.loaded_libraries(robot)
    sr = symbolic_robot(robot)
    assert set(loaded) == set(codegen.COMPILED)
    full = {name: compiler.lib_path(path.parent, name, codegen._source(getattr(sr, f"{name}_p")),
                                    compiler.CFLAGS) for name, path in loaded.items()}
    assert (kind == "optimised") == all(loaded[n] == full[n] for n in loaded)
    assert all(p.name.startswith(f"sixplus3_{n}_") and p.exists() for n, p in loaded.items())
    monkeypatch.setenv("SIXPLUS3_NO_CODEGEN", "1")
    assert codegen.build_kind(robot) == "interpreted"


def test_a_killed_background_build_is_seen_as_dead_and_cleaned_up(source, tmp_path) -> None:
    """An interrupted background build (its builder killed) blocks nothing: its marker
    names a dead process, and the next build removes what it left and starts again."""
    import subprocess

    full = compiler.lib_path(tmp_path, "margins", source, compiler.CFLAGS)
    dead = subprocess.Popen(["true"])
    dead.wait()
    full.with_suffix(".building").write_text(f"{dead.pid}\n")
    left = tmp_path / f"{full.stem}_bg_abc.c"
    left.write_text("half a source")
    assert not compiler.building(full)
    quick = compiler.lib_path(tmp_path, "margins", source, compiler.QUICK_CFLAGS)
    assert compiler.build_libraries({"margins": source}, tmp_path) == {"margins": quick}
    assert not left.exists()
    deadline = time.monotonic() + 300
    while not full.exists() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert full.exists()
    deadline = time.monotonic() + 30
    while len(list(tmp_path.iterdir())) > 1 and time.monotonic() < deadline:
        time.sleep(0.1)  # the builder's last clean-up after the rename
    assert sorted(p.name for p in tmp_path.iterdir()) == [full.name]


_THREADS_AFTER_PLANNING = """
import ctypes, pathlib, casadi
from sixplus3.dynamics.codegen import CASADI_OPENBLAS
from sixplus3.planner.ocp import Problem
from sixplus3.planner.solvers import ipopt_solver
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot
from sixplus3.dynamics.symbolic import symbolic_robot
task = task_from_dict({"name": "t", "nodes_per_segment": 4, "waypoints": [
    {"position": [0, 0, 0.58]}, {"position": [0.02, 0, 0.58]}]})
# the NLP is built: IPOPT and MUMPS (and their BLAS) loaded
ipopt_solver(Problem(task, Robot.default()))
lib = ctypes.CDLL(str(pathlib.Path(casadi.__file__).parent / CASADI_OPENBLAS))
print(lib.openblas_get_num_threads())
"""


@pytest.mark.parametrize("env, expected", [(None, "1"), ("2", "2")])
def test_the_planner_runs_mumps_blas_on_one_thread_unless_the_user_says(env, expected) -> None:
    """Building the planner's NLP sets CasADi's OpenBLAS (MUMPS's BLAS) to one thread,
    in a fresh process; a user's OPENBLAS_NUM_THREADS is left as it is."""
    import subprocess
    import sys

    child_env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if env is not None:
        child_env["OPENBLAS_NUM_THREADS"] = env
    out = subprocess.run([sys.executable, "-c", _THREADS_AFTER_PLANNING], env=child_env,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split()[-1] == expected


def test_the_background_build_is_bounded_in_memory_and_alone(tmp_path, monkeypatch) -> None:
    """Issue 53.7: gcc peaked at 9.6 GB on the optimised node function; two structures
    at once took 5 GB each.  A background build starts only with enough memory
    available, under an address-space cap, and never beside another one."""
    started: list[dict] = []
    real_available = compiler.memory_available

    def fake_run(args, env=None, **kw):
        started.append(env or {})

    monkeypatch.setattr(compiler.subprocess, "run", fake_run)
    lib, quick = tmp_path / "sixplus3_node_a.so", tmp_path / "sixplus3_node_a_q.so"
    monkeypatch.setattr(compiler, "memory_available", lambda need: False)
    compiler.start_background("gcc", "int x;", lib, quick)
    assert started == [] and not lib.with_suffix(".building").exists()
    monkeypatch.setattr(compiler, "memory_available", lambda need: True)
    other = tmp_path / "sixplus3_node_b.building"  # another structure's build, alive
    other.write_text(str(os.getpid()))
    compiler.start_background("gcc", "int x;", lib, quick)
    assert started == []
    other.unlink()
    compiler.start_background("gcc", "int x;", lib, quick)
    assert len(started) == 1
    assert int(started[0]["CAP_KB"]) * 1024 == compiler.BACKGROUND_MAX_BYTES
    assert "ulimit -v" in started[0]["BUILDER"]
    monkeypatch.setenv("SIXPLUS3_BUILD_MEMORY_GB", "6")
    assert compiler.background_memory_cap() == 6 * 2 ** 30
    monkeypatch.setenv("SIXPLUS3_BUILD_MEMORY_GB", "nonsense")
    assert compiler.background_memory_cap() == compiler.BACKGROUND_MAX_BYTES
    assert real_available(1) and not real_available(2 ** 60)
