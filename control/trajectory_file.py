"""Trajectory files for the controller: a CSV of samples and a JSON header beside it.

CSV, one row per sample: ``t`` [s]; for each actuated joint J (URDF names, legs 0..2,
each A, B, C): ``J_pos`` [rad], ``J_vel`` [rad/s], ``J_acc`` [rad/s^2], ``J_tau``
(feed-forward torque [N m]); then the platform pose ``platform_x/y/z`` [m],
``platform_qx/qy/qz/qw`` and the crank angles ``psi_0..2`` [rad].

JSON (same stem): format, units, joint names, rate, limits, the full robot (every
parameter and its hash, :attr:`Robot.hash`), the SHA-256 of the CSV, the task, planner
statistics and the validation.  A file is read only for the robot it was made for.

Both are written atomically (temporary file in the same directory, then rename), and
only after the trajectory passed
:func:`sixplus3.control.validation.validate_joint_trajectory`: no unsafe trajectory is
ever written as if it were valid.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
from dataclasses import asdict
from pathlib import Path

import numpy as np

from sixplus3.errors import GeometryError, TrajectoryFileError
from sixplus3.fileio import atomic_write
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import actuated_joint_names

FORMAT = "sixplus3-trajectory/1"
JOINTS = actuated_joint_names()
COLUMNS = (["t"] + [f"{j}_{k}" for j in JOINTS for k in ("pos", "vel", "acc", "tau")]
           + [f"platform_{c}" for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
           + [f"psi_{i}" for i in range(3)])
UNITS = {"t": "s", "pos": "rad", "vel": "rad/s", "acc": "rad/s^2", "tau": "N m",
         "platform_xyz": "m", "platform_q": "unit quaternion (x, y, z, w)", "psi": "rad"}


def write_trajectory(csv_path: Path, t, theta, theta_dot, theta_ddot, report, robot: Robot,
                     limits: Limits, meta: dict) -> tuple[Path, Path]:
    """Write the CSV and its JSON header for ``robot``; refuses a trajectory whose
    validation failed."""
    if report is None or not report.ok:
        reasons = "; ".join(report.violations) if report is not None else "not validated"
        raise TrajectoryFileError(f"refusing to write an invalid trajectory: {reasons}")
    csv_path = Path(csv_path)
    n = len(t)
    data = np.zeros((n, len(COLUMNS)))
    data[:, 0] = t
    for j in range(9):
        data[:, 1 + 4 * j:5 + 4 * j] = np.c_[theta[:, j], theta_dot[:, j], theta_ddot[:, j],
                                             report.tau[:, j]]
    data[:, 37:40] = report.position
    data[:, 40:44] = report.quaternion
    data[:, 44:47] = report.psi
    buf = io.StringIO()
    np.savetxt(buf, data, delimiter=",", header=",".join(COLUMNS), comments="", fmt="%.12g")
    csv_bytes = buf.getvalue().encode()
    header = {
        "format": FORMAT, "csv": csv_path.name,
        "csv_sha256": hashlib.sha256(csv_bytes).hexdigest(),
        "rate_hz": float(meta.get("rate_hz", 0.0)), "samples": n,
        "duration_s": float(t[-1]), "columns": COLUMNS, "units": UNITS,
        "joint_names": JOINTS, "limits": asdict(limits),
        "robot": {"hash": robot.hash, "parameters": robot.as_dict(),
                  "summary": robot.summary()},
        "task": meta.get("task"), "planner": meta.get("planner"),
        "smoothing": meta.get("smoothing"), "validation": report.summary(),
    }
    json_path = csv_path.with_suffix(".json")
    atomic_write(csv_path, csv_bytes)
    atomic_write(json_path, (json.dumps(header, indent=1, default=_jsonable) + "\n").encode())
    return csv_path, json_path


def _jsonable(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return str(obj)


def check_robot(header: dict, robot: Robot, name: str) -> None:
    """Refuse a header whose robot is not ``robot`` (or whose parameters do not give its
    recorded hash)."""
    rec = header.get("robot")
    if not isinstance(rec, dict) or not isinstance(rec.get("parameters"), dict):
        raise TrajectoryFileError(f"{name}: the header records no robot parameters")
    try:
        recorded = Robot.from_dict(rec["parameters"])
    except (GeometryError, TypeError, ValueError) as exc:
        raise TrajectoryFileError(f"{name}: the recorded robot is invalid: {exc}") from exc
    if recorded.hash != rec.get("hash"):
        raise TrajectoryFileError(f"{name}: the recorded robot parameters do not match the "
                                  "recorded robot hash (edited header)")
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


def read_trajectory(csv_path: str | Path, robot: Robot | None = None) -> tuple[dict, np.ndarray]:
    """Load and format-check a trajectory made for ``robot`` (default
    ``Robot.default()``); raises :class:`TrajectoryFileError`."""
    robot = robot or Robot.default()
    csv_path = Path(csv_path)
    json_path = csv_path.with_suffix(".json")
    for p in (csv_path, json_path):
        if not p.exists():
            raise TrajectoryFileError(f"missing file {p}")
    try:
        header = json.loads(json_path.read_text())
    except json.JSONDecodeError as exc:
        raise TrajectoryFileError(f"{json_path.name} is not valid JSON: {exc.msg}") from exc
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise TrajectoryFileError(f"{json_path.name}: format is {header.get('format')!r}, "
                                  f"expected {FORMAT!r}" if isinstance(header, dict) else
                                  f"{json_path.name}: not a trajectory header")
    raw = csv_path.read_bytes()
    check_robot(header, robot, json_path.name)
    lines = raw.decode(errors="replace").splitlines()
    if not lines:
        raise TrajectoryFileError(f"{csv_path.name} is empty")
    cols = lines[0].split(",")
    missing = [c for c in COLUMNS if c not in cols]
    if missing:
        raise TrajectoryFileError(f"{csv_path.name}: missing columns {missing[:4]}"
                                  + (" ..." if len(missing) > 4 else ""))
    if cols != COLUMNS:
        raise TrajectoryFileError(f"{csv_path.name}: unexpected column order or extra columns")
    try:
        data = np.loadtxt(io.StringIO("\n".join(lines[1:])), delimiter=",", ndmin=2)
    except ValueError as exc:
        raise TrajectoryFileError(f"{csv_path.name}: unreadable number ({exc})") from exc
    if data.shape[0] < 2 or data.shape[1] != len(COLUMNS):
        raise TrajectoryFileError(f"{csv_path.name}: expected >= 2 rows of {len(COLUMNS)} "
                                  f"values, got shape {data.shape}")
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise TrajectoryFileError(f"{csv_path.name}: non-finite value in column {COLUMNS[c]} "
                                  f"at row {r + 1}")
    dt = np.diff(data[:, 0])
    if data[0, 0] != 0.0 or np.any(dt <= 0):
        k = int(np.argmax(dt <= 0)) if np.any(dt <= 0) else 0
        raise TrajectoryFileError(f"{csv_path.name}: time must start at 0 and increase "
                                  f"strictly (row {k + 2})")
    rate = float(header.get("rate_hz", 0))
    if rate > 0 and np.any(np.abs(dt[:-1] - 1.0 / rate) > 1e-6):
        raise TrajectoryFileError(f"{csv_path.name}: samples are not at the declared "
                                  f"{rate:g} Hz")
    if hashlib.sha256(raw).hexdigest() != header.get("csv_sha256"):
        raise TrajectoryFileError(f"{csv_path.name} does not match its header (checksum): "
                                  "edited or truncated")
    q = data[:, 40:44]
    if np.any(np.abs(np.linalg.norm(q, axis=1) - 1) > 1e-6):
        raise TrajectoryFileError(f"{csv_path.name}: platform quaternions are not unit")
    if not math.isclose(float(header.get("duration_s", -1)), data[-1, 0], abs_tol=1e-9):
        raise TrajectoryFileError(f"{csv_path.name}: duration differs from its header")
    return header, data


def columns(data: np.ndarray, kind: str) -> np.ndarray:
    """(M, 9) of 'pos' | 'vel' | 'acc' | 'tau' for the 9 joints in order."""
    k = ("pos", "vel", "acc", "tau").index(kind)
    return data[:, [1 + 4 * j + k for j in range(9)]]
