"""Trajectory files for the controller: one file, one atomic unit, one integrity digest.

Four modules: :mod:`~sixplus3.control.file.file_format` (names, columns, the canonical
header and the digest), :mod:`~sixplus3.control.file.trajectory_parse` (reading the bytes one
way only), :mod:`~sixplus3.control.file.trajectory_read` (reading a file for a robot) and
this one (writing).  Each name is imported from its own module.

Layout (UTF-8 text; docs/validation.md is the contract)::

    # sixplus3-trajectory/2 {"format": ..., "rate_hz": ..., "robot": {...}, ...}
    t,leg0_A_pos,leg0_A_vel,leg0_A_acc,leg0_A_tau,...,platform_x,...,psi_2
    0,1.2,0,0,0.31,...

- line 1: ``# `` + :data:`FORMAT` + one space + the header, one line of JSON: rate,
  samples, duration, columns, units, joint names, the full robot (parameters + hash),
  the limits planned to, the task, planner and smoothing statistics, the validation
  summary, and ``integrity``: the SHA-256 of the canonical header (sorted keys, no
  ``integrity``) + ``"\\n"`` + every byte after line 1.  Editing any field or sample
  breaks it.  It detects corruption and accidental edits; it is not a signature, so
  the validator trusts nothing in the file and recomputes everything.
- line 2: the column names (:data:`COLUMNS`); then one row per sample: ``t`` [s]; for
  each actuated joint J (URDF names, legs 0..2, each A, B, C): ``J_pos`` [rad],
  ``J_vel`` [rad/s], ``J_acc`` [rad/s^2], ``J_tau`` (feed-forward torque [N m]); the
  platform pose ``platform_x/y/z`` [m], ``platform_qx/qy/qz/qw``; the crank angles
  ``psi_0..2`` [rad].  ``numpy.loadtxt(path, delimiter=",", skiprows=2)`` or
  ``pandas.read_csv(path, comment="#")`` read it.

Writing (:func:`write_trajectory`) refuses a trajectory whose validation failed, takes
an exclusive lock per output name (a second concurrent writer gets a
:class:`TrajectoryFileError`; the first wins), writes a temporary file in the same
directory, fsyncs it, renames it over the old one and fsyncs the directory: at any
instant the name holds the old complete file or the new complete file, whatever kills
the writer (SIGKILL, a full disk).  Output names are made safe first (:func:`safe_name`).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import io
import os
import re
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sixplus3.control.file.file_format import (
    _JOINT_COLUMNS,
    COLUMNS,
    FORMAT,
    JOINTS,
    PLATFORM_BLOCKS,
    SUFFIX,
    UNITS,
    _canonical,
    _finite_tree,
    digest,
)
from sixplus3.errors import InputError, TrajectoryFileError
from sixplus3.fileio import atomic_write
from sixplus3.motion import Motion
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

if TYPE_CHECKING:
    from sixplus3.control.report import ValidationReport

#: Longest output name [characters].
MAX_NAME = 100
_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


def safe_name(name: object) -> str:
    """An output name that cannot leave its directory: characters outside
    ``[A-Za-z0-9._-]`` become ``_``, leading and trailing dots and underscores go.
    Raises :class:`TrajectoryFileError` if nothing is left or the name is over
    :data:`MAX_NAME` characters."""
    if not isinstance(name, str) or "\x00" in name:
        raise TrajectoryFileError(f"output name {name!r} must be text without NUL",
                                  value=name, valid="[A-Za-z0-9._-], 1-100 characters")
    slug = _SAFE.sub("_", name).strip("._")
    if not slug or len(slug) > MAX_NAME:
        raise TrajectoryFileError(
            f"output name {name[:120]!r} gives {slug[:120]!r}: must have 1 to {MAX_NAME} of "
            "the characters A-Z a-z 0-9 . _ - (not only dots)", value=name,
            valid=f"1-{MAX_NAME} characters [A-Za-z0-9._-]")
    return slug


def output_path(out_dir: str | Path, name: str, suffix: str = SUFFIX) -> Path:
    """``out_dir / (safe_name(name) + suffix)``, checked to lie inside ``out_dir``."""
    out = Path(out_dir)
    path = out / (safe_name(name) + suffix)
    if path.resolve().parent != out.resolve():
        raise TrajectoryFileError(f"output {path} would leave {out}", value=name,
                                  valid=f"a file directly in {out}")
    return path


def encode(header: dict[str, Any], data: np.ndarray) -> bytes:
    """The bytes of a trajectory file: header line (with its digest), columns, rows."""
    buf = io.StringIO()
    np.savetxt(buf, data, delimiter=",", header=",".join(COLUMNS), comments="", fmt="%.17g")
    body = buf.getvalue().encode()
    header = _finite_tree({k: v for k, v in header.items() if k != "integrity"})
    header["integrity"] = {"algorithm": "sha256", "digest": digest(header, body)}
    first = f"# {FORMAT} ".encode() + _canonical(header) + b"\n"
    return first + body


def samples_array(motion: Motion, tau: np.ndarray, position: np.ndarray,
                  quaternion: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """(n, 47) rows in :data:`COLUMNS` order."""
    data = np.zeros((len(motion), len(COLUMNS)))
    data[:, 0] = motion.t
    for kind, values in (("pos", motion.theta), ("vel", motion.theta_dot),
                         ("acc", motion.theta_ddot), ("tau", tau)):
        data[:, _JOINT_COLUMNS[kind]] = values
    for kind, values in (("position", position), ("quaternion", quaternion), ("psi", psi)):
        data[:, PLATFORM_BLOCKS[kind]] = values
    return data


# ----------------------------------------------------------------------------- writing
@contextlib.contextmanager
def _exclusive(path: Path) -> Iterator[None]:
    """An exclusive, non-blocking lock on ``path``'s name: a lock file beside it, opened
    without following a link (a planted link is refused), removed when the write is done
    (so no lock file is left behind)."""
    lock = path.with_name(f".{path.name}.lock")
    try:
        fd = os.open(lock, os.O_CREAT | os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise TrajectoryFileError(f"{lock} is a link: refusing to write through it",
                                      value=str(lock), valid="no link at the lock's name") \
                from None
        raise
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise TrajectoryFileError(f"{lock} is not a regular file", value=str(lock),
                                      valid="a regular lock file or nothing")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise TrajectoryFileError(
                f"another process is writing {path.name} right now; it wins, this write "
                "was abandoned (the file it leaves is complete)",
                value=path.name, valid="one writer at a time") from None
        try:
            yield
        finally:
            # still holding the lock: a writer that opened this file meanwhile fails its
            # flock; one that opens the name after this gets a new file
            with contextlib.suppress(OSError):
                if os.path.samestat(os.fstat(fd), os.lstat(lock)):
                    os.unlink(lock)
    finally:
        os.close(fd)


def write_atomically(path: Path, data: bytes) -> None:
    """Replace ``path`` by ``data`` as one unit (:func:`sixplus3.fileio.atomic_write`);
    an error leaves the old file untouched and is reported as a TrajectoryFileError."""
    try:
        atomic_write(path, data)
    except OSError as exc:
        what = "the disk is full" if exc.errno == errno.ENOSPC else (exc.strerror or str(exc))
        raise TrajectoryFileError(f"cannot write {path}: {what}; the previous file, if any, "
                                  "is unchanged",
                                  value=str(path),
                                  valid="a writable directory with free space") from None


#: Limits of the header the gate reports but does not enforce at the samples.
REPORTED_ONLY = ("torque_rate",)
#: Header fields the writer sets itself; ``meta`` may not name them.
RESERVED = ("format", "rate_hz", "samples", "duration_s", "columns", "units",
            "joint_names", "robot", "limits", "limits_reported_only", "validation",
            "integrity")


def write_trajectory(path: str | Path, motion: Motion, report: ValidationReport,
                     robot: Robot, limits: Limits, meta: dict[str, Any]) -> Path:
    """Write the validated ``motion`` of ``robot`` to ``path`` (one atomic file).

    ``report`` must be the passed :class:`~sixplus3.control.report.ValidationReport`
    of exactly this motion, at its rate, for this robot (the fingerprints of the
    samples and rate must agree); anything else is refused and nothing is
    written.  :func:`sixplus3.control.gate.validation.validate_and_write` validates and
    writes in one call.  ``meta`` adds header fields (task, planner, smoothing
    statistics); it may not set the fields the writer owns (:data:`RESERVED`), except
    ``rate_hz`` equal to the validated rate.
    """
    if report is None or not getattr(report, "ok", False):
        reasons = "; ".join(report.messages()) if report is not None else "not validated"
        raise TrajectoryFileError(f"refusing to write an invalid trajectory: {reasons}",
                                  value=reasons, valid="a passed validation report")
    if report.robot_hash != robot.hash:
        raise TrajectoryFileError("refusing to write: the validation report is for another "
                                  "robot", value=report.robot_hash, valid=robot.hash)
    rate = report.rate_hz
    tau, position, quaternion, psi = report.tau, report.position, report.quaternion, report.psi
    if rate is None or tau is None or position is None or quaternion is None or psi is None:
        raise TrajectoryFileError("refusing to write: the validation report has no rate, "
                                  "torques or platform poses of its samples", value=None,
                                  valid="a report of validate_motion")
    if not isinstance(meta, dict):
        raise InputError("meta must be a mapping of extra header fields",
                         value=type(meta).__name__, valid="a dict")
    for key in meta:
        if key in RESERVED and not (key == "rate_hz" and meta[key] == rate):
            raise InputError(f"meta may not set the header field {key!r}: the writer sets "
                             "it from the validated samples", value=key,
                             valid=f"any field but {', '.join(RESERVED)}")
    if not isinstance(motion, Motion):
        raise InputError("write_trajectory takes the validated Motion",
                         value=type(motion).__name__, valid="a sixplus3.motion.Motion")
    mine = motion.fingerprint
    if mine != report.fingerprint:
        raise TrajectoryFileError("refusing to write: the validation report is of other "
                                  "samples or another rate than these",
                                  value=report.fingerprint, valid=mine)
    path = Path(path)
    if path.suffix != SUFFIX:
        raise TrajectoryFileError(f"trajectory files end in {SUFFIX}, got {path.name}",
                                  value=path.name, valid=f"*{SUFFIX}")
    output_path(path.parent, path.stem)  # the name is safe and stays in its directory
    data = samples_array(motion, tau, position, quaternion, psi)
    header = {
        "format": FORMAT, "rate_hz": float(rate), "samples": len(motion),
        "duration_s": motion.duration, "columns": COLUMNS, "units": UNITS,
        "joint_names": JOINTS,
        "robot": {"hash": robot.hash, "parameters": robot.as_dict(),
                  "summary": robot.summary()},
        "limits": limits.as_dict(),
        # what the gate does with each: torque_rate is the planner's bound between its
        # own nodes; the gate reports it between samples and does not enforce it there
        "limits_reported_only": list(REPORTED_ONLY),
        **{k: v for k, v in meta.items() if k not in RESERVED},
        "validation": report.summary(),
    }
    blob = encode(header, data)
    path.parent.mkdir(parents=True, exist_ok=True)
    with _exclusive(path):
        write_atomically(path, blob)
    return path


