"""Drive logs: what the robot's drives measured, for identification and the wrench.

The log format (docs/identification.md, "Logs"): a CSV text file.

- Lines starting with ``#`` are comments.  A comment ``# sixplus3-log/1 {...}`` (canonical
  JSON) may carry ``rate_hz``, ``robot_kinematics`` (:func:`kinematic_hash` of the robot
  the log was taken on) and free notes; a log whose ``robot_kinematics`` differs from the
  robot it is read for is refused (a log from another robot).
- The first other row names the columns: ``t`` [s], and per actuated joint (legs 0..2,
  each A, B, C, as in the trajectory files) either joint-side units,
  ``{joint}_pos`` [rad] and ``{joint}_tau`` [N m at the joint: what the drive applied],
  optional ``{joint}_vel`` [rad/s]; or the drive's own units, as the drive table of
  ``sixplus3 export --format drive-csv`` writes them: ``{joint}_counts`` (motor encoder
  counts), ``{joint}_torque_0p1pct`` (0.1 % of the motor's rated torque), optional
  ``{joint}_counts_per_s``, converted with ``Robot.motors`` (belt ratio, encoder bits,
  zero offsets, directions, rated torque).
- Every other row: one number per column, in the files' strict decimal grammar.

Time must start at 0 or later, increase on a uniform grid (the rate; at most 1 % jitter
of a period, no gaps) and the log must hold at least :data:`MIN_SAMPLES` samples.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.file.trajectory_parse import NUMBER, json_one_meaning
from sixplus3.errors import InputError
from sixplus3.fileio import atomic_write, read_bytes, short_repr
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names

FORMAT = "sixplus3-log/1"
JOINTS = tuple(actuated_joint_names())
#: Largest log read [bytes] (a 10 min log at 1 kHz is ~ 110 MB).
MAX_BYTES = 256 << 20
#: Fewest samples a log may hold.
MIN_SAMPLES = 200
#: Largest jitter of the time grid, as a fraction of a period.
JITTER = 0.01
_NUM = re.compile(NUMBER)


@dataclass
class DriveLog:
    """A log in joint-side SI units: t (n,), theta (n, 9), tau (n, 9), theta_dot (n, 9)
    or None; ``meta`` the log's own comment header."""

    t: np.ndarray
    theta: np.ndarray
    tau: np.ndarray
    theta_dot: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    name: str = "log"
    #: (n, 9) the motors' raw encoder counts, when the log is in the drive's units
    counts: np.ndarray | None = None

    @property
    def rate(self) -> float:
        return float((len(self.t) - 1) / (self.t[-1] - self.t[0]))

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])


def kinematic_hash(robot: Robot) -> str:
    """The robot's identity for logs: geometry, assembly mode, drive train, zero offsets
    and directions (what maps the drives' readings to joint angles), not its masses or
    friction, which identification changes."""
    d = robot.as_dict()
    doc = {"geometry": d["geometry"], "mode": d["mode"],
           "motors": {k: d["motors"][k] for k in ("model", "zero_offsets", "directions")}}
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _bad(name: str, msg: str, valid: str, value: object = None) -> InputError:
    return InputError(f"{name}: {msg}", value=value, valid=valid)


def parse_log(raw: bytes, robot: Robot, name: str = "log") -> DriveLog:
    """A :class:`DriveLog` from the bytes of a log file (module doc); InputError naming
    what is wrong and the valid range otherwise."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise _bad(name, "not UTF-8 text", "a UTF-8 CSV text file") from None
    meta, header, rows = _lines(text, name)
    cols, joint_units = _columns(header, name)
    if len(rows) < MIN_SAMPLES:
        raise _bad(name, f"{len(rows)} samples, too short", f">= {MIN_SAMPLES} samples",
                   len(rows))
    data = _numbers(rows, header, name)
    t = data[:, cols["t"]]
    _time_grid(t, meta, name)
    kin = meta.get("robot_kinematics")
    if kin is not None and kin != kinematic_hash(robot):
        raise _bad(name, f"taken on another robot (kinematics {short_repr(kin, 20)}, this "
                   f"robot's {kinematic_hash(robot)})", "a log of this robot's "
                   "geometry, drive train, offsets and directions")
    theta = np.c_[[data[:, cols[f"{j}_{'pos' if joint_units == 'pos' else 'counts'}"]]
                   for j in JOINTS]].T
    tau = np.c_[[data[:, cols[f"{j}_{'tau' if joint_units == 'pos' else 'torque_0p1pct'}"]]
                 for j in JOINTS]].T
    vcol = "vel" if joint_units == "pos" else "counts_per_s"
    vel = (np.c_[[data[:, cols[f"{j}_{vcol}"]] for j in JOINTS]].T
           if all(f"{j}_{vcol}" in cols for j in JOINTS) else None)
    counts = None
    if joint_units == "counts":
        if np.any(theta != np.rint(theta)) or np.abs(theta).max() > 2.0**62:
            raise _bad(name, "an encoder count is not a whole number", "integer counts")
        counts = theta.astype(np.int64)
        theta, vel, tau = from_drive_units(robot, theta, vel, tau)
    return DriveLog(t=t, theta=theta, tau=tau, theta_dot=vel, meta=meta, name=name,
                    counts=counts)


def _lines(text: str, name: str) -> tuple[dict[str, Any], list[str], list[str]]:
    """(the format comment's mapping, the column names, the data rows) of a log's text."""
    meta: dict[str, Any] = {}
    rows: list[str] = []
    header: list[str] | None = None
    for ln, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            body = s[1:].strip()
            if body.startswith(FORMAT):
                try:
                    meta = json_one_meaning(body[len(FORMAT):].strip() or "{}")
                except (ValueError, RecursionError) as exc:
                    raise _bad(name, f"line {ln}: the {FORMAT} comment is not JSON of one "
                               f"meaning ({str(exc)[:80]})",
                               "JSON without duplicate keys, NaN or Infinity") from None
                if not isinstance(meta, dict):
                    raise _bad(name, f"line {ln}: the {FORMAT} comment is not a mapping",
                               "a JSON object")
            continue
        if header is None:
            header = [c.strip() for c in s.split(",")]
            continue
        rows.append(s)
    if header is None:
        raise _bad(name, "no column names", "a row naming the columns")
    return meta, header, rows


def _columns(header: list[str], name: str) -> tuple[dict[str, int], str]:
    """(each column's index, the joints' units: "pos" or "counts"), every column known
    and every needed one there."""
    cols = {c: i for i, c in enumerate(header)}
    if len(cols) != len(header):
        raise _bad(name, "a column is named twice", "unique column names")
    known = {"t"} | {f"{j}_{k}" for j in JOINTS for k in
                     ("pos", "vel", "tau", "counts", "counts_per_s", "torque_0p1pct")}
    unknown = [c for c in header if c not in known]
    if unknown:
        raise _bad(name, f"unknown column {short_repr(unknown[0], 40)}",
                   "t and per joint (leg0_A .. leg2_C) _pos, _tau, optional _vel; or "
                   "_counts, _torque_0p1pct, optional _counts_per_s", unknown[0])
    joint_units = "pos" if any(c.endswith("_pos") for c in header) else "counts"
    need = ["t"] + [f"{j}_{'pos' if joint_units == 'pos' else 'counts'}" for j in JOINTS] \
        + [f"{j}_{'tau' if joint_units == 'pos' else 'torque_0p1pct'}" for j in JOINTS]
    missing = [c for c in need if c not in cols]
    if missing:
        raise _bad(name, f"missing column {missing[0]} (a log has all nine joints, in one "
                   "kind of units)", "t, 9 positions and 9 torques", missing[0])
    return cols, joint_units


def _numbers(rows: list[str], header: list[str], name: str) -> np.ndarray:
    """The rows' values, each a decimal number (no NaN, inf or other spellings)."""
    width = len(header)
    data = np.empty((len(rows), width))
    for k, row in enumerate(rows):
        fields = row.split(",")
        if len(fields) != width:
            raise _bad(name, f"row {k + 1} has {len(fields)} values", f"{width} values")
        for c, f in enumerate(fields):
            f = f.strip()
            if not _NUM.fullmatch(f):
                raise _bad(name, f"row {k + 1}, column {header[c]}: {short_repr(f, 30)} is "
                           "not a number (NaN, inf and other spellings are refused)",
                           "a decimal number", f[:30])
            data[k, c] = float(f)
    if not np.all(np.isfinite(data)):
        raise _bad(name, "a value is out of range", "finite numbers")
    return data


def _time_grid(t: np.ndarray, meta: dict[str, Any], name: str) -> None:
    """The times increase on a uniform grid that matches the header's rate."""
    dt = np.diff(t)
    if t[0] < 0 or np.any(dt <= 0):
        k = int(np.argmax(dt <= 0)) + 1 if np.any(dt <= 0) else 0
        raise _bad(name, f"time does not increase at row {k + 1}", "t >= 0, increasing")
    period = float(np.median(dt))
    jitter = np.abs(dt - period)
    if jitter.max() > JITTER * period:
        k = int(np.argmax(jitter))
        raise _bad(name, f"the time grid has a gap or jitter at t = {t[k]:.6f} s "
                   f"({dt[k]:.6g} s after the previous sample, period {period:.6g} s)",
                   f"a uniform grid (jitter <= {JITTER:g} of a period)", float(dt[k]))
    if "rate_hz" in meta and not (isinstance(meta["rate_hz"], (int, float))
                                  and abs(meta["rate_hz"] * period - 1.0) < 1e-3):
        raise _bad(name, f"its header says {meta['rate_hz']!r} Hz, its times "
                   f"{1 / period:.6g} Hz", "a header rate that matches the times")


def counts_per_rad(robot: Robot) -> float:
    """Motor encoder counts per radian of the joint (the belt ratio times the counts of
    a motor turn over 2 pi)."""
    m = robot.motors
    return float(m.gear_ratio * 2 ** m.encoder_bits / (2 * math.pi))


def to_drive_units(robot: Robot, theta: np.ndarray, theta_dot: np.ndarray | None,
                   tau: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The drive's own integer units of joint-side samples: (position counts, velocity
    counts/s or None, torque in 0.1 % of the motor's rated torque), each int64, through
    the robot's belt ratio, encoder, zero offsets and directions."""
    m = robot.motors
    d = np.asarray(m.directions, dtype=float)
    k = counts_per_rad(robot)
    counts = np.rint(d * (np.asarray(theta) - np.asarray(m.zero_offsets)) * k).astype(np.int64)
    vel = (None if theta_dot is None
           else np.rint(d * np.asarray(theta_dot) * k).astype(np.int64))
    torque = np.rint(1000.0 * d * np.asarray(tau) / (m.gear_ratio * m.rated_torque)
                     ).astype(np.int64)
    return counts, vel, torque


def from_drive_units(robot: Robot, counts: np.ndarray, counts_per_s: np.ndarray | None,
                     torque: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Joint-side (theta, theta_dot, tau) of the drive's units (the inverse of
    :func:`to_drive_units`)."""
    m = robot.motors
    d = np.asarray(m.directions, dtype=float)
    k = m.gear_ratio * 2 ** m.encoder_bits / (2 * math.pi)
    theta = d * counts / k + np.asarray(m.zero_offsets)
    vel = None if counts_per_s is None else d * counts_per_s / k
    tau = d * torque * m.gear_ratio * m.rated_torque / 1000.0
    return theta, vel, tau


def read_log(path: str | Path, robot: Robot) -> DriveLog:
    """The log at ``path`` (CSV, module doc; a directory: a rosbag2 bag, its
    ``/joint_states`` with efforts)."""
    p = Path(path)
    if p.is_dir():
        return read_bag_log(p, robot)
    return parse_log(read_bytes(p, "log", MAX_BYTES), robot, p.name)


def read_bag_log(path: Path, robot: Robot, topic: str = "/joint_states") -> DriveLog:
    """A log from a rosbag2 bag's ``sensor_msgs/JointState`` messages (positions and
    efforts of the nine actuated joints by name; stamps from the headers)."""
    try:
        # deferred: rosbags (optional) loads only when this runs
        from rosbags.highlevel import AnyReader
    except ImportError:  # pragma: no cover - depends on the install
        raise InputError("reading bags needs rosbags: pip install 'sixplus3[ros]'",
                         value="rosbags", valid="rosbags installed") from None
    t, th, tau = [], [], []
    try:
        with AnyReader([path]) as reader:
            conns = [c for c in reader.connections if c.topic == topic]
            if not conns:
                raise InputError(f"{path.name}: no {topic} topic", value=topic,
                                 valid="a bag with sensor_msgs/JointState")
            for conn, _ts, raw in reader.messages(connections=conns):
                msg: Any = reader.deserialize(raw, conn.msgtype)
                idx = {n: i for i, n in enumerate(msg.name)}
                if not all(j in idx for j in JOINTS) or len(msg.effort) != len(msg.name):
                    raise InputError(f"{path.name}: a JointState without the nine actuated "
                                     "joints' positions and efforts", value=None,
                                     valid="positions and efforts of leg0_A .. leg2_C")
                t.append(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec)
                th.append([msg.position[idx[j]] for j in JOINTS])
                tau.append([msg.effort[idx[j]] for j in JOINTS])
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged bag: one line
        raise InputError(f"{path.name}: not a readable rosbag2 bag ({type(exc).__name__})",
                         value=str(path), valid="a rosbag2 directory") from None
    rows = ["t," + ",".join(f"{j}_pos" for j in JOINTS) + "," + ",".join(
        f"{j}_tau" for j in JOINTS)]
    t0 = t[0] if t else 0.0
    for k in range(len(t)):
        rows.append(",".join(repr(float(x)) for x in [t[k] - t0, *th[k], *tau[k]]))
    return parse_log(("\n".join(rows) + "\n").encode(), robot, path.name)


def write_log(path: str | Path, log: DriveLog, robot: Robot,
              notes: dict[str, Any] | None = None, units: str = "joint") -> Path:
    """Write ``log`` atomically with its format comment, in joint-side units or
    (``units="drive"``) in the drive's integer units through ``robot``'s motors.  A
    log in drive units records the drive train, not the robot's kinematic hash: its
    counts do not depend on the offsets and directions a lab commissions."""
    if units not in ("joint", "drive"):
        raise InputError(f"log units must be joint or drive, got {units!r}", value=units,
                         valid="joint or drive")
    meta: dict[str, Any] = {"rate_hz": round(log.rate, 9), **(notes or {})}
    if units == "joint":
        meta["robot_kinematics"] = kinematic_hash(robot)
        cols = ["t"] + [f"{j}_pos" for j in JOINTS] + [f"{j}_tau" for j in JOINTS]
        arrays = [log.t[:, None], log.theta, log.tau]
        if log.theta_dot is not None:
            cols += [f"{j}_vel" for j in JOINTS]
            arrays.append(log.theta_dot)
    else:
        meta["drive_train"] = robot.motors.model
        counts, vel, torque = to_drive_units(robot, log.theta, log.theta_dot, log.tau)
        cols = (["t"] + [f"{j}_counts" for j in JOINTS]
                + [f"{j}_torque_0p1pct" for j in JOINTS])
        arrays = [log.t[:, None], counts, torque]
        if vel is not None:
            cols += [f"{j}_counts_per_s" for j in JOINTS]
            arrays.append(vel)
    lines = [f"# {FORMAT} " + json.dumps(meta, sort_keys=True, separators=(",", ":")),
             ",".join(cols)]
    if units == "joint":
        block = np.hstack(arrays)
        lines += [",".join(_num(x) for x in row) for row in block]
    else:  # the times as decimals, every drive value as an integer
        ints = np.hstack(arrays[1:])
        lines += [_num(tk) + "," + ",".join(map(str, row.tolist()))
                  for tk, row in zip(log.t, ints, strict=True)]
    atomic_write(path, ("\n".join(lines) + "\n").encode())
    return Path(path)


def _num(x: float) -> str:
    """A float in the strict grammar (repr, without '+' in the exponent)."""
    r = repr(float(x))
    if "e" in r:
        mant, exp = r.split("e")
        if "." not in mant:
            mant += ".0"
        r = f"{mant}e{int(exp)}"
    return r


__all__ = ["FORMAT", "JOINTS", "DriveLog", "counts_per_rad", "from_drive_units",
           "kinematic_hash", "parse_log", "read_log", "to_drive_units", "write_log"]
