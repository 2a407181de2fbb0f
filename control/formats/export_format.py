"""What an export format is (the registry :mod:`sixplus3.control.formats.registry` lists
them): a name, a line of help, its default torque hold, whether it takes a lower
``--rate`` and ``--goal`` (the forms a controller interpolates), and a function that
renders a validated motion as text (or writes a directory: the rosbag2 bag).

A lab adds a format with one module that defines an :class:`ExportFormat` and one line
in the registry; the CLI's choices and help come from the registry (its name table,
``sixplus3/cli/names.py``, is compared with it by a test)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sixplus3.motion import Motion
from sixplus3.robot_description.robot import Robot


@dataclass(frozen=True)
class Export:
    """What a format renders: the validated ``motion`` (the file's, or its decimation,
    validated again), its torques ``tau`` (n, 9) [N m] held as ``torque_hold`` says,
    for ``robot``; ``source`` the file's name; ``goal``: as a FollowJointTrajectory
    goal (the interpolated forms)."""

    source: str
    robot: Robot
    motion: Motion
    tau: np.ndarray
    torque_hold: str
    goal: bool = False


@dataclass(frozen=True)
class ExportFormat:
    """A format renders text (``render``), or writes a directory (``directory``:
    (the trajectory file, the robot, the output directory, its options) -> the
    directory, validating the file itself, e.g. the rosbag2 bag)."""

    name: str
    summary: str  #: one line of help
    torque_hold: str  #: the default: "sample" (interpolated forms) or "mean" (held)
    interpolated: bool  #: takes --rate (decimated, validated again) and --goal
    render: Callable[[Export], str] | None = None
    directory: Callable[..., Path] | None = None


__all__ = ["Export", "ExportFormat"]
