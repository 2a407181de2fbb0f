"""Excitation: a motion that makes the base parameters identifiable, planned by our own
planner within every limit the gate enforces (docs/identification.md, "Excitation").

The criterion is the condition number of the stacked base regressor, its columns scaled
to unit norm (the usual one: Gautier and Khalil 1992; Swevers et al. use the log-det of
the information matrix; both are reported).

The search: candidate *tours* (home, then ``waypoints`` random poses of the platform
within ``reach`` of home and tilted up to ``tilt`` degrees, with random crank angles,
then home again, at rest at both ends) are planned time-optimally by the planner, at
``torque_fraction`` of the torque limit, each within every limit (torque, rates,
margins, spherical joints, clearance, the site's platform limits).  Tours are then
chosen greedily: each time the candidate that lowers the condition number of the
regressor stacked so far the most, until the motion is ``duration`` long.  The chosen
tours are joined at home (each ends where the next begins, at rest) and the whole motion
goes through the gate before it is written.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.gate.validation import validate_and_write
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.errors import InfeasibleTaskError, InputError, Sixplus3Error, check_number
from sixplus3.identification.base import BaseParameters, base_parameters, stacked_regressor
from sixplus3.identification.estimate import condition_number
from sixplus3.motion import Motion
from sixplus3.planner.ocp import plan
from sixplus3.planner.smoothing import smooth
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot

#: Samples per second kept for the criterion (the regressor of every 5th sample at 1 kHz).
SCORE_RATE = 200.0


@dataclass
class ExcitationSettings:
    duration: float = 10.0  #: at least this long [s]
    candidates: int = 12  #: tours planned
    waypoints: int = 4  #: random poses per tour
    reach: float = 0.06  #: platform within this of home [m]
    tilt: float = 25.0  #: tilt up to [deg]
    crank: float = 35.0  #: crank angles within this of home [deg]
    torque_fraction: float = 0.6
    #: the tours' jerk [rad/s^3] and torque-rate [N m/s] limits: a smooth motion, well
    #: inside the identification filter's band (docs/identification.md, "The filter")
    jerk: float = 5000.0
    torque_rate: float = 100.0
    seed: int = 0
    rate: float = 1000.0

    def check(self) -> None:
        for name, lo, hi in (("duration", 0.2, 120.0), ("reach", 0.0, 0.2),
                             ("tilt", 0.0, 60.0), ("crank", 0.0, 80.0),
                             ("torque_fraction", 0.5, 1.0), ("jerk", 200.0, 2e5),
                             ("torque_rate", 10.0, 2000.0)):
            check_number(f"excitation {name}", getattr(self, name), lo, hi)
        for name, lo, hi in (("candidates", 1, 200), ("waypoints", 1, 12),
                             ("seed", 0, 2 ** 31)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise InputError(f"excitation {name} must be an integer in [{lo}, {hi}], "
                                 f"got {v!r}", value=v, valid=f"[{lo}, {hi}]")


@dataclass
class Tour:
    task: dict[str, Any]
    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    x_guess: np.ndarray
    Wb: np.ndarray  # the base regressor of its samples at SCORE_RATE, (m * 9, r)


@dataclass
class Excitation:
    path: Path
    duration: float
    condition: float
    log_det: float
    tours: list[dict[str, Any]]
    planned: int
    refused: int
    per_tour: list[float] = field(default_factory=list)


def _tour_task(robot: Robot, rng: np.random.Generator, st: ExcitationSettings,
               k: int) -> dict[str, Any]:
    home = list(robot.home_position)
    psi0 = [math.degrees(p) for p in robot.home_psi]
    wps: list[dict[str, Any]] = [{"position": home}]
    for _ in range(st.waypoints):
        p = [home[i] + float(rng.uniform(-st.reach, st.reach)) for i in range(3)]
        rpy = [float(rng.uniform(-st.tilt, st.tilt)) for _ in range(2)] + [
            float(rng.uniform(-st.tilt, st.tilt))]
        psi = [psi0[i] + float(rng.uniform(-st.crank, st.crank)) for i in range(3)]
        wps.append({"position": p, "rpy": rpy, "psi": psi})
    wps.append({"position": home})
    return {"name": f"excite_{k}", "waypoints": wps, "torque_fraction": st.torque_fraction,
            "nodes_per_segment": 8,
            "limits": {"jerk": st.jerk, "torque_rate": st.torque_rate}}


def base_regressor(dyn: ClosedLoopDynamics, base: BaseParameters, theta: np.ndarray,
                   theta_dot: np.ndarray, theta_ddot: np.ndarray, rate: float,
                   x_known: np.ndarray | None = None) -> np.ndarray:
    """The base regressor of a motion's samples at :data:`SCORE_RATE`; ``x_known``: the
    planned motion's own minimal coordinates (no search for a pose, see
    :func:`stacked_regressor`)."""
    step = max(1, int(round(rate / SCORE_RATE)))
    sl = slice(0, None, step)
    Y = stacked_regressor(dyn, theta[sl], theta_dot[sl], theta_ddot[sl],
                          None if x_known is None else x_known[sl])
    return base.reduce(Y).reshape(-1, base.rank)


def plan_tours(robot: Robot, st: ExcitationSettings, base: BaseParameters,
               say: Callable[[str], None] = lambda s: None) -> tuple[list[Tour], int]:
    """The candidate tours that plan (and the number refused)."""
    rng = np.random.default_rng(st.seed)
    dyn = ClosedLoopDynamics(robot)
    tours, refused = [], 0
    for k in range(st.candidates):
        doc = _tour_task(robot, rng, st, k)
        try:
            sol = plan(task_from_dict(doc), robot)
            sm = smooth(sol, rate=st.rate)
        except (InfeasibleTaskError, Sixplus3Error) as exc:
            refused += 1
            say(f"  tour {k}: refused ({str(exc)[:100]})")
            continue
        try:  # the plan's own states: no forward kinematics search from a log
            Wb = base_regressor(dyn, base, sm.theta, sm.theta_dot, sm.theta_ddot, st.rate,
                                sm.x_guess)
        except Sixplus3Error as exc:  # a tour that cannot be scored is skipped, and said
            refused += 1
            say(f"  tour {k}: planned but not scored, skipped ({str(exc)[:120]})")
            continue
        tours.append(Tour(doc, sm.t, sm.theta, sm.theta_dot, sm.theta_ddot, sm.x_guess, Wb))
        say(f"  tour {k}: {sm.duration:.3f} s, condition {condition_number(Wb):.3g}")
    return tours, refused


def log_det(Wb: np.ndarray) -> float:
    """log det of the column-scaled information matrix (the D-optimal criterion)."""
    s = np.linalg.norm(Wb, axis=0)
    s[s == 0] = 1.0
    sign, ld = np.linalg.slogdet((Wb / s).T @ (Wb / s))
    return float(ld) if sign > 0 else -math.inf


def choose(tours: list[Tour], duration: float) -> list[int]:
    """Greedy choice of tours (module doc); a tour may be chosen again."""
    chosen: list[int] = []
    total = 0.0
    W = np.zeros((0, tours[0].Wb.shape[1]))
    while total < duration:
        best, best_c = 0, math.inf
        for i, tr in enumerate(tours):
            c = condition_number(np.vstack([W, tr.Wb]))
            if c < best_c:
                best, best_c = i, c
        chosen.append(best)
        W = np.vstack([W, tours[best].Wb])
        total += float(tours[best].t[-1])
    return chosen


def excite(robot: Robot, out_dir: str | Path, st: ExcitationSettings | None = None,
           say: Callable[[str], None] = lambda s: None) -> Excitation:
    """Plan, choose, join, validate and write ``out_dir/excitation.csv`` (module doc)."""
    st = st or ExcitationSettings()
    st.check()
    out = Path(out_dir)
    base = base_parameters(robot)
    say(f"base parameters: {base.rank} of {base.layout.size}")
    tours, refused = plan_tours(robot, st, base, say)
    if not tours:
        raise InfeasibleTaskError(f"none of the {st.candidates} excitation tours could be "
                                  "planned within the limits: lower --reach or --tilt")
    order = choose(tours, st.duration)
    parts_t, th, v, a, x = [], [], [], [], []
    t0 = 0.0
    for n, i in enumerate(order):
        tr = tours[i]
        s = 0 if n == 0 else 1  # each tour starts where the last ended (home, at rest)
        parts_t.append(tr.t[s:] + t0)
        th.append(tr.theta[s:])
        v.append(tr.theta_dot[s:])
        a.append(tr.theta_ddot[s:])
        x.append(tr.x_guess[s:])
        t0 += float(tr.t[-1])
    rate = st.rate
    theta = np.vstack(th)
    t = np.arange(len(theta)) / rate
    W = np.vstack([tours[i].Wb for i in order])
    cond, ld = condition_number(W), log_det(W)
    meta = {"rate_hz": rate, "task": {"name": "excitation", "tours": [tours[i].task
                                                                       for i in order]},
            "excitation": {"criterion": "condition number of the column-scaled base "
                                        "regressor", "condition": cond, "log_det": ld,
                           "base_parameters": base.rank, "settings": st.__dict__}}
    out.mkdir(parents=True, exist_ok=True)
    limits = task_from_dict(tours[order[0]].task).limits_for(robot)  # the plans' share
    path, _ = validate_and_write(out / "excitation.csv",
                                 Motion(t, theta, np.vstack(v), np.vstack(a), rate), robot,
                                 np.vstack(x), limits=limits, meta=meta)
    return Excitation(path=path, duration=float(t[-1]), condition=cond, log_det=ld,
                      tours=[tours[i].task for i in order], planned=len(tours),
                      refused=refused, per_tour=[condition_number(tr.Wb) for tr in tours])


__all__ = ["Excitation", "ExcitationSettings", "choose", "excite", "log_det", "plan_tours"]
