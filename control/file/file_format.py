"""The trajectory file format: its name, columns, units, size cap, canonical header JSON
and integrity digest (docs/validation.md).  The layer under the reader
(:mod:`sixplus3.control.file.trajectory_parse`) and the writer
(:mod:`sixplus3.control.file.trajectory_file`).  Import these names from here."""

from __future__ import annotations

import hashlib
import json
import math
from typing import Any

import numpy as np

from sixplus3.errors import InputError
from sixplus3.motion import Motion
from sixplus3.robot_description.urdf import actuated_joint_names

FORMAT = "sixplus3-trajectory/2"
SUFFIX = ".csv"
JOINTS = actuated_joint_names()
COLUMNS = (["t"] + [f"{j}_{k}" for j in JOINTS for k in ("pos", "vel", "acc", "tau")]
           + [f"platform_{c}" for c in ("x", "y", "z", "qx", "qy", "qz", "qw")]
           + [f"psi_{i}" for i in range(3)])
UNITS = {"t": "s", "pos": "rad", "vel": "rad/s", "acc": "rad/s^2", "tau": "N m",
         "platform_xyz": "m", "platform_q": "unit quaternion (x, y, z, w)", "psi": "rad"}


def column_unit(name: str) -> str:
    """The unit of the column ``name`` of :data:`COLUMNS` (SI; the quaternion's
    components are unitless: "1")."""
    if name == "t":
        return "s"
    if name.startswith("platform_q"):
        return "1"
    if name.startswith("platform_"):
        return UNITS["platform_xyz"]
    if name.startswith("psi_"):
        return UNITS["psi"]
    kind = name.rsplit("_", 1)[-1]
    if name in COLUMNS and kind in UNITS:
        return UNITS[kind]
    raise KeyError(name)


#: The unit of every column (:func:`column_unit`).
COLUMN_UNITS = {c: column_unit(c) for c in COLUMNS}
#: Largest trajectory file read [bytes]: ~143,000 samples (the package writes at most
#: MAX_SAMPLES).  Validating one this size peaks near 1 GB (benchmarks/bench_gate_memory.py;
#: about 1.9 kB per sample above a 0.8 GB base, docs/validation.md "Caps").
MAX_BYTES = 128 << 20
#: The one column accessor's kinds: the 9 joints' 'pos' | 'vel' | 'acc' | 'tau' (each
#: (n, 9) in joint order), and the platform's blocks (:func:`columns`).
JOINT_KINDS = ("pos", "vel", "acc", "tau")
PLATFORM_BLOCKS = {
    "position": slice(COLUMNS.index("platform_x"), COLUMNS.index("platform_z") + 1),
    "quaternion": slice(COLUMNS.index("platform_qx"), COLUMNS.index("platform_qw") + 1),
    "psi": slice(COLUMNS.index("psi_0"), COLUMNS.index("psi_2") + 1),
    "platform": slice(COLUMNS.index("platform_x"), COLUMNS.index("psi_2") + 1),
}
_JOINT_COLUMNS = {k: [COLUMNS.index(f"{j}_{k}") for j in JOINTS] for k in JOINT_KINDS}

def _canonical(header: dict[str, Any]) -> bytes:
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


def digest(header: dict[str, Any], body: bytes | memoryview) -> str:
    """The integrity digest of a header (without ``integrity``) and the body bytes."""
    h = {k: v for k, v in header.items() if k != "integrity"}
    sha = hashlib.sha256(_canonical(h))
    sha.update(b"\n")
    sha.update(body)
    return sha.hexdigest()


def columns(data: np.ndarray, kind: str) -> np.ndarray:
    """The columns of ``kind`` of (n, 47) samples in :data:`COLUMNS` order, the file's one
    accessor: 'pos' | 'vel' | 'acc' | 'tau' give (n, 9) in joint order; 'position' (n, 3)
    [m], 'quaternion' (n, 4) (x, y, z, w), 'psi' (n, 3) [rad] and 'platform' (n, 10,
    the three together) are views of the platform's blocks."""
    if kind in _JOINT_COLUMNS:
        return data[:, _JOINT_COLUMNS[kind]]
    if kind in PLATFORM_BLOCKS:
        return data[:, PLATFORM_BLOCKS[kind]]

    raise InputError(f"no column kind {kind!r} in a trajectory file", value=kind,
                     valid=", ".join([*JOINT_KINDS, *PLATFORM_BLOCKS]))


def motion_of(data: np.ndarray, rate: float) -> Motion:
    """The :class:`~sixplus3.motion.Motion` of (n, 47) samples in :data:`COLUMNS` order
    declared at ``rate`` [Hz]: the times and the joints' angles, rates and
    accelerations."""
    return Motion(data[:, 0], columns(data, "pos"), columns(data, "vel"),
                  columns(data, "acc"), rate)


__all__ = ["COLUMNS", "FORMAT", "JOINTS", "JOINT_KINDS", "MAX_BYTES", "PLATFORM_BLOCKS",
           "SUFFIX", "UNITS", "columns", "digest", "motion_of"]
