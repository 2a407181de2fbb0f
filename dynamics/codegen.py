"""Compiled node functions for the planner (CasADi C code generation + gcc, cached).

The planner's NLP evaluates, at every IPOPT iteration, the Jacobian of the path
constraints (:attr:`dynamics.symbolic.SymbolicRobot.node`, with the symbolic dynamics) at
every node and every interval midpoint.  In CasADi's SX virtual machine that Jacobian
costs ~1.2 ms per point; compiled with gcc -O1 it is ~6x faster, with -O0 ~3x
(benchmarks/bench_codegen.py, BENCHMARKS.md).

The C source is generated from the very same SX functions, so compiled and interpreted
evaluations agree to rounding (tests/test_planner.py checks it).  The shared library is
cached under ``$SIXPLUS3_CACHE`` (default ``$XDG_CACHE_HOME/sixplus3`` or
``~/.cache/sixplus3``), named by the SHA-256 of the generated source and the flags, so a
changed model never loads a stale library.

Two builds of the same C code: gcc -O1 (the optimised build, ~2 min here: the Jacobian is
one 11 MB function and gcc's register allocation dominates) and gcc -O0 (the quick
build, ~25 s, the same results bit for bit, its Jacobian ~2x slower).  A process that
finds no optimised library compiles the quick one, plans with it, and starts the
optimised build in a detached, niced background process that outlives it; the next
process loads the optimised library.  :func:`ensure_optimised` waits for it instead
(benchmarks).  Every library is written to a temporary file and renamed, so an
interrupted build leaves nothing half-written.  Without a C compiler (or with
``SIXPLUS3_NO_CODEGEN=1``) the planner falls back to the interpreted functions: same
results, slower.

Small functions (thousands of instructions: the planner's profile function, the atlas's
holding torques) are compiled with ``CFLAGS`` in the foreground by :func:`compiled_small`
(a few seconds, once per machine and structure; :func:`ensure_optimised` builds the
profile function too).
"""

from __future__ import annotations

import ctypes
import logging
import os
from collections.abc import Callable
from pathlib import Path

import casadi as ca

from sixplus3.cache import cached
from sixplus3.dynamics import library_index
from sixplus3.dynamics.compiler import (
    CFLAGS,
    build_libraries,
    compile_library,
    compiler_command,
    lib_path,
)
from sixplus3.dynamics.symbolic import profile_function, setup_parameters, structure, symbolic_robot
from sixplus3.robot_description.robot import Robot

log = logging.getLogger(__name__)

#: Functions compiled for the planner, each with its Jacobian (``jac_<name>``).
COMPILED = ("node",)


#: CasADi's private OpenBLAS (IPOPT's MUMPS calls it); its name inside the wheel
CASADI_OPENBLAS = "libcasadi-tp-openblas.so.0"
_blas_done = False


def single_threaded_solver_blas() -> int | None:
    """Run the BLAS of IPOPT's linear solver (MUMPS, through CasADi's own OpenBLAS) on
    one thread, unless the user set ``OPENBLAS_NUM_THREADS``.  Once per process; returns
    the thread count now set, or None (the user's setting, or no such library).

    MUMPS's fronts in the planner's KKT systems are too small for threaded BLAS to help,
    and OpenBLAS's idle threads spin (system time): on the held-out set one thread gave
    the same iterates (durations within 1e-5), ~40 % less CPU time in IPOPT and a 3-7 %
    lower wall time in sum, the spinning thread no longer competing with the Jacobian's
    two (BENCHMARKS.md, sixth round).
    """
    global _blas_done
    if _blas_done or "OPENBLAS_NUM_THREADS" in os.environ:
        return None
    _blas_done = True
    path = Path(ca.__file__).parent / CASADI_OPENBLAS
    try:  # the name MUMPS links to, so the copy loaded here is the one it uses
        lib = ctypes.CDLL(str(path))
        lib.openblas_set_num_threads(1)
        return int(lib.openblas_get_num_threads())
    except (OSError, AttributeError):  # another platform or CasADi build: leave it
        return None


def cache_dir() -> Path:
    env = os.environ.get("SIXPLUS3_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "sixplus3"


def codegen_enabled() -> bool:
    return os.environ.get("SIXPLUS3_NO_CODEGEN", "") in ("", "0") and compiler_command() is not None


def _source(f: ca.Function) -> str:
    """C source of ``f`` and its Jacobian (CasADi finds ``jac_<name>`` in the library)."""
    cg = ca.CodeGenerator(f"{f.name()}.c", {"with_header": False})
    cg.add(f)
    cg.add(f.jacobian())
    return cg.dump()


def cached_library(name: str, src: str, flags: tuple[str, ...] = CFLAGS) -> Path:
    """The library of ``src`` built with ``flags`` in :func:`cache_dir` (named by the
    hash of both), compiled now in the foreground unless it is there; raises OSError or
    RuntimeError (with the compiler's output) if that fails."""
    lib = lib_path(cache_dir(), name, src, flags)
    if not lib.exists():
        lib.parent.mkdir(parents=True, exist_ok=True)
        compile_library(lib.parent, name, src, flags)
    return lib


def compiled_small(f: ca.Function | Callable[[], ca.Function], key: str,
                   name: str | None = None) -> ca.Function:
    """A small function (thousands of instructions, not the planner's 11 MB Jacobian)
    compiled with ``CFLAGS`` in the foreground (about a second).  Cached per process by
    its name and ``key`` (what it depends on, e.g. the robot structure's hash), and on
    disk, like the planner's libraries, by the source's hash.

    ``f`` may be a function or what makes one (then ``name`` is its name): a library
    already built for this name and key is found through :mod:`~sixplus3.dynamics.
    library_index` without building the symbolic model (about 2.5 s of a command's
    start-up).  Returns the interpreted function (the same results)
    when code generation is off or fails."""
    if name is None:
        assert isinstance(f, ca.Function), "name the function that f makes"
        name = f.name()

    def function() -> ca.Function:
        return f if isinstance(f, ca.Function) else f()

    if not codegen_enabled():
        return cached(("interpreted-small", f"{name}:{key}"), function)

    def build() -> ca.Function:
        lib = library_index.lookup(name, key, cache_dir())
        if lib is not None:
            try:
                return ca.external(name, str(lib))
            except RuntimeError:
                pass  # a library that does not load: build it again
        fn = function()
        cg = ca.CodeGenerator(f"{name}.c", {"with_header": False})
        cg.add(fn)
        try:
            lib = cached_library(name, cg.dump())
            out = ca.external(name, str(lib))
        except (OSError, RuntimeError) as exc:
            log.warning("compiling %s failed (%s); interpreted", name, exc)
            return fn
        library_index.record(name, key, cache_dir(), lib)
        return out

    return cached(("compiled-small", f"{name}:{key}"), build)


def compiled_profile(robot: Robot) -> tuple[ca.Function, ca.DM]:
    """(f, p): :func:`dynamics.symbolic.profile_function` compiled (:func:`compiled_small`),
    and ``robot``'s setup parameters to pass as its last input.  Cached per process."""

    def make() -> tuple[ca.Function, ca.DM]:
        return (compiled_small(profile_function(robot), structure(robot).hash),
                ca.DM(setup_parameters(robot)))

    return cached(("compiled-profile", robot.hash), make)


def compiled_functions(robot: Robot) -> dict[str, ca.Function]:
    """Compiled ``node`` (with its Jacobian) of the robot's symbolic model.

    Cached per process by the robot's hash (and on disk by the hash of the generated
    source).  Returns an empty dict when code generation is disabled or fails (the caller
    then uses the interpreted SX functions); the reason is logged.
    """
    if not codegen_enabled():
        log.info("planner code generation disabled or no C compiler: interpreted functions")
        return {}

    libs = cached(("compiled", structure(robot).hash), lambda: _compiled(robot))
    if not libs:
        return {}
    return cached(("compiled-setup", robot.hash), lambda: _with_setup(robot, libs))


def _with_setup(robot: Robot, libs: dict[str, ca.Function]) -> dict[str, ca.Function]:
    """The libraries with this robot's setup parameters (payload, mounting, motors)
    fixed: one library serves every setup of a structure."""

    params = ca.DM(symbolic_robot(robot).params)
    out = {}
    for name, ext in libs.items():
        ins = [ca.MX.sym(f"in{k}", ext.size1_in(k), ext.size2_in(k))
               for k in range(ext.n_in() - 1)]
        out[name] = ca.Function(name, ins, [ext(*ins, params)])
    return out


#: What this process loaded, by robot structure hash: "optimised" or "quick".
_KIND: dict[str, str] = {}
#: the library files this process loaded, per structure hash (what build_kind names)
_LOADED: dict[str, dict[str, Path]] = {}


def loaded_libraries(robot: Robot) -> dict[str, Path]:
    """The compiled library files this process loaded for ``robot``'s structure (empty
    when it runs interpreted)."""

    if not compiled_functions(robot):
        return {}
    return dict(_LOADED.get(structure(robot).hash, {}))


def _compiled(robot: Robot, optimised: bool = False) -> dict[str, ca.Function]:

    sr = symbolic_robot(robot)
    sources = {name: _source(getattr(sr, f"{name}_p")) for name in COMPILED}
    try:
        libs = build_libraries(sources, cache_dir(), optimised)
    except (OSError, RuntimeError) as exc:
        log.warning("planner code generation failed (%s); using interpreted functions", exc)
        return {}
    full = all(lib == lib_path(lib.parent, name, sources[name], CFLAGS)
               for name, lib in libs.items())
    _KIND[structure(robot).hash] = "optimised" if full else "quick"
    _LOADED[structure(robot).hash] = dict(libs)
    return {name: ca.external(f"{name}_p", str(libs[name])) for name in COMPILED}


def ensure_optimised(robot: Robot) -> bool:
    """Build the optimised library of ``robot``'s structure now (or wait for its
    background build), so that this process's :func:`compiled_functions` load it.
    Benchmarks call it first: a plan timed with the quick build is not the planner's
    time.  False when code generation is off or failed, or when this process had
    already loaded the quick build."""
    if not codegen_enabled():
        return False

    cached(("compiled", structure(robot).hash), lambda: _compiled(robot, True))
    compiled_profile(robot)  # the small profile function too (a few seconds, once)
    return build_kind(robot) == "optimised"


def build_kind(robot: Robot) -> str:
    """"optimised", "quick" or "interpreted": what this process's planner runs for
    ``robot``'s structure (loading it if not yet loaded)."""

    if not compiled_functions(robot):
        return "interpreted"
    return _KIND[structure(robot).hash]


__all__ = ["build_kind", "cache_dir", "cached_library", "codegen_enabled", "compiled_functions",
           "compiled_profile", "compiled_small", "ensure_optimised"]
