"""The whole-robot layout study (``sixplus3 design layout``; docs/design.md, "Layout").

The paper optimises one leg (§V-A) and places three of them on a stated layout
(tangential actuated axes, |a_j - a_i| = 0.143 m, l6 = l7 = 0.13 m); on that layout the
legs of its §V assembly intersect (docs/design.md).  This study keeps the leg and its
assembly and searches the freedoms the text leaves open:

- ``axis_turn`` (gamma): every actuated axis turned about the vertical through its A_i;
- ``platform_phase``: the orientation of the platform's crank axes against the legs
  (the study sweeps an offset from the paper's -45 deg, at which P_i points at leg i
  at psi = 90 deg).

For each layout it computes the constant-orientation workspace (:mod:`design.cow`:
horizontal platform, cranks at home, reach, actuated range, singularity-free, the 2 g
criterion within the torque limit, and no interference in the robot's collision model)
and reports its volume, z range, projected area, the footprint and the ratio of the two
(the paper's 5.03).  The winner maximises the interference-free volume.  Layouts run as
Dask tasks (:mod:`design.cluster`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sixplus3 import fileio
from sixplus3.design.cluster import map_tasks
from sixplus3.design.cow import PAPER_RATIO, compute_cow
from sixplus3.errors import InputError
from sixplus3.kinematics.collision import layout_clearance
from sixplus3.robot_description.geometry import LegGeometry
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.robot_geometry import PAPER_PHASE

#: Most layouts of one sweep (per leg): a COW each, ~0.6 s at the default 2 cm grid.
MAX_LAYOUTS = 2000


@dataclass(frozen=True)
class LayoutSettings:
    """The sweep and the COW grid of the study [deg, m]."""

    turns_deg: tuple[float, ...] = tuple(np.arange(0.0, 45.01, 2.5).tolist())
    phases_deg: tuple[float, ...] = (-20.0, -10.0, 0.0, 10.0, 20.0)
    step: float = 0.02  # COW grid pitch, x and y [m]
    z_step: float = 0.02  # COW layer pitch [m]
    extent: float = 0.5  # COW grid half-width [m]
    z_max: float = 0.8  # highest COW layer [m]

    def check(self) -> LayoutSettings:
        for name in ("turns_deg", "phases_deg"):
            v = getattr(self, name)
            ok = (isinstance(v, tuple) and 1 <= len(v) <= 400
                  and all(isinstance(a, (int, float)) and math.isfinite(a) and -90 <= a <= 90
                          for a in v))
            if not ok:
                raise InputError(f"{name} must be 1 to 400 finite angles in [-90, 90] deg, "
                                 f"got {str(v)[:80]}", value=str(v)[:80],
                                 valid="1..400 angles in [-90, 90] deg")
        n = len(self.turns_deg) * len(self.phases_deg)
        if n > MAX_LAYOUTS:
            raise InputError(f"the sweep has {n} layouts, over the cap of {MAX_LAYOUTS}: "
                             "use fewer turns or phases, or run it in parts",
                             value=n, valid=f"<= {MAX_LAYOUTS}")
        values = (self.step, self.z_step, self.extent, self.z_max)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values) or not (
                0.005 <= self.step <= 0.1 and 0.005 <= self.z_step <= 0.2
                and 0 < self.extent <= 2 and 0 < self.z_max <= 2):
            raise InputError("step, z_step, extent, z_max must be in [0.005, 0.1], "
                             f"[0.005, 0.2], (0, 2], (0, 2] m, got {values}", value=values)
        return self


@dataclass(frozen=True)
class LayoutPoint:
    """One layout's COW (volumes [L], areas [m^2], heights [m])."""

    leg: str  # which leg family ("paper" or "other-basin")
    turn_deg: float
    phase_deg: float  # offset from the paper's platform phase (-45 deg)
    hub_clearance: float  # [m] between the hubs of different legs (static)
    volume_torque: float  # reach .. 2 g within the torque limit [L]
    volume_clear: float  # and no interference [L]
    z_low: float  # lowest and highest interference-free layer (NaN: empty)
    z_high: float
    area_clear: float  # projected interference-free area [m^2]
    footprint: float  # convex hull of the nine actuated joints [m^2]

    @property
    def ratio(self) -> float:
        """Projected interference-free area / footprint (the paper's 5.03)."""
        return self.area_clear / self.footprint

    def as_dict(self) -> dict[str, float | str]:
        return {"leg": self.leg, "turn_deg": self.turn_deg, "phase_deg": self.phase_deg,
                "hub_clearance_mm": self.hub_clearance * 1e3,
                "volume_torque_l": self.volume_torque, "volume_clear_l": self.volume_clear,
                "z_low_m": self.z_low, "z_high_m": self.z_high,
                "area_clear_m2": self.area_clear, "footprint_m2": self.footprint,
                "ratio": self.ratio}


def study_robot(base: Robot, turn_deg: float, phase_deg: float) -> Robot:
    """``base`` with the axis turn and the platform phase offset (from the paper's) of
    one layout."""
    return base.replace(geometry=replace(base.geometry, axis_turn=math.radians(turn_deg),
                                         platform_phase=PAPER_PHASE + math.radians(phase_deg)))


def _point(shared: tuple[Robot, LayoutSettings, str], item: tuple[float, float]
           ) -> LayoutPoint:
    """One Dask task: the COW of one layout."""
    base, st, leg = shared
    turn, phase = item
    robot = study_robot(base, turn, phase)
    hub = layout_clearance(robot)[0]
    cow = compute_cow(robot, step=st.step, z_step=st.z_step, extent=st.extent,
                      z_max=st.z_max, margin=robot.limits.margin, z_min=st.z_step)
    layers = np.flatnonzero(cow.masks["clear"].any(axis=(1, 2)))
    zr = ((float(cow.zs[layers[0]]), float(cow.zs[layers[-1]])) if len(layers)
          else (math.nan, math.nan))
    return LayoutPoint(leg, float(turn), float(phase), float(hub),
                       cow.volume("torque") * 1e3, cow.volume("clear") * 1e3, *zr,
                       cow.projected_area("clear"), cow.footprint_area)


def other_basin_leg(ey: float) -> LegGeometry:
    """The best leg of the §V study's other basin, (0.252-0.268, 0.345, 0.182-0.192)
    (docs/design.md): its middle, with the study's ey."""
    return LegGeometry.symmetric(0.260, 0.345, 0.187, ey=ey)


@dataclass(frozen=True)
class LayoutStudy:
    """Every layout of the sweep, for each leg family, and the winners."""

    points: tuple[LayoutPoint, ...]
    settings: LayoutSettings
    base: Robot

    def best(self, leg: str = "paper") -> LayoutPoint:
        """The layout with the largest interference-free volume (ties: the smaller
        turn, then the smaller |phase|)."""
        rows = [p for p in self.points if p.leg == leg]
        if not rows:
            raise InputError(f"no layout of leg {leg!r} in the study", value=leg)
        return max(rows, key=lambda p: (round(p.volume_clear, 6), -abs(p.turn_deg),
                                        p.turn_deg >= 0, -abs(p.phase_deg)))

    def curve(self, leg: str = "paper") -> tuple[np.ndarray, np.ndarray]:
        """(turns [deg], the best volume over the phases at each turn [L])."""
        turns = sorted({p.turn_deg for p in self.points if p.leg == leg})
        best = [max(p.volume_clear for p in self.points
                    if p.leg == leg and p.turn_deg == t) for t in turns]
        return np.array(turns), np.array(best)

    def report(self) -> str:
        lines = [f"layout study of {self.base.summary()}",
                 f"COW grid {self.settings.step * 100:g} x {self.settings.step * 100:g} x "
                 f"{self.settings.z_step * 100:g} cm, |x|, |y| <= {self.settings.extent} m, "
                 f"z <= {self.settings.z_max} m; horizontal platform, cranks at home; "
                 "volumes in L (2 g within the torque limit; and interference-free)",
                 f"{'leg':<12}{'turn':>6}{'phase':>7}{'hubs mm':>9}{'2g L':>7}"
                 f"{'free L':>8}{'z range m':>13}{'ratio':>7}"]
        for leg in dict.fromkeys(p.leg for p in self.points):
            turns, _ = self.curve(leg)
            for t in turns:
                rows = [p for p in self.points if p.leg == leg and p.turn_deg == t]
                p = max(rows, key=lambda q: (q.volume_clear, -abs(q.phase_deg)))
                zr = (f"{p.z_low:.2f}-{p.z_high:.2f}" if math.isfinite(p.z_low) else "-")
                lines.append(f"{leg:<12}{p.turn_deg:>6.1f}{p.phase_deg:>7.1f}"
                             f"{p.hub_clearance * 1e3:>9.1f}{p.volume_torque:>7.1f}"
                             f"{p.volume_clear:>8.1f}{zr:>13}{p.ratio:>7.2f}")
        for leg in dict.fromkeys(p.leg for p in self.points):
            b = self.best(leg)
            lines.append(f"best {leg}: turn {b.turn_deg:g} deg, phase offset "
                         f"{b.phase_deg:g} deg: {b.volume_clear:.1f} L interference-free "
                         f"(2 g: {b.volume_torque:.1f} L), z {b.z_low:.2f}-{b.z_high:.2f} m, "
                         f"footprint {b.footprint * 1e4:.0f} cm^2, projected area / footprint "
                         f"{b.ratio:.2f} (the paper's {PAPER_RATIO})")
        return "\n".join(lines)


def layout_study(base: Robot, settings: LayoutSettings | None = None,
                 legs: Sequence[str] = ("paper", "other-basin"),
                 scheduler: str | None = None, workers: int = 2,
                 progress: Callable[[int, int], None] | bool = False) -> LayoutStudy:
    """Sweep the layouts of ``base`` (its leg as ``paper``; ``other-basin`` is
    :func:`other_basin_leg` in the same assembly) on Dask (``scheduler``: None a
    LocalCluster of ``workers``, ``"synchronous"`` here, or an address)."""
    if not isinstance(base, Robot):
        raise InputError("layout_study needs a Robot", value=type(base).__name__,
                         valid="a Robot")
    st = (settings or LayoutSettings()).check()
    bad = [leg for leg in legs if leg not in ("paper", "other-basin")]
    if bad or not legs:
        raise InputError(f"legs must be 'paper' and/or 'other-basin', got {list(legs)}",
                         value=list(legs), valid="paper, other-basin")
    items = [(t, p) for t in st.turns_deg for p in st.phases_deg]
    points: list[LayoutPoint] = []
    for leg in legs:
        robot = base if leg == "paper" else base.replace(geometry=replace(
            base.geometry, leg=other_basin_leg(base.leg.ey)))
        points += map_tasks(_point, items, (robot, st, leg), scheduler, workers, progress,
                            desc=f"layout {leg}")
    return LayoutStudy(tuple(points), st, base)


def plot_study(study: LayoutStudy, path: str | Path) -> None:
    """The figure: interference-free 2 g COW volume against the axis turn (the best
    phase at each turn), one curve per leg, written atomically."""
    # deferred: matplotlib loads only when this runs
    import matplotlib

    matplotlib.use("Agg")
    # deferred: matplotlib loads only when this runs
    import matplotlib.pyplot as plt


    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for leg in dict.fromkeys(p.leg for p in study.points):
        t, v = study.curve(leg)
        ax.plot(t, v, marker="o", label=f"{leg} leg")
        b = study.best(leg)
        ax.annotate(f"{b.volume_clear:.1f} L", (b.turn_deg, b.volume_clear),
                    textcoords="offset points", xytext=(4, 6))
    top = max(p.volume_clear for p in study.points)
    ax.set_ylim(bottom=0.0, top=max(1.0, 1.15 * top))
    ax.set_xlabel("axis turn gamma [deg]")
    ax.set_ylabel("interference-free 2 g COW [L]")
    ax.set_title("Layout study (horizontal platform, best platform phase per gamma)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fileio.save_figure(fig, path, dpi=120)
