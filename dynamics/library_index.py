"""Where the compiled library of a small function is, by the function's name and key,
without generating its C source (:func:`~sixplus3.dynamics.codegen.compiled_small`).

A library is named by the hash of its source (``codegen``), and generating the source
needs the symbolic model (about 2.5 s of a command's start-up). The index records, for
a name, a key (e.g. the robot structure's hash) and the :func:`generator_stamp` of the
code that writes the functions, which library that source was compiled into. A changed
generator, CasADi or flag gives another stamp, so a stale library is never found."""

from __future__ import annotations

import hashlib
from pathlib import Path

import casadi as ca

from sixplus3.cache import cached
from sixplus3.fileio import atomic_write


def generator_stamp() -> str:
    """A hash of the code that writes the symbolic functions (every module of
    ``sixplus3.dynamics``, ``kinematics`` and ``robot_description``) and of CasADi's
    version.  About a millisecond, once per process."""
    def make() -> str:
        # deferred: the packages' folders, to hash their sources
        import sixplus3.dynamics
        import sixplus3.kinematics
        import sixplus3.robot_description

        h = hashlib.sha256(str(getattr(ca, "__version__", "")).encode())
        for pkg in (sixplus3.dynamics, sixplus3.kinematics, sixplus3.robot_description):
            for path in sorted(Path(next(iter(pkg.__path__))).glob("*.py")):
                h.update(path.name.encode())
                h.update(path.read_bytes())
        return h.hexdigest()[:16]

    return cached(("generator-stamp", "sixplus3"), make)


def _index_path(name: str, key: str, directory: Path) -> Path:
    digest = hashlib.sha256(f"{name}:{key}:{generator_stamp()}".encode()).hexdigest()[:16]
    return directory / "index" / f"{name}_{digest}.txt"


def lookup(name: str, key: str, directory: Path) -> Path | None:
    """The library recorded for ``name`` and ``key`` in the cache ``directory``, if it
    is there (only a library inside ``directory`` is ever returned)."""
    try:
        lib = Path(_index_path(name, key, directory).read_text().strip())
    except (OSError, UnicodeDecodeError):
        return None
    return lib if lib.parent == directory and lib.is_file() else None


def record(name: str, key: str, directory: Path, lib: Path) -> None:
    """Record ``lib`` for ``name`` and ``key`` (atomically; a read-only cache is left
    as it is: the next process generates the source again)."""
    index = _index_path(name, key, directory)
    try:
        index.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(index, (str(lib) + "\n").encode())
    except OSError:
        pass


__all__ = ["generator_stamp", "lookup", "record"]
