"""Reading a trajectory file for a robot: the bytes read within the size cap
(:func:`read_bytes`), parsed (:func:`sixplus3.control.file.trajectory_parse.parse`),
checked against the robot it is meant for (:func:`check_robot`, the difference named
field by field) and held as :class:`TrajectoryData` (:func:`read_trajectory`).  Writing
is :mod:`sixplus3.control.file.trajectory_file`'s."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from sixplus3 import fileio
from sixplus3.control.file.file_format import (
    COLUMN_UNITS,
    COLUMNS,
    MAX_BYTES,
    columns,
    motion_of,
)
from sixplus3.control.file.trajectory_parse import parse
from sixplus3.errors import GeometryError, InputError, LimitError, TrajectoryFileError
from sixplus3.motion import Motion
from sixplus3.robot_description.robot import Robot, require_robot

if TYPE_CHECKING:
    import pandas as pd


def check_robot(header: dict[str, Any], robot: Robot, name: str) -> None:
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


def _robot_diff(a: dict[str, Any], b: dict[str, Any], where: str = "") -> str:
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
            return (f"{where}{k}: file {fileio.short_repr(va, 60)}, robot "
                    f"{fileio.short_repr(vb, 60)}")
    return ""


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
    - ``traj.motion``: the :class:`~sixplus3.motion.Motion` of its samples at its rate;
    - ``traj.platform_position`` (n, 3) [m], ``traj.platform_quaternion`` (n, 4)
      (x, y, z, w), ``traj.psi`` (n, 3) [rad];
    - ``traj.to_pandas()``: a DataFrame of the 46 named columns indexed by time
      (``t [s]``), with every column's unit in ``df.attrs["units"]`` (or in the names
      themselves, ``to_pandas(unit_names=True)``: ``leg0_A_pos [rad]``), and the file's
      rate, robot hash, name and limits in ``df.attrs`` (pandas is optional: an
      InputError says how to install it if it is missing).
    """

    header: dict[str, Any]
    data: np.ndarray

    def __getitem__(self, key: str | int) -> Any:  # type: ignore[override]
        if isinstance(key, str):
            if key not in COLUMNS:
                raise InputError(f"no column {key!r} in a trajectory file", value=key,
                                 valid=f"one of {', '.join(COLUMNS[:3])}, ..., {COLUMNS[-1]}")
            return self.data[:, COLUMNS.index(key)]
        if isinstance(key, bool) or not isinstance(key, (int, slice)):
            raise InputError(f"a trajectory is indexed by a column name or 0 (header), 1 "
                             f"(samples), got {type(key).__name__}", value=repr(key)[:40],
                             valid="a column name, 0, 1 or a slice")
        if isinstance(key, int) and not -2 <= key <= 1:
            raise InputError(f"a trajectory has two parts (header, samples), got index "
                             f"{key}", value=key, valid="0 or 1 (or -2, -1)")
        return tuple.__getitem__(self, key)

    @property
    def t(self) -> np.ndarray:
        return self.data[:, 0]

    @property
    def motion(self) -> Motion:
        return motion_of(self.data, float(self.header["rate_hz"]))

    def joints(self, kind: str) -> np.ndarray:
        return columns(self.data, kind)

    @property
    def platform_position(self) -> np.ndarray:
        return columns(self.data, "position")

    @property
    def platform_quaternion(self) -> np.ndarray:
        return columns(self.data, "quaternion")

    @property
    def psi(self) -> np.ndarray:
        return columns(self.data, "psi")

    def to_pandas(self, unit_names: bool = False) -> pd.DataFrame:
        try:
            # deferred: pandas (optional) loads only when this runs
            import pandas as pd
        except ImportError:
            raise InputError("to_pandas needs pandas: pip install pandas", value=None,
                             valid="pandas installed") from None
        names = COLUMNS[1:]
        if unit_names:
            names = [f"{c} [{COLUMN_UNITS[c]}]" for c in names]
        df = pd.DataFrame(self.data[:, 1:], columns=names,
                          index=pd.Index(self.data[:, 0], name="t [s]"))
        df.attrs.update({
            "units": {c: COLUMN_UNITS[c] for c in COLUMNS},
            "rate_hz": self.header.get("rate_hz"),
            "robot_hash": (self.header.get("robot") or {}).get("hash"),
            "name": (self.header.get("task") or {}).get("name")
            if isinstance(self.header.get("task"), dict) else None,
            "limits": self.header.get("limits")})
        return df


def read_trajectory(path: str | Path, robot: Robot) -> TrajectoryData:
    """Load, format-check and integrity-check a trajectory made for ``robot``: a
    :class:`TrajectoryData` (``header, data = ...`` unpacks it; ``traj["leg0_A_pos"]``
    and ``traj.joints("tau")`` name the columns).  Raises :class:`TrajectoryFileError`.
    It checks the format, the digest and the robot, not the motion:
    :func:`sixplus3.validate_file` is the gate."""
    robot = require_robot(robot)
    raw = read_bytes(path)  # checks that path is a path
    name = Path(path).name
    header, data = parse(raw, name)
    check_robot(header, robot, name)
    return TrajectoryData(header, data)
