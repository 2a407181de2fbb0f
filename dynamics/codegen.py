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
import hashlib
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import casadi as ca
from tqdm import tqdm

from sixplus3 import progress
from sixplus3.cache import cached
from sixplus3.dynamics import library_index
from sixplus3.dynamics.symbolic import profile_function, setup_parameters, structure, symbolic_robot
from sixplus3.robot_description.robot import Robot

log = logging.getLogger(__name__)

#: Functions compiled for the planner, each with its Jacobian (``jac_<name>``).
COMPILED = ("node",)
CFLAGS = ("-O1", "-fPIC", "-shared")
#: The quick build of a first run (same code, same results; BENCHMARKS.md).
QUICK_CFLAGS = ("-O0", "-fPIC", "-shared")
#: A background build's marker older than this is a dead build [s].
BACKGROUND_STALE_S = 1200.0
#: The optimised build's gcc peaked at 9.6 GB resident for the planner's node function
#: (one robot structure; BENCHMARKS.md, "The background build's memory").  A background
#: build starts only when the machine has BACKGROUND_MIN_AVAILABLE bytes available
#: (MemAvailable), runs under an address-space cap of BACKGROUND_MAX_BYTES (``ulimit
#: -v``: a build that would need more fails, and the quick build stays in use), and
#: never beside another background build (one marker alive in the cache: none started).
#: ``SIXPLUS3_BUILD_MEMORY_GB`` sets the cap (the minimum follows it).
BACKGROUND_MAX_BYTES = 12 * 2 ** 30
BACKGROUND_MIN_AVAILABLE = BACKGROUND_MAX_BYTES


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
    return os.environ.get("SIXPLUS3_NO_CODEGEN", "") in ("", "0") and _compiler() is not None


def _compiler() -> str | None:
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")


def _source(f: ca.Function) -> str:
    """C source of ``f`` and its Jacobian (CasADi finds ``jac_<name>`` in the library)."""
    cg = ca.CodeGenerator(f"{f.name()}.c", {"with_header": False})
    cg.add(f)
    cg.add(f.jacobian())
    return cg.dump()


def _lib_path(directory: Path, name: str, src: str, flags: tuple[str, ...]) -> Path:
    """The library of ``src`` built with ``flags``: named by the SHA-256 of both (and of
    CasADi's version), so a changed model or flag never loads a stale library."""
    stamp = src + " ".join(flags) + str(getattr(ca, "__version__", ""))
    return directory / f"sixplus3_{name}_{hashlib.sha256(stamp.encode()).hexdigest()[:16]}.so"


def _building(lib: Path) -> bool:
    """Whether a background build of ``lib`` is running: its marker is fresh and the
    builder whose pid it holds is alive (no pid yet: just started)."""
    mark = lib.with_suffix(".building")
    try:
        age = time.time() - mark.stat().st_mtime
        pid = mark.read_text().strip()
    except OSError:
        return False
    if age >= BACKGROUND_STALE_S:
        return False
    if pid.isdigit():
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            return False  # the builder died (killed, machine restarted)
        except PermissionError:
            pass  # alive, another user's
    return True


def background_memory_cap() -> int:
    """The background build's address-space cap [bytes] (:data:`BACKGROUND_MAX_BYTES`,
    or ``$SIXPLUS3_BUILD_MEMORY_GB``; a value that is not a number in [1, 1024] is
    ignored)."""
    env = os.environ.get("SIXPLUS3_BUILD_MEMORY_GB", "")
    try:
        gb = float(env)
    except ValueError:
        return BACKGROUND_MAX_BYTES
    return int(gb * 2 ** 30) if 1.0 <= gb <= 1024.0 else BACKGROUND_MAX_BYTES


def memory_available(need: int) -> bool:
    """Whether the kernel reports at least ``need`` bytes available (MemAvailable of
    /proc/meminfo); True where it cannot be read (another platform)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024 >= need
    except (OSError, ValueError, IndexError):
        pass
    return True


def _start_background(cc: str, src: str, lib: Path, quick: Path) -> None:
    """Build ``lib`` (the optimised flags) in a detached, niced process that outlives
    this one: the source goes to a temporary file, the compiler writes a temporary
    library, and only a finished library is renamed into place (atomic), then the
    temporary files and the marker are removed.  Nothing is started if a build of this
    library is already running."""
    if _building(lib) or any(_building(m.with_suffix(".so"))
                             for m in lib.parent.glob("*.building")):
        return  # one background build at a time, whatever the robot structure
    cap = background_memory_cap()
    if not memory_available(cap):
        if progress.level() != progress.QUIET:
            print(f"sixplus3: the optimised build is not started: less than "
                  f"{cap / 2 ** 30:.0f} GiB of memory available (gcc peaks near 10 GB on "
                  "it); the quick build stays in use (set SIXPLUS3_BUILD_MEMORY_GB, or "
                  "run `python -c 'import sixplus3.dynamics.codegen as c; "
                  "c.ensure_optimised(...)'` when the machine is free)", file=sys.stderr)
        return
    for left in lib.parent.glob(f"{lib.stem}_bg_*"):  # a dead build's source and output
        left.unlink(missing_ok=True)
    mark = lib.with_suffix(".building")
    mark.write_text("")  # no pid yet: "just started"
    fd, c_path = tempfile.mkstemp(suffix=".c", prefix=f"{lib.stem}_bg_", dir=lib.parent)
    with os.fdopen(fd, "w") as fh:
        fh.write(src)
    tmp = c_path[:-2] + ".so.part"
    # the builder writes its pid into the marker (so a killed build is seen as dead),
    # compiles, renames the finished library into place, removes the quick library (a
    # process that loaded it keeps its mapping), then its temporary files and the marker
    builder = ('echo $$ > "$MARK"; ulimit -v "$CAP_KB"; nice -n 10 "$@" >/dev/null 2>&1 '
               '&& mv -f "$TMP" "$LIB" && rm -f "$QUICK"; rm -f "$C" "$TMP" "$MARK"')
    # the outer shell starts the builder in the background and exits at once: the
    # builder is re-parented to init, so it outlives this process (and its Ctrl-C: a
    # new session)
    subprocess.run(["sh", "-c", 'sh -c "$BUILDER" sh "$@" >/dev/null 2>&1 </dev/null &',
                    "sh", cc, *CFLAGS, c_path, "-o", tmp],
                   env={**os.environ, "BUILDER": builder, "TMP": tmp, "LIB": str(lib),
                        "C": c_path, "MARK": str(mark), "QUICK": str(quick),
                        "CAP_KB": str(cap // 1024)},
                   start_new_session=True, check=False)


def _build(sources: dict[str, str], directory: Path, optimised: bool = False
           ) -> dict[str, Path]:
    """Name -> library path, building what is missing.

    The optimised library (``CFLAGS``, gcc -O1, ~2 min on this machine) is used when it
    exists.  Otherwise, unless ``optimised``, the quick build (``QUICK_CFLAGS``, -O0,
    ~25 s; the same C code, the same results bit for bit, its Jacobian ~2x slower) is
    compiled in the foreground and used, and then the optimised one is built in the
    background for the next process.  With ``optimised`` the optimised library is
    waited for (a running background build) or compiled in the foreground.
    """
    directory.mkdir(parents=True, exist_ok=True)
    libs, jobs = {}, []
    cc = _compiler()
    if cc is None:
        raise RuntimeError("no C compiler (set CC or install gcc)")
    waiting: list[str] = []  # names whose optimised library a background build makes
    background: list[tuple[str, Path, Path]] = []  # (source, optimised, quick) to start
    for name, src in sources.items():
        full = _lib_path(directory, name, src, CFLAGS)
        libs[name] = full
        if full.exists():
            continue
        if optimised:
            if _building(full):
                waiting.append(name)
            else:
                jobs.append(_start_foreground(cc, name, src, full, CFLAGS))
            continue
        quick = _lib_path(directory, name, src, QUICK_CFLAGS)
        background.append((src, full, quick))
        libs[name] = quick
        if not quick.exists():
            jobs.append(_start_foreground(cc, name, src, quick, QUICK_CFLAGS))

    if (jobs or waiting) and progress.level() != progress.QUIET:  # quiet: waits below
        what = "an optimised" if optimised else "a quick"
        print(f"sixplus3: compiling {what} build of the planner's constraint functions "
              f"(once per machine and robot structure, ~{'120' if optimised else '25'} s) "
              f"into {directory}", file=sys.stderr, flush=True)
        _wait_with_progress([job[4] for job in jobs], [libs[n] for n in waiting])
    for name in waiting:  # a background build: wait for it, or build here if it failed
        while not libs[name].exists() and _building(libs[name]):
            time.sleep(0.5)
        if not libs[name].exists():
            jobs.append(_start_foreground(cc, name, sources[name], libs[name], CFLAGS))
    errors = [err for err in map(_finish, jobs) if err]
    if errors:
        raise RuntimeError("compiling the planner functions failed:\n" + "\n".join(errors))
    # only now, with the quick library in place (the builder removes it when done)
    for src, full, quick in background:
        _start_background(cc, src, full, quick)
    return libs


def _start_foreground(cc: str, name: str, src: str, lib: Path,
                      flags: tuple[str, ...]) -> Any:
    """Start compiling ``src`` into ``lib`` (a job for :func:`_finish`)."""
    fd, c_path = tempfile.mkstemp(suffix=".c", prefix=f"{name}_", dir=lib.parent)
    with os.fdopen(fd, "w") as fh:
        fh.write(src)
    tmp_lib = c_path[:-2] + ".so.part"
    return (name, lib, c_path, tmp_lib, subprocess.Popen(
        [cc, *flags, c_path, "-o", tmp_lib], stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT))


def _finish(job: Any) -> str | None:
    """Wait for a compile job; rename its library into place (atomic: a library is
    either whole or absent) and remove its temporary files.  Returns the compiler's
    error text, or None."""
    name, lib, c_path, tmp_lib, proc = job
    out, _ = proc.communicate()
    os.unlink(c_path)
    if proc.returncode != 0:
        if os.path.exists(tmp_lib):
            os.unlink(tmp_lib)
        return f"{name}: {out.decode(errors='replace')[-2000:]}"
    os.replace(tmp_lib, lib)
    return None


def compile_library(directory: Path, name: str, src: str, flags: tuple[str, ...]) -> Path:
    """Compile ``src`` with ``flags`` into ``directory`` now (its cache name); raises
    RuntimeError with the compiler's output if it fails.  For benchmarks and tests that
    compare builds; the planner goes through :func:`compiled_functions`."""
    cc = _compiler()
    if cc is None:
        raise RuntimeError("no C compiler (set CC or install gcc)")
    lib = _lib_path(directory, name, src, flags)
    err = _finish(_start_foreground(cc, name, src, lib, flags))
    if err:
        raise RuntimeError(err)
    return lib


def cached_library(name: str, src: str, flags: tuple[str, ...] = CFLAGS) -> Path:
    """The library of ``src`` built with ``flags`` in :func:`cache_dir` (named by the
    hash of both), compiled now in the foreground unless it is there; raises OSError or
    RuntimeError (with the compiler's output) if that fails."""
    lib = _lib_path(cache_dir(), name, src, flags)
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


def _wait_with_progress(procs: list[subprocess.Popen[bytes]], libs: list[Path]) -> None:
    """Wait for the compilers (and background builds of ``libs``), showing the elapsed
    time (a tqdm line on a terminal, a line every 30 s otherwise) so a first run never
    looks hung."""

    start = time.monotonic()
    tty = sys.stderr.isatty()

    def running() -> bool:
        return (any(p.poll() is None for p in procs)
                or any(not lib.exists() and _building(lib) for lib in libs))

    with tqdm(total=None, desc="sixplus3: gcc", bar_format="{desc}: {elapsed} elapsed",
              file=sys.stderr, disable=not tty) as bar:
        last = start
        while running():
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
        libs = _build(sources, cache_dir(), optimised)
    except (OSError, RuntimeError) as exc:
        log.warning("planner code generation failed (%s); using interpreted functions", exc)
        return {}
    full = all(lib == _lib_path(lib.parent, name, sources[name], CFLAGS)
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
