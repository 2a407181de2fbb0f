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
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

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
#: Largest trajectory file read [bytes]: ~143,000 samples (the package writes at most
#: MAX_SAMPLES).  Validating one this size peaks near 1 GB (benchmarks/bench_gate_memory.py;
#: about 1.9 kB per sample above a 0.8 GB base, docs/validation.md "Caps").
MAX_BYTES = 128 << 20
#: Most samples of a motion this package makes (a plan at a rate, its dwells, a slower
#: replay): 2 minutes at 1 kHz.  Estimated before anything is allocated.
MAX_SAMPLES = 120_000
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


def digest(header: dict, body: bytes | memoryview) -> str:
    """The integrity digest of a header (without ``integrity``) and the body bytes."""
    h = {k: v for k, v in header.items() if k != "integrity"}
    sha = hashlib.sha256(_canonical(h))
    sha.update(b"\n")
    sha.update(body)
    return sha.hexdigest()


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


def check_samples(duration: float, rate: float, what: str) -> int:
    """The number of samples of ``duration`` [s] at ``rate`` [Hz], refused (InputError
    naming ``what``) past :data:`MAX_SAMPLES`, before anything is allocated."""
    n = duration * rate + 1 if math.isfinite(duration * rate) else math.inf
    if not n <= MAX_SAMPLES:
        raise InputError(f"{what}: {duration:.6g} s at {rate:g} Hz would make {n:.6g} "
                         f"samples, over the cap of {MAX_SAMPLES} ({MAX_SAMPLES / rate:g} s "
                         "at this rate): shorten it, or plan it in parts", value=n,
                         valid=f"<= {MAX_SAMPLES} samples")
    return int(n)


def samples_fingerprint(t, theta, theta_dot, theta_ddot, rate: float) -> str:
    """SHA-256 of a motion's samples (as float64) and its rate: what a validation report
    records of the motion it judged, and what :func:`write_trajectory` checks."""
    sha = hashlib.sha256(repr(float(rate)).encode())
    for arr in (t, theta, theta_dot, theta_ddot):
        a = np.ascontiguousarray(np.asarray(arr, dtype=np.float64))
        sha.update(repr(a.shape).encode())
        sha.update(a.tobytes())
    return sha.hexdigest()


#: Header fields the writer sets itself; ``meta`` may not name them.
RESERVED = ("format", "rate_hz", "samples", "duration_s", "columns", "units",
            "joint_names", "robot", "limits", "validation", "integrity")


def write_trajectory(path: str | Path, t, theta, theta_dot, theta_ddot, report,
                     robot: Robot, limits: Limits, meta: dict) -> Path:
    """Write the validated trajectory of ``robot`` to ``path`` (one atomic file).

    ``report`` must be the passed :class:`~sixplus3.control.validation.ValidationReport`
    of exactly these samples, at its rate, for this robot (its fingerprint of the
    samples and rate is recomputed here); anything else is refused and nothing is
    written.  :func:`sixplus3.control.validation.validate_and_write` validates and
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
    if not isinstance(meta, dict):
        raise InputError("meta must be a mapping of extra header fields",
                         value=type(meta).__name__, valid="a dict")
    for key in meta:
        if key in RESERVED and not (key == "rate_hz" and meta[key] == rate):
            raise InputError(f"meta may not set the header field {key!r}: the writer sets "
                             "it from the validated samples", value=key,
                             valid=f"any field but {', '.join(RESERVED)}")
    try:
        mine = samples_fingerprint(t, theta, theta_dot, theta_ddot, rate)
    except (TypeError, ValueError) as exc:
        raise InputError(f"the samples are not numeric arrays: {exc}", value=None,
                         valid="(n,) times and (n, 9) arrays") from None
    if rate is None or mine != report.fingerprint:
        raise TrajectoryFileError("refusing to write: the validation report is of other "
                                  "samples or another rate than these",
                                  value=report.fingerprint, valid=mine)
    path = Path(path)
    if path.suffix != SUFFIX:
        raise TrajectoryFileError(f"trajectory files end in {SUFFIX}, got {path.name}",
                                  value=path.name, valid=f"*{SUFFIX}")
    output_path(path.parent, path.stem)  # the name is safe and stays in its directory
    data = samples_array(t, theta, theta_dot, theta_ddot, report.tau, report.position,
                         report.quaternion, report.psi)
    header = {
        "format": FORMAT, "rate_hz": float(rate), "samples": len(t),
        "duration_s": float(t[-1]), "columns": COLUMNS, "units": UNITS,
        "joint_names": JOINTS,
        "robot": {"hash": robot.hash, "parameters": robot.as_dict(),
                  "summary": robot.summary()},
        "limits": limits.as_dict(),
        **{k: v for k, v in meta.items() if k not in RESERVED},
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


#: One number of a sample row: the decimal grammar that C's strtod, numpy and pandas
#: read alike (no underscores, no hex, no inf/nan, no spaces, no leading '+' or '.').
NUMBER = r"-?(?:0|[1-9][0-9]*)(?:\.[0-9]+)?(?:[eE][+-]?[0-9]+)?"
_ROW = re.compile(rb"%s(?:,%s){%d}" % (NUMBER.encode(), NUMBER.encode(), len(COLUMNS) - 1))
#: Deepest nesting of the header JSON (the writer's is 4).
MAX_HEADER_DEPTH = 16
#: Rows parsed per block: the text of a block is the only copy of it in memory.
PARSE_BLOCK = 65536


class _HeaderError(ValueError):
    pass


def _no_constants(token: str) -> float:
    raise _HeaderError(f"{token} is not a number JSON allows")


def _finite_float(token: str) -> float:
    value = float(token)
    if not math.isfinite(value):
        raise _HeaderError(f"{token[:40]} overflows to infinity")
    return value


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _HeaderError(f"the key {key[:40]!r} appears twice")
        out[key] = value
    return out


def parse_header(line: bytes, name: str = "trajectory") -> dict:
    """The header of a trajectory file's first line (without ``# FORMAT ``), parsed one
    way only: JSON without duplicate keys, NaN, Infinity or overflowing numbers, at most
    :data:`MAX_HEADER_DEPTH` deep, and byte for byte the canonical form the writer makes
    (sorted keys, no spaces, shortest round-trip numbers).  So every reader sees the same
    header, and the digest, computed over the canonical form, covers line 1's exact
    bytes."""
    try:
        header = json.loads(line.decode("utf-8"), parse_constant=_no_constants,
                            parse_float=_finite_float, object_pairs_hook=_unique_keys)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        what = "nests too deep" if isinstance(exc, RecursionError) else str(exc)[:120]
        raise TrajectoryFileError(f"{name}: the header is not valid JSON of one meaning "
                                  f"({what})", value=what,
                                  valid="JSON without duplicate keys, NaN or Infinity") \
            from None
    if not isinstance(header, dict):
        raise TrajectoryFileError(f"{name}: the header is not a JSON object",
                                  value=type(header).__name__, valid="an object")
    if fileio.depth(header, MAX_HEADER_DEPTH) > MAX_HEADER_DEPTH:
        raise TrajectoryFileError(f"{name}: the header nests deeper than {MAX_HEADER_DEPTH}",
                                  value=None, valid=f"<= {MAX_HEADER_DEPTH} levels")
    try:
        canonical = _canonical(header)
    except (TypeError, ValueError, RecursionError):
        canonical = b""
    if canonical != line:
        raise TrajectoryFileError(
            f"{name}: line 1 is not the canonical JSON of its header (sorted keys, no "
            "spaces, shortest numbers), so readers could disagree on it: it was not "
            "written by sixplus3, or was edited", value=line[:60],
            valid="the writer's canonical JSON")
    return header


def header_number(header: dict, key: str, name: str, lo: float, hi: float,
                  integer: bool = False) -> float:
    """``header[key]`` as a finite number in [lo, hi] (an int if ``integer``); a
    TrajectoryFileError naming the field and its range otherwise."""
    value = header.get(key)
    ok = (isinstance(value, int) if integer else isinstance(value, (int, float))) \
        and not isinstance(value, bool)
    number = float(value) if ok else math.nan  # type: ignore[arg-type]
    if not lo <= number <= hi:
        kind = "an integer" if integer else "a number"
        raise TrajectoryFileError(f"{name}: header field {key} must be {kind} in "
                                  f"[{lo:g}, {hi:g}], got {fileio.short_repr(value, 60)}",
                                  value=value, valid=f"{kind} in [{lo:g}, {hi:g}]")
    return number


def parse(raw: bytes, name: str = "trajectory") -> tuple[dict, np.ndarray]:
    """Header and samples (n, 47) of a trajectory file's bytes, format-checked and
    integrity-checked (nothing physical: that is the validator's job)."""
    nl = raw.find(b"\n")
    prefix = f"# {FORMAT} ".encode()
    if nl < 0 or not raw.startswith(prefix):
        if raw.startswith(prefix) or raw.startswith(b"# sixplus3-trajectory/2 "):
            why = " (line 1 is cut off: a truncated file)"
        elif raw.startswith(b"t,") or raw.startswith(b"# sixplus3-trajectory/"):
            why = " (an older format: re-plan it)"
        else:
            why = ""
        raise TrajectoryFileError(f"{name}: not a {FORMAT} file{why}",
                                  valid=f"first line '# {FORMAT} {{header}}'", value=raw[:40])
    header = parse_header(raw[len(prefix):nl], name)
    if header.get("format") != FORMAT:
        raise TrajectoryFileError(f"{name}: the header does not declare format {FORMAT}",
                                  value=fileio.short_repr(header.get("format"), 60),
                                  valid=FORMAT)
    body = memoryview(raw)[nl + 1:]  # no copy
    integ = header.get("integrity")
    if not isinstance(integ, dict) or integ.get("algorithm") != "sha256" \
            or not isinstance(integ.get("digest"), str):
        raise TrajectoryFileError(f"{name}: the header has no sha256 integrity digest",
                                  value=fileio.short_repr(integ, 80),
                                  valid="{algorithm: sha256, digest}")
    if digest(header, body) != integ.get("digest"):
        raise TrajectoryFileError(f"{name}: integrity digest mismatch: the header or the "
                                  "samples were edited, truncated or corrupted",
                                  value=integ.get("digest"),
                                  valid="the SHA-256 of the header and samples")
    ncol = len(COLUMNS)
    want = (",".join(COLUMNS) + "\n").encode()
    if bytes(body[:len(want)]) != want:
        raise TrajectoryFileError(f"{name}: line 2 must be the {ncol} column names "
                                  f"{','.join(COLUMNS[:3])},...,{COLUMNS[-1]}",
                                  value=bytes(body[:80]), valid=",".join(COLUMNS))
    n = int(header_number(header, "samples", name, 2, MAX_BYTES // (2 * ncol), True))
    header_number(header, "rate_hz", name, 0.0, 1e9)
    header_number(header, "duration_s", name, 0.0, 1e9)
    if header.get("columns") != COLUMNS:
        raise TrajectoryFileError(f"{name}: header field columns does not match the samples",
                                  value=fileio.short_repr(header.get("columns"), 80),
                                  valid="the 47 column names")
    data = _parse_rows(raw, nl + 1 + len(want), n, name)
    if not math.isclose(float(header["duration_s"]), data[-1, 0], abs_tol=1e-12):
        raise TrajectoryFileError(f"{name}: header duration differs from the last sample",
                                  value=header.get("duration_s"), valid=float(data[-1, 0]))
    return header, data


def _parse_rows(raw: bytes, pos: int, n: int, name: str) -> np.ndarray:
    """The (n, 47) samples of the rows that start at ``raw[pos]``, each ending in a
    newline, parsed block by block: every number must match :data:`NUMBER`."""
    ncol = len(COLUMNS)
    data = np.empty((n, ncol))
    k = 0
    while k < n:
        stop = min(n, k + PARSE_BLOCK)
        lines = []
        for r in range(k, stop):
            e = raw.find(b"\n", pos)
            if e < 0:
                raise TrajectoryFileError(
                    f"{name}: {r} complete sample rows, the header says {n} (a truncated "
                    "file)", value=r, valid=f"{n} rows, each ending in a newline")
            line = raw[pos:e]
            if _ROW.fullmatch(line) is None:
                _bad_row(line, r + 1, name)
            lines.append(line)
            pos = e + 1
        data[k:stop] = np.array(b",".join(lines).split(b","),
                                dtype=np.float64).reshape(stop - k, ncol)
        k = stop
    if pos != len(raw):
        raise TrajectoryFileError(f"{name}: more sample rows than the header's {n}",
                                  value=f"> {n}", valid=f"{n} rows")
    finite = np.isfinite(data)
    if not finite.all():
        r, c = np.argwhere(~finite)[0]
        raise TrajectoryFileError(f"{name}: non-finite value in column {COLUMNS[c]} at sample "
                                  f"{r} (t = {data[r, 0]:g} s)",
                                  value=float(data[r, c]), valid="finite numbers")
    return data


def _bad_row(line: bytes, row: int, name: str) -> None:
    ncol = len(COLUMNS)
    fields = line.split(b",")
    if len(fields) != ncol:
        raise TrajectoryFileError(f"{name}: sample row {row} does not have {ncol} values",
                                  value=row, valid=f"{ncol} values per row")
    num = re.compile(NUMBER.encode())
    c = next(i for i, f in enumerate(fields) if num.fullmatch(f) is None)
    raise TrajectoryFileError(
        f"{name}: sample row {row}, column {COLUMNS[c]}: {fields[c][:40]!r} is not a plain "
        "decimal number (digits, one '.', an exponent; no '_', '+', hex, inf or nan)",
        value=fields[c][:40].decode("ascii", "replace"), valid=NUMBER)


def read_bytes(path: str | Path) -> bytes:
    """The bytes of a trajectory file (at most :data:`MAX_BYTES`)."""
    try:
        return fileio.read_bytes(path, "trajectory file", MAX_BYTES)
    except InputError as exc:
        raise TrajectoryFileError(str(exc), value=exc.value, valid=exc.valid) from None


class TrajectoryData(NamedTuple):
    """A trajectory file as read: ``header`` (the dict of line 1) and ``data`` (the
    (n, 47) samples in :data:`COLUMNS` order).  It unpacks as ``header, data`` and names
    its columns:

    - ``traj["t"]``, ``traj["leg1_B_tau"]``, ``traj["platform_qw"]``: one column (n,);
    - ``traj.t``; ``traj.joints("pos" | "vel" | "acc" | "tau")``: (n, 9) in joint order;
    - ``traj.platform_position`` (n, 3) [m], ``traj.platform_quaternion`` (n, 4)
      (x, y, z, w), ``traj.psi`` (n, 3) [rad];
    - ``traj.to_pandas()``: a DataFrame with the 47 named columns (pandas is optional:
      an InputError says how to install it if it is missing).
    """

    header: dict
    data: np.ndarray

    def __getitem__(self, key):  # type: ignore[override]
        if isinstance(key, str):
            if key not in COLUMNS:
                raise InputError(f"no column {key!r} in a trajectory file", value=key,
                                 valid=f"one of {', '.join(COLUMNS[:3])}, ..., {COLUMNS[-1]}")
            return self.data[:, COLUMNS.index(key)]
        return tuple.__getitem__(self, key)

    @property
    def t(self) -> np.ndarray:
        return self.data[:, 0]

    def joints(self, kind: str) -> np.ndarray:
        return columns(self.data, kind)

    @property
    def platform_position(self) -> np.ndarray:
        return self.data[:, 37:40]

    @property
    def platform_quaternion(self) -> np.ndarray:
        return self.data[:, 40:44]

    @property
    def psi(self) -> np.ndarray:
        return self.data[:, 44:47]

    def to_pandas(self):  # noqa: ANN201 - pandas is optional
        try:
            import pandas as pd
        except ImportError:
            raise InputError("to_pandas needs pandas: pip install pandas", value=None,
                             valid="pandas installed") from None
        return pd.DataFrame(self.data, columns=COLUMNS)


def read_trajectory(path: str | Path, robot: Robot | None = None) -> TrajectoryData:
    """Load, format-check and integrity-check a trajectory made for ``robot`` (default
    ``Robot.default()``): a :class:`TrajectoryData` (``header, data = ...`` unpacks it;
    ``traj["leg0_A_pos"]``, ``traj.joints("tau")`` name the columns).  Raises
    :class:`TrajectoryFileError`.  It checks the format, the digest and the robot, not
    the motion: :func:`sixplus3.validate_file` is the gate."""
    robot = robot or Robot.default()
    raw = read_bytes(path)  # checks that path is a path
    name = Path(path).name
    header, data = parse(raw, name)
    check_robot(header, robot, name)
    return TrajectoryData(header, data)


def columns(data: np.ndarray, kind: str) -> np.ndarray:
    """(M, 9) of 'pos' | 'vel' | 'acc' | 'tau' for the 9 joints in order."""
    k = ("pos", "vel", "acc", "tau").index(kind)
    return data[:, [1 + 4 * j + k for j in range(9)]]
