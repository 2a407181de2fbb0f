"""Planning tasks: platform waypoints + limits, from YAML, validated against a schema.

Example (units: m and degrees in the file, SI inside)::

    name: tilt-30-x
    waypoints:
      - position: [0.0, 0.0, 0.30]
        rpy: [0, 0, 0]              # roll, pitch, yaw [deg] (R = Rz Ry Rx), or
      - position: [0.0, 0.0, 0.30]
        quaternion: [0.2588, 0, 0, 0.9659]   # x, y, z, w
        psi: [90, 90, 90]           # optional crank angles [deg]; free otherwise
    limits:                         # optional, defaults below
      torque: 10                    # |tau| [N m]
      velocity: 14.8                # |theta_dot| [rad/s]
      acceleration: 200             # |theta_ddot| [rad/s^2]
      margin: 0.05                  # every singularity margin (scale-free, 0..1)
    nodes_per_segment: 12

The motion starts and ends at rest and passes through the waypoints in order; the timing
is free.  A bad file raises :class:`TaskError` naming the field, its value and the range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import jsonschema
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from sixplus3.robot_description.urdf import TORQUE_LIMIT, VELOCITY_LIMIT
from sixplus3.errors import InputError

_VEC3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
SCHEMA = {
    "type": "object",
    "required": ["waypoints"],
    "additionalProperties": False,
    "properties": {
        "name": {"type": "string", "maxLength": 200},
        "description": {"type": "string"},
        "waypoints": {
            "type": "array", "minItems": 2, "maxItems": 50,
            "items": {
                "type": "object", "required": ["position"], "additionalProperties": False,
                "properties": {
                    "position": {**_VEC3, "items": {"type": "number", "minimum": -1.0,
                                                    "maximum": 1.5}},
                    "rpy": {**_VEC3, "items": {"type": "number", "minimum": -180,
                                               "maximum": 180}},
                    "quaternion": {"type": "array", "items": {"type": "number"},
                                   "minItems": 4, "maxItems": 4},
                    "psi": {**_VEC3, "items": {"type": "number", "minimum": -180,
                                               "maximum": 180}},
                },
                "not": {"required": ["rpy", "quaternion"]},
            },
        },
        "limits": {
            "type": "object", "additionalProperties": False,
            "properties": {
                "torque": {"type": "number", "exclusiveMinimum": 0, "maximum": TORQUE_LIMIT},
                "velocity": {"type": "number", "exclusiveMinimum": 0, "maximum": 50},
                "acceleration": {"type": "number", "exclusiveMinimum": 0, "maximum": 5000},
                "margin": {"type": "number", "minimum": 0.001, "maximum": 0.5},
            },
        },
        "nodes_per_segment": {"type": "integer", "minimum": 4, "maximum": 60},
    },
}


class TaskError(InputError):
    """A task file or task value is malformed or out of range; nothing was planned."""


@dataclass(frozen=True)
class Limits:
    torque: float = TORQUE_LIMIT  # |tau| [N m]
    velocity: float = VELOCITY_LIMIT  # |theta_dot| [rad/s]
    acceleration: float = 200.0  # |theta_ddot| [rad/s^2] (a comfort limit for pHRI; no data)
    margin: float = 0.05  # every singularity margin (leg type I/II, platform) >= margin


@dataclass(frozen=True)
class Waypoint:
    position: np.ndarray  # (3,) platform centre [m]
    rotation: np.ndarray  # (3, 3)
    psi: np.ndarray | None = None  # (3,) crank angles [rad] or None (free)


@dataclass(frozen=True)
class Task:
    waypoints: tuple[Waypoint, ...]
    limits: Limits = field(default_factory=Limits)
    name: str = "task"
    nodes_per_segment: int = 12
    source: dict | None = None  # the validated file content, for the trajectory header

    @property
    def n_segments(self) -> int:
        return len(self.waypoints) - 1


def _path(error: jsonschema.ValidationError) -> str:
    out = ""
    for p in error.absolute_path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(top level)"


def task_from_dict(doc: object, name: str = "task") -> Task:
    """Validate a task document (as loaded from YAML) and build the :class:`Task`."""
    validator = jsonschema.Draft202012Validator(SCHEMA)
    errors = sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path))
    if errors:
        e = errors[0]
        raise TaskError(f"task field {_path(e)}: {e.message} (value {e.instance!r})")
    assert isinstance(doc, dict)
    wps = []
    for k, w in enumerate(doc["waypoints"]):
        pos = np.array(w["position"], dtype=float)
        if "quaternion" in w:
            qq = np.array(w["quaternion"], dtype=float)
            norm = np.linalg.norm(qq)
            if not (abs(norm - 1.0) < 1e-3):
                raise TaskError(f"task field waypoints[{k}].quaternion: norm {norm:.6f}, must "
                                "be a unit quaternion (x, y, z, w) within 1e-3")
            rot = Rotation.from_quat(qq / norm).as_matrix()
        else:
            rpy = np.radians(w.get("rpy", [0.0, 0.0, 0.0]))
            rot = Rotation.from_euler("xyz", rpy).as_matrix()
        psi = None
        if "psi" in w:
            psi = np.radians(np.array(w["psi"], dtype=float))
            if np.any(np.abs(np.sin(psi)) < 0.05):
                raise TaskError(f"task field waypoints[{k}].psi: {w['psi']} deg puts a crank "
                                "along its radius (platform singularity); use angles in "
                                "(3, 177) deg or (-177, -3) deg")
        wps.append(Waypoint(pos, rot, psi))
    lim = Limits(**doc.get("limits", {}))
    return Task(tuple(wps), lim, str(doc.get("name", name)),
                int(doc.get("nodes_per_segment", 12)), source=doc)


def load_task(path: str | Path) -> Task:
    """Read and validate a YAML task file; raises :class:`TaskError`."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise TaskError(f"cannot read task file {path}: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise TaskError(f"task file {path} is not valid YAML: {exc}".splitlines()[0]) from exc
    return task_from_dict(doc, name=path.stem)


def rotvec(R: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(R).as_rotvec()


def tilt_angle(R: np.ndarray) -> float:
    """Angle between the platform normal and z [rad]."""
    return math.acos(max(-1.0, min(1.0, float(R[2, 2]))))
