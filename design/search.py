"""The optimal leg design of paper §V-B: a grid search over (l2 = l3, l4 = l5, ex = fx).

Objective: the area of the design half-plane (z = 0, y >= 0, the disk of centre (0, l1)
and radius l1 = dp) whose points are reachable in the assembly mode, have every actuated
angle in [0, theta_max] (theta_max = 135 deg) and need tau_ext <= 10 N m for a 2 g
acceleration of 0.5 kg in any direction against gravity.  A design counts only if its RUS
chains reach every point of the disk.  Stage 1: a 1 cm grid over the three variables
(0.01 .. 0.35 m each); stage 2: a 1 mm grid within one coarse step of the best.

The paper's conventions are not all stated; a :class:`Reading` makes each one explicit
(docs/design.md compares them).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from tqdm import tqdm

from sixplus3.design import _kernel
from sixplus3.design.workspace import halfplane_grid
from sixplus3.errors import InputError, check_number
from sixplus3.robot_description.assembly import AssemblyMode
from sixplus3.robot_description.geometry import LegGeometry, LegLoad

#: The paper's optimum (l2, l4, ex) [m].
PAPER_DESIGN = (0.139, 0.350, 0.097)
#: Longest link allowed [m] (paper §V-B).
MAX_LINK = 0.35
#: Zero-weight points on the disk boundary checked for RUS reachability.
RING_POINTS = 2000


@dataclass(frozen=True)
class Reading:
    """One reading of the paper's conventions for the design study."""

    name: str = "spec"
    mode: str = "++++"  # assembly mode (kinematics.leg.AssemblyMode)
    ey: float = 0.020  # E, F offsets from the D-P line: ey = -fy [m]
    theta_zero: float = 0.0  # where theta = 0 points, as an angle from +y about +x [rad]
    theta_direction: int = 1  # +1: theta grows about +x_f; -1: about -x_f
    theta_max: float = math.radians(135.0)  # every theta in [0, theta_max] (paper) [rad]
    description: str = "ours: theta = 0 along +y (to the centre), 90 deg up; mode ++++"

    def base_geometry(self) -> LegGeometry:
        return replace(LegGeometry(), ey=self.ey, fy=-self.ey)

    def symmetric(self) -> bool:
        """Mirror x -> -x maps the mode to itself (th2 and th3 branches equal)."""
        s = AssemblyMode.parse(self.mode).signs
        return s[2] == s[3]


#: Stage 2 refines every coarse design within this fraction of the best coarse area ...
SEED_TOLERANCE = 0.03
#: ... at most this many.
MAX_SEEDS = 8
#: Designs whose area is within this fraction of the best belong to the ridge.
RIDGE_TOLERANCE = 0.01


@dataclass(frozen=True)
class Ridge:
    """The near-optimal designs: every design of both stages with area >= (1 - tol) best.

    The coarse stage covers the whole box at its step, the fine stage one coarse step
    around each seed; the ridge may extend beyond the fine boxes, where it is resolved at
    the coarse step only.
    """

    tolerance: float
    count: int
    l2: tuple[float, float]  # (min, max) [m]
    l4: tuple[float, float]
    ex: tuple[float, float]
    l2_over_ex: tuple[float, float]  # (min, max) of l2 / ex

    def line(self) -> str:
        return (f"{self.count} designs within {self.tolerance:.0%} of the best: l2 "
                f"{self.l2[0]:.3f}..{self.l2[1]:.3f}, l4 {self.l4[0]:.3f}..{self.l4[1]:.3f}, "
                f"ex {self.ex[0]:.3f}..{self.ex[1]:.3f} m, l2/ex {self.l2_over_ex[0]:.2f}.."
                f"{self.l2_over_ex[1]:.2f}")


def ridge(designs: np.ndarray, areas: np.ndarray, tol: float = RIDGE_TOLERANCE) -> Ridge | None:
    """The designs within ``tol`` of the best area (None when nothing counts)."""
    best = float(areas.max()) if len(areas) else 0.0
    if best <= 0.0:
        return None
    d = designs[areas >= (1.0 - tol) * best]
    span = lambda v: (float(v.min()), float(v.max()))  # noqa: E731
    return Ridge(tol, len(d), span(d[:, 0]), span(d[:, 1]), span(d[:, 2]),
                 span(d[:, 0] / d[:, 2]))


@dataclass(frozen=True)
class DesignResult:
    found: bool  # False when no feasible design has a counted point (l2, l4, ex are NaN)
    l2: float  # [m]
    l4: float  # [m]
    ex: float  # [m]
    area_m2: float  # counted area of the optimum [m^2]
    paper_design_area_m2: float  # the paper's (0.139, 0.350, 0.097) under the same reading
    evaluations: int  # designs evaluated (both stages)
    point_evaluations: int  # leg kernel calls (pruned designs stop early)
    feasible_designs: int
    seconds: float
    ws_step: float
    reading: Reading
    ridge: Ridge | None = None  # every evaluated design within RIDGE_TOLERANCE of the best
    local_optima: list[tuple[float, float, float, float]] = field(default_factory=list)
    # (l2, l4, ex, area) of the refined optimum around each coarse seed, best seed first

    def as_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["reading"] = asdict(self.reading)
        return out


@dataclass(frozen=True)
class Grid:
    points: np.ndarray  # (n, 3), ordered: likely RUS failures first
    weights: np.ndarray  # (n,) area of each point [m^2]


def design_grid(step: float, reading: Reading, geometry: LegGeometry | None = None,
                use_symmetry: bool = True) -> Grid:
    """The workspace grid of a reading; halved by the x -> -x mirror when it applies.

    For a symmetric leg (l2 = l3, l4 = l5, l6 = l7, ex = fx, ey = -fy, ez = fz) in a mode
    with equal th2 / th3 branches, the mirror maps a solution at (x, y) to one at (-x, y)
    with th2 and th3 exchanged (tests/test_design.py checks this numerically).
    """
    geometry = geometry or reading.base_geometry()
    pts = halfplane_grid(geometry, step)
    w = np.full(len(pts), step * step)
    # Feasibility must not depend on how close the grid comes to the disk boundary,
    # where RUS chains fail first: a dense ring just inside the boundary circle, with
    # zero area weight, is checked too.  Its angles avoid x = 0 for the mirror.
    t = (np.arange(RING_POINTS) + 0.5) * (2 * np.pi / RING_POINTS)
    r_ring = geometry.dp * (1.0 - 1e-9)
    ring = np.c_[r_ring * np.sin(t), geometry.l1 - r_ring * np.cos(t), np.zeros_like(t)]
    ring = ring[ring[:, 1] > 0.0]
    pts = np.vstack([ring, pts])
    w = np.concatenate([np.zeros(len(ring)), w])
    if use_symmetry and reading.symmetric():
        keep = pts[:, 0] > 0.0  # neither cell centres nor ring points lie on x = 0
        pts, w = pts[keep], 2.0 * w[keep]
    # Boundary and axis points first: that is where RUS chains fail, so infeasible
    # designs stop after a few points.
    r = np.hypot(pts[:, 0], pts[:, 1] - geometry.l1)
    order = np.argsort(-np.maximum(r / geometry.dp, 1.0 - pts[:, 1] / geometry.l1),
                       kind="stable")
    return Grid(np.ascontiguousarray(pts[order]), np.ascontiguousarray(w[order]))


def evaluate(designs: np.ndarray, reading: Reading, grid: Grid,
             load: LegLoad | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Counted area [m^2] of each (l2, l4, ex) design, -1 if infeasible; and the work."""
    load = load or LegLoad()
    designs = np.ascontiguousarray(np.atleast_2d(designs), dtype=np.float64)
    return _kernel.evaluate_designs(
        designs, reading.base_geometry().packed(), grid.points, grid.weights,
        AssemblyMode.parse(reading.mode).array(), load.mass * load.gravity, load.accel_g,
        reading.theta_zero, float(reading.theta_direction), reading.theta_max,
        load.torque_limit)


def _axis(lo: float, hi: float, step: float) -> np.ndarray:
    n = int(math.floor((hi - lo) / step + 1e-9)) + 1
    return np.round(lo + step * np.arange(n), 6)


def _cube(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    return np.stack(np.meshgrid(a, b, c, indexing="ij"), axis=-1).reshape(-1, 3)


def _run(designs: np.ndarray, reading: Reading, grid: Grid, chunk: int,
         progress: Callable[[int], None] | None) -> tuple[np.ndarray, np.ndarray]:
    areas, work = np.empty(len(designs)), np.empty(len(designs), dtype=np.int64)
    for s in range(0, len(designs), chunk):
        a, w = evaluate(designs[s:s + chunk], reading, grid)
        areas[s:s + chunk], work[s:s + chunk] = a, w
        if progress:
            progress(min(chunk, len(designs) - s))
    return areas, work


def check_steps(coarse_step: float, fine_step: float, *ws_steps: float) -> None:
    """Raise ValueError naming the first grid step out of its range."""
    checks = [("coarse_step", coarse_step, 1e-3, 0.1),
              ("fine_step", fine_step, 1e-4, coarse_step)]
    checks += [("ws_step", v, 1e-4, 0.05) for v in ws_steps]
    for name, v, lo, hi in checks:
        check_number(f"{name} [m]", v, lo, hi)


def optimize(coarse_step: float = 0.01, fine_step: float = 0.001, ws_step: float = 0.005,
             reading: Reading | None = None, progress: bool | Callable[..., Any] = False,
             seed_tolerance: float = SEED_TOLERANCE, max_seeds: int = MAX_SEEDS
             ) -> DesignResult:
    """Two-stage grid search; ties go to the first design in (l2, l4, ex) order.

    Stage 2 refines around every coarse design within ``seed_tolerance`` of the best
    coarse area (at most ``max_seeds``, best first), not only the best one: the objective
    is a narrow ridge along l2 ~ 1.4 ex with near-equal coarse maxima far apart, and
    which one wins the coarse stage depends on the workspace grid.  ``seed_tolerance=0``
    is the paper's procedure (one seed).  :attr:`DesignResult.local_optima` lists the
    refined optimum of each seed.
    """
    reading = reading or Reading()
    if not (math.isfinite(seed_tolerance) and 0.0 <= seed_tolerance < 1.0):
        raise InputError(f"seed_tolerance must be in [0, 1), got {seed_tolerance}",
                         value=seed_tolerance, valid="[0, 1)")
    if not (isinstance(max_seeds, int) and 1 <= max_seeds <= 100):
        raise InputError(f"max_seeds must be an integer in [1, 100], got {max_seeds}",
                         value=max_seeds, valid="an integer in [1, 100]")
    check_steps(coarse_step, fine_step, ws_step)
    t0 = time.perf_counter()
    grid = design_grid(ws_step, reading)
    coarse_axis = _axis(coarse_step, MAX_LINK, coarse_step)
    coarse = _cube(coarse_axis, coarse_axis, coarse_axis)
    bar = None
    if progress is True:
        bar = tqdm(total=len(coarse), desc="coarse designs", unit="design", leave=False)
        tick = bar.update
    else:
        tick = progress or None
    a1, w1 = _run(coarse, reading, grid, 4096, tick)
    best = coarse[int(np.argmax(a1))]
    order = np.argsort(-a1, kind="stable")
    n_seeds = 1
    if a1.max() > 0.0:
        n_seeds = int(min(max_seeds, max(1, (a1 >= (1.0 - seed_tolerance) * a1.max()).sum())))
    seeds = coarse[order[:n_seeds]]
    boxes = [_cube(*(_axis(max(fine_step, c - coarse_step), min(MAX_LINK, c + coarse_step),
                           fine_step) for c in seed)) for seed in seeds]
    fine = np.unique(np.vstack(boxes), axis=0)  # sorted: ties keep (l2, l4, ex) order
    if bar is not None:
        bar.close()

        bar = tqdm(total=len(fine), desc="fine designs", unit="design", leave=False)
        tick = bar.update
    a2, w2 = _run(fine, reading, grid, 4096, tick)
    if bar is not None:
        bar.close()
    k = int(np.argmax(a2))
    if a2[k] < a1.max():  # cannot happen when the coarse optimum is on the fine grid
        best_design, best_area = best, float(a1.max())
    else:
        best_design, best_area = fine[k], float(a2[k])
    paper_area = float(evaluate(np.array([PAPER_DESIGN]), reading, grid)[0][0])
    local: list[tuple[float, float, float, float]] = []
    for box in boxes:
        lo, hi = box.min(axis=0) - 1e-9, box.max(axis=0) + 1e-9
        inside = np.all((fine >= lo) & (fine <= hi), axis=1)
        j = int(np.flatnonzero(inside)[np.argmax(a2[inside])])
        local.append((float(fine[j, 0]), float(fine[j, 1]), float(fine[j, 2]), float(a2[j])))
    found = best_area > 0.0
    if not found:
        best_design = np.full(3, np.nan)
    return DesignResult(
        found=found,
        l2=float(best_design[0]), l4=float(best_design[1]), ex=float(best_design[2]),
        area_m2=max(best_area, 0.0), paper_design_area_m2=paper_area,
        evaluations=len(coarse) + len(fine), point_evaluations=int(w1.sum() + w2.sum()),
        feasible_designs=int((a1 >= 0).sum() + (a2 >= 0).sum()),
        seconds=time.perf_counter() - t0, ws_step=ws_step, reading=reading,
        ridge=ridge(np.vstack([coarse, fine]), np.concatenate([a1, a2])),
        local_optima=local)
