"""Building C libraries for the compiled functions (gcc), cached by the SHA-256 of their
source, flags and CasADi's version (:func:`lib_path`).

Two builds of the same C code: the optimised one (:data:`CFLAGS`, gcc -O1) and the quick
one (:data:`QUICK_CFLAGS`, -O0; the same results bit for bit).  :func:`build_libraries`
compiles the quick build in the foreground when no optimised library exists and starts the
optimised one in a detached, niced background process that outlives this one
(:func:`start_background`): one background build at a time, only with enough memory
available, under an address-space cap (:func:`background_memory_cap`).  Every library is
written to a temporary file and renamed, so an interrupted build leaves nothing
half-written.  :mod:`sixplus3.dynamics.codegen` decides what is compiled and loads it."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import casadi as ca
from tqdm import tqdm

from sixplus3 import progress

#: The optimised build (BENCHMARKS.md).
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


def compiler_command() -> str | None:
    """The C compiler: ``$CC``, else gcc, else cc (None: there is none)."""
    return os.environ.get("CC") or shutil.which("gcc") or shutil.which("cc")


def lib_path(directory: Path, name: str, src: str, flags: tuple[str, ...]) -> Path:
    """The library of ``src`` built with ``flags``: named by the SHA-256 of both (and of
    CasADi's version), so a changed model or flag never loads a stale library."""
    stamp = src + " ".join(flags) + str(getattr(ca, "__version__", ""))
    return directory / f"sixplus3_{name}_{hashlib.sha256(stamp.encode()).hexdigest()[:16]}.so"


def building(lib: Path) -> bool:
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


def start_background(cc: str, src: str, lib: Path, quick: Path) -> None:
    """Build ``lib`` (the optimised flags) in a detached, niced process that outlives
    this one: the source goes to a temporary file, the compiler writes a temporary
    library, and only a finished library is renamed into place (atomic), then the
    temporary files and the marker are removed.  Nothing is started if a build of this
    library is already running."""
    if building(lib) or any(building(m.with_suffix(".so"))
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


def build_libraries(sources: dict[str, str], directory: Path, optimised: bool = False
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
    cc = compiler_command()
    if cc is None:
        raise RuntimeError("no C compiler (set CC or install gcc)")
    waiting: list[str] = []  # names whose optimised library a background build makes
    background: list[tuple[str, Path, Path]] = []  # (source, optimised, quick) to start
    for name, src in sources.items():
        full = lib_path(directory, name, src, CFLAGS)
        libs[name] = full
        if full.exists():
            continue
        if optimised:
            if building(full):
                waiting.append(name)
            else:
                jobs.append(start_compile(cc, name, src, full, CFLAGS))
            continue
        quick = lib_path(directory, name, src, QUICK_CFLAGS)
        background.append((src, full, quick))
        libs[name] = quick
        if not quick.exists():
            jobs.append(start_compile(cc, name, src, quick, QUICK_CFLAGS))

    if (jobs or waiting) and progress.level() != progress.QUIET:  # quiet: waits below
        what = "an optimised" if optimised else "a quick"
        print(f"sixplus3: compiling {what} build of the planner's constraint functions "
              f"(once per machine and robot structure, ~{'120' if optimised else '25'} s) "
              f"into {directory}", file=sys.stderr, flush=True)
        _wait_with_progress([job[4] for job in jobs], [libs[n] for n in waiting])
    for name in waiting:  # a background build: wait for it, or build here if it failed
        while not libs[name].exists() and building(libs[name]):
            time.sleep(0.5)
        if not libs[name].exists():
            jobs.append(start_compile(cc, name, sources[name], libs[name], CFLAGS))
    errors = [err for err in map(finish_compile, jobs) if err]
    if errors:
        raise RuntimeError("compiling the planner functions failed:\n" + "\n".join(errors))
    # only now, with the quick library in place (the builder removes it when done)
    for src, full, quick in background:
        start_background(cc, src, full, quick)
    return libs


def start_compile(cc: str, name: str, src: str, lib: Path,
                      flags: tuple[str, ...]) -> Any:
    """Start compiling ``src`` into ``lib`` (a job for :func:`finish_compile`)."""
    fd, c_path = tempfile.mkstemp(suffix=".c", prefix=f"{name}_", dir=lib.parent)
    with os.fdopen(fd, "w") as fh:
        fh.write(src)
    tmp_lib = c_path[:-2] + ".so.part"
    return (name, lib, c_path, tmp_lib, subprocess.Popen(
        [cc, *flags, c_path, "-o", tmp_lib], stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT))


def finish_compile(job: Any) -> str | None:
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
    cc = compiler_command()
    if cc is None:
        raise RuntimeError("no C compiler (set CC or install gcc)")
    lib = lib_path(directory, name, src, flags)
    err = finish_compile(start_compile(cc, name, src, lib, flags))
    if err:
        raise RuntimeError(err)
    return lib


def _wait_with_progress(procs: list[subprocess.Popen[bytes]], libs: list[Path]) -> None:
    """Wait for the compilers (and background builds of ``libs``), showing the elapsed
    time (a tqdm line on a terminal, a line every 30 s otherwise) so a first run never
    looks hung."""

    start = time.monotonic()
    tty = sys.stderr.isatty()

    def running() -> bool:
        return (any(p.poll() is None for p in procs)
                or any(not lib.exists() and building(lib) for lib in libs))

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
