"""The leg's design workspace (paper §V-A): the horizontal half-plane z = 0, y >= 0.

By the circular symmetry of the leg about x_f, the half-plane holds the whole story: the
reachable set is the disk of centre (x, y) = (0, l1) and radius dp.  A point *counts*
when it is solved in the chosen assembly mode, every actuated angle lies in
[0, theta_max] (the paper's max(theta) <= 135 deg; angles below 0 are the base-collision
quadrant (270, 360) deg), and tau_ext <= the torque limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sixplus3.errors import check_number
from sixplus3.kinematics.leg import LegEval, LegState, leg_eval_packed
from sixplus3.robot_description.assembly import DEFAULT_MODE, AssemblyMode
from sixplus3.robot_description.geometry import LegGeometry, LegLoad

#: The paper's design limit on the actuated angles [rad].
THETA_MAX = math.radians(135.0)


def halfplane_grid(geometry: LegGeometry, step: float) -> np.ndarray:
    """Cell centres of a square grid of pitch ``step`` [m] inside the reachable disk.

    Returns (n, 3) points (x, y, 0) of the leg frame; each stands for an area step^2.
    """
    check_number("workspace step [m]", step, 1e-4, 0.1)
    r = geometry.dp
    xs = np.arange(-r + step / 2, r, step)
    ys = np.arange(step / 2, geometry.l1 + r, step)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    inside = X**2 + (Y - geometry.l1) ** 2 <= r**2
    pts = np.zeros((int(inside.sum()), 3))
    pts[:, 0] = X[inside]
    pts[:, 1] = Y[inside]
    return pts


def theta_within(theta: np.ndarray, theta_max: float = THETA_MAX, zero: float = 0.0,
                 direction: int = 1) -> np.ndarray:
    """(n,) every actuated angle in [0, theta_max] in a reading's angle convention.

    theta_reading = (direction * theta - zero) mod 2 pi in [0, 2 pi), as the paper counts
    them (collision in (270, 360) deg).  With zero = 0, direction = +1 (docs/conventions.md) this is
    0 <= theta <= theta_max for our theta in [-90, 270) deg.
    """
    t = np.mod(direction * np.asarray(theta) - zero, 2.0 * math.pi)
    return np.all(t <= theta_max, axis=-1)


def counted(ev: LegEval, load: LegLoad, theta_max: float = THETA_MAX) -> np.ndarray:
    """(n,) the points that count toward the design objective (docs/conventions.md reading)."""
    return ev.ok & theta_within(ev.theta, theta_max) & (ev.tau_ext <= load.torque_limit)


def counted_reading(ev: LegEval | LegState, load: LegLoad, reading: Any) -> np.ndarray:
    """:func:`counted` under a :class:`design.search.Reading`'s angle convention."""
    return (ev.ok & theta_within(ev.theta, reading.theta_max, reading.theta_zero,
                                 reading.theta_direction)
            & (ev.tau_ext <= load.torque_limit))


@dataclass(frozen=True)
class AreaReport:
    step: float  # grid pitch [m]
    disk_area: float  # area of the grid cells inside the reachable disk [m^2]
    reachable_area: float  # solved in the assembly mode [m^2]
    theta_ok_area: float  # ... and 0 <= theta <= theta_max [m^2]
    usable_area: float  # ... and tau_ext <= limit [m^2]  (the paper's objective)


def usable_area(geometry: LegGeometry, step: float = 0.005,
                mode: AssemblyMode | str = DEFAULT_MODE, load: LegLoad | None = None,
                theta_max: float = THETA_MAX, zero: float = 0.0,
                direction: int = 1) -> AreaReport:
    """Areas of the half-plane workspace that are reachable, within theta, within torque;
    the angles counted in the convention (``zero``, ``direction``) of
    :func:`theta_within` (default: ours, docs/conventions.md)."""
    load = load or LegLoad()
    pts = halfplane_grid(geometry, step)
    ev = leg_eval_packed(pts, geometry.packed(), AssemblyMode.parse(mode), load,
                         margin_ii=False)
    cell = step * step
    th_ok = ev.ok & theta_within(ev.theta, theta_max, zero, direction)
    return AreaReport(
        step=step, disk_area=len(pts) * cell, reachable_area=float(ev.ok.sum()) * cell,
        theta_ok_area=float(th_ok.sum()) * cell,
        usable_area=float((th_ok & (ev.tau_ext <= load.torque_limit)).sum()) * cell,
    )
