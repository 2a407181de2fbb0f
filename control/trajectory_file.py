"""Trajectory files for the controller: one file, one atomic unit, one integrity digest.

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
import hashlib
import io
import json
import math
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3 import fileio
from sixplus3.errors import GeometryError, InputError, LimitError, TrajectoryFileError
from sixplus3.fileio import atomic_write
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names

FORMAT = "sixplus3-trajectory/2"
SUFFIX = ".csv"
JOINTS = actuated_joint_names()
COLUMNS = (["t"] + [f"{j}_{k}" for j in JOINTS for k in ("pos", "vel", "acc", "tau")]
           + [f"platform_{c}" for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
           + [f"psi_{i}" for i in range(3)])
UNITS = {"t": "s", "pos": "rad", "vel": "rad/s", "acc": "rad/s^2", "tau": "N m",
         "platform_xyz": "m", "platform_q": "unit quaternion (x, y, z, w)", "psi": "rad"}
#: Largest trajectory file read [bytes] (~40 min at 1 kHz).
MAX_BYTES = 1 << 30
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


def _canonical(header: dict) -> bytes:
    return json.dumps(header, sort_keys=True, separators=(",", ":"), allow_nan=False,
                      default=_jsonable).encode()


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return str(obj)


def _finite_tree(obj: Any) -> Any:
    """The header with non-finite floats as null (JSON has no NaN)."""
    if isinstance(obj, dict):
        return {str(k): _finite_tree(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_tree(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _finite_tree(obj.tolist())
    if isinstance(obj, np.generic):
        return _finite_tree(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def digest(header: dict, body: bytes) -> str:
    """The integrity digest of a header (without ``integrity``) and the body bytes."""
    h = {k: v for k, v in header.items() if k != "integrity"}
    return hashlib.sha256(_canonical(h) + b"\n" + body).hexdigest()


def encode(header: dict, data: np.ndarray) -> bytes:
    """The bytes of a trajectory file: header line (with its digest), columns, rows."""
    buf = io.StringIO()
    np.savetxt(buf, data, delimiter=",", header=",".join(COLUMNS), comments="", fmt="%.17g")
    body = buf.getvalue().encode()
    header = _finite_tree({k: v for k, v in header.items() if k != "integrity"})
    header["integrity"] = {"algorithm": "sha256", "digest": digest(header, body)}
    first = f"# {FORMAT} ".encode() + _canonical(header) + b"\n"
    return first + body


def samples_array(t, theta, theta_dot, theta_ddot, tau, position, quaternion,
                  psi) -> np.ndarray:
    """(n, 47) rows in :data:`COLUMNS` order."""
    n = len(t)
    data = np.zeros((n, len(COLUMNS)))
    data[:, 0] = t
    for j in range(9):
        data[:, 1 + 4 * j:5 + 4 * j] = np.c_[theta[:, j], theta_dot[:, j], theta_ddot[:, j],
                                             tau[:, j]]
    data[:, 37:40] = position
    data[:, 40:44] = quaternion
    data[:, 44:47] = psi
    return data


# ----------------------------------------------------------------------------- writing
@contextlib.contextmanager
def _exclusive(path: Path) -> Iterator[None]:
    """An exclusive, non-blocking lock on ``path``'s name (a lock file beside it)."""
    lock = path.with_name(f".{path.name}.lock")
    fd = os.open(lock, os.O_CREAT | os.O_RDWR, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise TrajectoryFileError(
                f"another process is writing {path.name} right now; it wins, this write "
                "was abandoned (the file it leaves is complete)",
                value=path.name, valid="one writer at a time") from None
        yield
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


def write_trajectory(path: str | Path, t, theta, theta_dot, theta_ddot, report,
                     robot: Robot, limits: Limits, meta: dict) -> Path:
    """Write the validated trajectory of ``robot`` to ``path`` (one atomic file).

    ``report`` is the :class:`~sixplus3.control.validation.ValidationReport` of exactly
    these samples for this robot; a failed or missing report is refused and nothing is
    written.  ``meta`` adds header fields (task, planner, smoothing statistics).
    """
    if report is None or not report.ok:
        reasons = "; ".join(report.messages()) if report is not None else "not validated"
        raise TrajectoryFileError(f"refusing to write an invalid trajectory: {reasons}",
                                  value=reasons, valid="a passed validation report")
    if report.robot_hash != robot.hash:
        raise TrajectoryFileError("refusing to write: the validation report is for another "
                                  "robot", value=report.robot_hash, valid=robot.hash)
    path = Path(path)
    if path.suffix != SUFFIX:
        raise TrajectoryFileError(f"trajectory files end in {SUFFIX}, got {path.name}",
                                  value=path.name, valid=f"*{SUFFIX}")
    output_path(path.parent, path.stem)  # the name is safe and stays in its directory
    data = samples_array(t, theta, theta_dot, theta_ddot, report.tau, report.position,
                         report.quaternion, report.psi)
    rate = float(meta.get("rate_hz", 0.0))
    header = {
        "format": FORMAT, "rate_hz": rate, "samples": len(t),
        "duration_s": float(t[-1]), "columns": COLUMNS, "units": UNITS,
        "joint_names": JOINTS,
        "robot": {"hash": robot.hash, "parameters": robot.as_dict(),
                  "summary": robot.summary()},
        "limits": limits.as_dict(),
        **{k: v for k, v in meta.items() if k not in ("rate_hz", "robot", "limits")},
        "validation": report.summary(),
    }
    blob = encode(header, data)
    path.parent.mkdir(parents=True, exist_ok=True)
    with _exclusive(path):
        write_atomically(path, blob)
    return path


# ----------------------------------------------------------------------------- reading
def check_robot(header: dict, robot: Robot, name: str) -> None:
    """Refuse a header whose robot is not ``robot`` (or whose parameters do not give its
    recorded hash)."""
    rec = header.get("robot")
    if not isinstance(rec, dict) or not isinstance(rec.get("parameters"), dict):
        raise TrajectoryFileError(f"{name}: the header records no robot parameters",
                                  value=None, valid="robot.parameters in the header")
    try:
        recorded = Robot.from_dict(rec["parameters"])
    except (GeometryError, LimitError, TypeError, ValueError) as exc:
        raise TrajectoryFileError(f"{name}: the recorded robot is invalid: {exc}",
                                  value=rec.get("parameters"),
                                  valid="valid robot parameters") from exc
    if recorded.hash != rec.get("hash"):
        raise TrajectoryFileError(f"{name}: the recorded robot parameters do not match the "
                                  "recorded robot hash (an edited header, or a file of an "
                                  "older sixplus3 whose robot had fewer parameters: "
                                  "re-plan it)",
                                  value=rec.get("hash"), valid=recorded.hash)
    if recorded.hash != robot.hash:
        diff = _robot_diff(recorded.as_dict(), robot.as_dict())
        raise TrajectoryFileError(
            f"robot mismatch: {name} was made for robot {recorded.hash[:12]}, not for "
            f"{robot.hash[:12]} ({diff}); re-plan for this robot",
            value=recorded.hash, valid=robot.hash)


def _robot_diff(a: dict, b: dict, where: str = "") -> str:
    """The first parameter that differs between two robot dicts."""
    for k in sorted(set(a) | set(b)):
        if k == "name":
            continue
        va, vb = a.get(k), b.get(k)
        if isinstance(va, dict) and isinstance(vb, dict):
            d = _robot_diff(va, vb, f"{where}{k}.")
            if d:
                return d
        elif va != vb:
            return f"{where}{k}: file {va!r}, robot {vb!r}"
    return ""


def _no_constants(token: str) -> float:
    raise ValueError(f"{token} is not a number JSON allows")


def parse(raw: bytes, name: str = "trajectory") -> tuple[dict, np.ndarray]:
    """Header and samples (n, 47) of a trajectory file's bytes, format-checked and
    integrity-checked (nothing physical: that is the validator's job)."""
    nl = raw.find(b"\n")
    prefix = f"# {FORMAT} ".encode()
    if nl < 0 or not raw.startswith(prefix):
        old = raw.startswith(b"t,") or raw.startswith(b"# sixplus3-trajectory/")
        raise TrajectoryFileError(
            f"{name}: not a {FORMAT} file" + (" (an older format: re-plan it)" if old else ""),
            valid=f"first line '# {FORMAT} {{header}}'", value=raw[:40])
    try:
        header = json.loads(raw[len(prefix):nl].decode("utf-8"), parse_constant=_no_constants)
    except (UnicodeDecodeError, ValueError) as exc:
        raise TrajectoryFileError(f"{name}: the header is not valid JSON ({str(exc)[:120]})",
                                  value=str(exc)[:120], valid="JSON without NaN/Infinity") \
            from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise TrajectoryFileError(f"{name}: the header does not declare format {FORMAT}",
                                  value=header.get("format") if isinstance(header, dict) else None,
                                  valid=FORMAT)
    body = raw[nl + 1:]
    integ = header.get("integrity")
    if not isinstance(integ, dict) or integ.get("algorithm") != "sha256":
        raise TrajectoryFileError(f"{name}: the header has no sha256 integrity digest",
                                  value=integ, valid="{algorithm: sha256, digest}")
    if digest(header, body) != integ.get("digest"):
        raise TrajectoryFileError(f"{name}: integrity digest mismatch: the header or the "
                                  "samples were edited, truncated or corrupted",
                                  value=integ.get("digest"),
                                  valid="the SHA-256 of the header and samples")
    try:
        text = body.decode("ascii")
    except UnicodeDecodeError:
        raise TrajectoryFileError(f"{name}: the samples are not plain ASCII numbers",
                                  value=None, valid="ASCII numbers") from None
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    if not lines or lines[0].split(",") != COLUMNS:
        raise TrajectoryFileError(f"{name}: line 2 must be the {len(COLUMNS)} column names "
                                  f"{','.join(COLUMNS[:3])},...,{COLUMNS[-1]}",
                                  value=lines[0][:80] if lines else None,
                                  valid=",".join(COLUMNS))
    rows = lines[1:]
    if len(rows) < 2:
        raise TrajectoryFileError(f"{name}: {len(rows)} samples; a trajectory has >= 2",
                                  value=len(rows), valid=">= 2 samples")
    ncol = len(COLUMNS)
    bad = next((k for k, r in enumerate(rows) if r.count(",") != ncol - 1), None)
    if bad is not None:
        raise TrajectoryFileError(f"{name}: sample row {bad + 1} does not have {ncol} values",
                                  value=bad + 1, valid=f"{ncol} values per row")
    try:
        data = np.array(",".join(rows).split(","), dtype=np.float64).reshape(len(rows), ncol)
    except ValueError as exc:
        raise TrajectoryFileError(f"{name}: unreadable number ({str(exc)[:80]})",
                                  value=str(exc)[:80], valid="numbers") from None
    finite = np.isfinite(data)
    if not finite.all():
        r, c = np.argwhere(~finite)[0]
        raise TrajectoryFileError(f"{name}: non-finite value in column {COLUMNS[c]} at sample "
                                  f"{r} (t = {data[r, 0]:g} s)",
                                  value=float(data[r, c]), valid="finite numbers")
    for key, want in (("samples", len(rows)), ("columns", COLUMNS)):
        if header.get(key) != want:
            raise TrajectoryFileError(f"{name}: header field {key} does not match the samples",
                                      value=header.get(key), valid="consistent with the samples")
    if not math.isclose(float(header.get("duration_s", -1)), data[-1, 0], abs_tol=1e-12):
        raise TrajectoryFileError(f"{name}: header duration differs from the last sample",
                                  value=header.get("duration_s"), valid=float(data[-1, 0]))
    return header, data


def read_bytes(path: str | Path) -> bytes:
    """The bytes of a trajectory file (at most :data:`MAX_BYTES`)."""
    try:
        return fileio.read_bytes(path, "trajectory file", MAX_BYTES)
    except InputError as exc:
        raise TrajectoryFileError(str(exc), value=exc.value, valid=exc.valid) from None


def read_trajectory(path: str | Path, robot: Robot | None = None) -> tuple[dict, np.ndarray]:
    """Load, format-check and integrity-check a trajectory made for ``robot`` (default
    ``Robot.default()``); raises :class:`TrajectoryFileError`."""
    robot = robot or Robot.default()
    name = Path(path).name
    header, data = parse(read_bytes(path), name)
    check_robot(header, robot, name)
    return header, data


def columns(data: np.ndarray, kind: str) -> np.ndarray:
    """(M, 9) of 'pos' | 'vel' | 'acc' | 'tau' for the 9 joints in order."""
    k = ("pos", "vel", "acc", "tau").index(kind)
    return data[:, [1 + 4 * j + k for j in range(9)]]
