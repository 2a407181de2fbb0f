"""Compiled node functions for the planner (CasADi C code generation + gcc, cached).

The planner's NLP evaluates, at every IPOPT iteration, the Jacobian of the path
constraints (:attr:`planner.model.SymbolicRobot.node`, with the symbolic dynamics) at
every node and every interval midpoint.  In CasADi's SX virtual machine that Jacobian
costs ~2 ms per point; compiled with gcc -O1 it is ~18x faster
(benchmarks/bench_codegen.py, BENCHMARKS.md).

The C source is generated from the very same SX functions, so compiled and interpreted
evaluations agree to rounding (tests/test_planner.py checks it).  The shared library is
cached under ``$SIXPLUS3_CACHE`` (default ``$XDG_CACHE_HOME/sixplus3`` or
``~/.cache/sixplus3``), named by the SHA-256 of the generated source, so a changed model
never loads a stale library.  Compilation takes about a minute once per machine and
model; it is written to a temporary file and renamed, so an interrupted build leaves
nothing half-written.  Without a C compiler (or with ``SIXPLUS3_NO_CODEGEN=1``) the
planner falls back to the interpreted functions: same results, slower.
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import casadi as ca

from sixplus3.robot_description.robot import Robot, _cached

log = logging.getLogger(__name__)

#: Functions compiled for the planner, each with its Jacobian (``jac_<name>``).
COMPILED = ("node",)
CFLAGS = ("-O1", "-fPIC", "-shared")


def cache_dir() -> Path:
    env = os.environ.get("SIXPLUS3_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "sixplus3"


def codegen_enabled() -> bool:
    return os.environ.get("SIXPLUS3_NO_CODEGEN", "") in ("", "0") and _compiler() is not None


def _compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")


def _source(f: ca.Function) -> str:
    """C source of ``f`` and its Jacobian (CasADi finds ``jac_<name>`` in the library)."""
    cg = ca.CodeGenerator(f"{f.name()}.c", {"with_header": False})
    cg.add(f)
    cg.add(f.jacobian())
    return cg.dump()


def _build(sources: dict[str, str], directory: Path) -> dict[str, Path]:
    """Compile missing libraries (in parallel) and return name -> library path."""
    directory.mkdir(parents=True, exist_ok=True)
    libs, jobs = {}, []
    cc = _compiler()
    if cc is None:
        raise RuntimeError("no C compiler (set CC or install gcc)")
    for name, src in sources.items():
        stamp = src + " ".join(CFLAGS) + str(getattr(ca, "__version__", ""))
        digest = hashlib.sha256(stamp.encode()).hexdigest()
        lib = directory / f"sixplus3_{name}_{digest[:16]}.so"
        libs[name] = lib
        if lib.exists():
            continue
        fd, c_path = tempfile.mkstemp(suffix=".c", prefix=f"{name}_", dir=directory)
        with os.fdopen(fd, "w") as fh:
            fh.write(src)
        tmp_lib = c_path[:-2] + ".so.part"
        jobs.append((name, lib, c_path, tmp_lib, subprocess.Popen(
            [cc, *CFLAGS, c_path, "-o", tmp_lib], stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT)))
    from sixplus3 import progress

    if jobs and progress.level() != progress.QUIET:  # quiet: communicate() below waits
        print("sixplus3: compiling the planner's constraint functions (once per machine "
              f"and robot structure, ~1-3 min) into {directory}", file=sys.stderr,
              flush=True)
        _wait_with_progress([job[4] for job in jobs])
    errors = []
    for name, lib, c_path, tmp_lib, proc in jobs:
        out, _ = proc.communicate()
        os.unlink(c_path)
        if proc.returncode != 0:
            errors.append(f"{name}: {out.decode(errors='replace')[-2000:]}")
            if os.path.exists(tmp_lib):
                os.unlink(tmp_lib)
            continue
        os.replace(tmp_lib, lib)  # atomic: a library is either whole or absent
    if errors:
        raise RuntimeError("compiling the planner functions failed:\n" + "\n".join(errors))
    return libs


def _wait_with_progress(procs: list[subprocess.Popen]) -> None:
    """Wait for the compilers, showing the elapsed time (a tqdm line on a terminal, a
    line every 30 s otherwise) so a first run never looks hung."""
    import time

    from tqdm import tqdm

    start = time.monotonic()
    tty = sys.stderr.isatty()
    with tqdm(total=None, desc="sixplus3: gcc", bar_format="{desc}: {elapsed} elapsed",
              file=sys.stderr, disable=not tty) as bar:
        last = start
        while any(p.poll() is None for p in procs):
            time.sleep(0.5)
            bar.update(0)
            bar.refresh()
            now = time.monotonic()
            if not tty and now - last >= 30.0:
                print(f"sixplus3: still compiling, {now - start:.0f} s elapsed",
                      file=sys.stderr, flush=True)
                last = now
    print(f"sixplus3: compiled in {time.monotonic() - start:.0f} s", file=sys.stderr,
          flush=True)


def compiled_functions(robot: Robot) -> dict[str, ca.Function]:
    """Compiled ``node`` (with its Jacobian) of the robot's symbolic model.

    Cached per process by the robot's hash (and on disk by the hash of the generated
    source).  Returns an empty dict when code generation is disabled or fails (the caller
    then uses the interpreted SX functions); the reason is logged.
    """
    if not codegen_enabled():
        log.info("planner code generation disabled or no C compiler: interpreted functions")
        return {}
    from sixplus3.planner.model import structure

    libs = _cached(("compiled", structure(robot).hash), lambda: _compiled(robot))
    if not libs:
        return {}
    return _cached(("compiled-setup", robot.hash), lambda: _with_setup(robot, libs))


def _with_setup(robot: Robot, libs: dict[str, ca.Function]) -> dict[str, ca.Function]:
    """The libraries with this robot's setup parameters (payload, mounting, motors)
    fixed: one library serves every setup of a structure."""
    params = ca.DM(robot.symbolic().params)
    out = {}
    for name, ext in libs.items():
        ins = [ca.MX.sym(f"in{k}", ext.size1_in(k), ext.size2_in(k))
               for k in range(ext.n_in() - 1)]
        out[name] = ca.Function(name, ins, [ext(*ins, params)])
    return out


def _compiled(robot: Robot) -> dict[str, ca.Function]:
    sr = robot.symbolic()
    sources = {name: _source(getattr(sr, f"{name}_p")) for name in COMPILED}
    try:
        libs = _build(sources, cache_dir())
    except (OSError, RuntimeError) as exc:
        log.warning("planner code generation failed (%s); using interpreted functions", exc)
        return {}
    return {name: ca.external(f"{name}_p", str(libs[name])) for name in COMPILED}


__all__ = ["cache_dir", "codegen_enabled", "compiled_functions"]
