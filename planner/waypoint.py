"""A waypoint of a task: a platform pose, optional crank angles, a stop and a dwell;
checked where it is built."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sixplus3.errors import TaskError
from sixplus3.fileio import short_repr


@dataclass(frozen=True)
class Waypoint:
    position: np.ndarray  # (3,) platform centre [m]
    rotation: np.ndarray  # (3, 3)
    psi: np.ndarray | None = None  # (3,) crank angles [rad] or None (free)
    #: come to rest here (zero velocity and acceleration); ``dwell`` [s] then holds it
    stop: bool = False
    dwell: float = 0.0

    def __post_init__(self) -> None:
        def arr(name: str, v: object, shape: tuple[int, ...], unit: str) -> np.ndarray:
            try:
                a = np.array(v, dtype=float)
            except (TypeError, ValueError):
                a = np.full(0, np.nan)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise TaskError(f"waypoint {name} must be {shape} finite numbers [{unit}], "
                                f"got {short_repr(v, 60)}", value=short_repr(v, 60),
                                valid=f"{shape} finite [{unit}]")
            return a

        pos = arr("position", self.position, (3,), "m")
        if np.abs(pos).max() > 10.0:
            raise TaskError("waypoint position must be within 10 m of the base",
                            value=pos.tolist(), valid="|x|, |y|, |z| <= 10 m")
        rot = arr("rotation", self.rotation, (3, 3), "1")
        if (np.abs(rot.T @ rot - np.eye(3)).max() > 1e-6
                or abs(np.linalg.det(rot) - 1.0) > 1e-6):
            raise TaskError("waypoint rotation must be a rotation matrix (orthonormal, "
                            "det 1, to 1e-6)", value="not a rotation", valid="R in SO(3)")
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "rotation", rot)
        if self.psi is not None:
            object.__setattr__(self, "psi", arr("psi", self.psi, (3,), "rad"))
        if not isinstance(self.stop, (bool, np.bool_)):
            raise TaskError("waypoint stop must be true or false", value=self.stop,
                            valid="a bool")
        d = self.dwell
        if (isinstance(d, bool) or not isinstance(d, (int, float, np.floating))
                or not 0.0 <= float(d) <= 3600.0):
            raise TaskError("waypoint dwell must be in [0, 3600] s", value=short_repr(d, 40),
                            valid="[0, 3600] s")
