"""A safety report per plan, for the integrator's risk assessment (ISO/TS 15066 §5.5,
ISO 10218-2; issue 70): what a trajectory file does at every point a person can touch,
with the gate's own numbers recomputed from the file, never the planner's.

:func:`safety_report` judges the file with the gate (:func:`validate_file`: the record
``validate --json`` prints is kept whole under ``validation``), then recomputes along
the path, from the file's samples:

- power and force limiting at every point judged (:func:`pfl_profile`, the gate's
  check itself): each point's speed, and per body region its effective mass along the
  worst direction and the two-body model's contact force;
- the stop table (:func:`stop_table`, what the guard recomputes; the header's only
  checked against it) and, from each sample, the stop's time and the distance the tool
  centre point and the fastest point judged travel before rest (:func:`stop_runs`),
  and with the guard's worst measured detection before it (at the plan's speed).

and states what it does not cover, the guard's settings and its measured detection
figures with their source, and the assumptions.  :mod:`sixplus3.interaction.report.safety_page`
writes the page.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.file.file_format import motion_of
from sixplus3.control.gate.pfl import Judged, judged, pfl_profile
from sixplus3.control.gate.stop import TORQUE_SHARE, stop_runs, stop_table
from sixplus3.control.gate.validation import validate_file, validation_record
from sixplus3.interaction.contact.tables import IDENTIFIED, LAG, UNIDENTIFIED
from sixplus3.interaction.envelope import COMMAND_SHARE, DEFAULT_RATE, MAX_JUMP
from sixplus3.robot_description import hardware
from sixplus3.robot_description.body_regions import REGIONS
from sixplus3.robot_description.leg_links import link_names
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.robot import Robot

#: The report's format.
FORMAT = "sixplus3-safety-report/1"
#: Significant digits of the per-sample arrays in the JSON file.
DIGITS = 5
#: The contact guard's detection as measured (not computed from this file), with the
#: command that measured it (BENCHMARKS.md).
GUARD_MEASURED: tuple[dict[str, Any], ...] = (
    {"robot model": "identified (a parameter covariance given)",
     "contacts": 276, "within both limits": 276, "detection median [ms]": 4,
     "detection worst [ms]": 7,
     "source": "BENCHMARKS.md, 'Safety that holds like the gate' (2026-11-29): "
               "benchmarks/bench_contact_battery.py P --regions hand lower_arm chest face "
               "upper_arm --speeds 0.1 0.5 max --normals along across --drives soft stiff "
               "--rate-feedback encoder plant filtered (the nominal plant)"},
    {"robot model": "not identified (the guard's prior)",
     "contacts": 401, "within both limits": 401, "detection median [ms]": 6,
     "detection worst [ms]": 10,
     "source": "BENCHMARKS.md, 'Safety that holds like the gate' (2026-11-29): "
               "benchmarks/bench_contact_battery.py P --regions hand lower_arm chest "
               "--speeds 0.1 0.5 max --normals along across --drives soft stiff --plant "
               "pS1.yaml pS2.yaml pS3.yaml --no-nominal (six +-30 % prototypes)"},
    {"robot model": "the nominal model; contacts at the legs' vertices",
     "contacts": 1108, "within both limits": 1095, "detection median [ms]": 3,
     "detection worst [ms]": 9,
     "source": "BENCHMARKS.md, 'The legs in power and force limiting' (2026-11-29): "
               "benchmarks/bench_contact_battery.py P --task (11 examples, 7 held-out) "
               "--regions hand lower_arm --kinds free clamp --point legs --drives soft "
               "stiff --plant p2001.yaml p2002.yaml (the 13 above the limit: clamps on "
               "the stiff drive, <= 1.7 % over, and a prototype's overshoot)"},
)
#: What the two-body model and this report leave out, said plainly.
ASSUMPTIONS = (
    "Transient contacts by ISO/TS 15066 Annex A's two-body model: the energy of the "
    "robot's effective mass at the point's speed, taken by the body region's spring; "
    "the force is that spring's at full compression.",
    "The effective mass is the robot's with the motors' torques held: what a contact "
    "meets within the few milliseconds before the drives react. The drives react after "
    "one control tick and the guard's detection (measured, above); the energy is "
    "judged at the speed before any reaction.",
    "Pressure is not modelled: the report judges force (energy) only. The contact "
    "surfaces' areas (edges, the spherical joints' housings) must be assessed apart.",
    "Body values (effective mass, spring constant, permissible force; the transient "
    "factor 2 where a transient contact is permitted, 1 for the skull, face and neck) "
    "from ISO/TS 15066:2016 Annex A, Tables A.2 and A.3 "
    "(robot_description/body_regions.py). A clamped region's mass is infinite.",
    "A link is judged at its vertices (the joint centres that bound it): a rigid link's "
    "fastest point is a vertex; that its contact energy is largest there too is checked "
    "by sampling (tests/test_leg_pfl.py), not proven.",
    "The robot model is the file's robot (the identified one if the file was planned "
    "for it); the numbers hold for the real robot as far as the model does.",
    "The stop is the stop table's alone, begun at the plan's speed at each sample; the "
    "guard may stop faster where the torque allows, never slower. Detection time adds "
    "its distance at the point's speed before the stop begins.",
)
#: What the points judged never cover.
NEVER_COVERED = (
    "the platform's plate and its cranks away from the tool centre point, the platform "
    "centre and the spherical joints P",
    "the tool's body away from its centre point",
    "the base, the motors and the pulleys (fixed)",
)


def _round(a: np.ndarray) -> list[Any]:
    """An array as nested lists of DIGITS significant digits (inf and NaN as None)."""
    out = np.asarray(a, dtype=float)
    return [None if not np.isfinite(x) else float(f"{x:.{DIGITS}g}") for x in out.ravel()] \
        if out.ndim == 1 else [_round(row) for row in out]


def _arc(p: np.ndarray) -> np.ndarray:
    """(n,) the arc length along the positions (n, 3) from the first [m]."""
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]


def safety_report(path: str | Path, robot: Robot) -> dict[str, Any]:
    """The report of the trajectory file at ``path`` for ``robot`` (the site's hardware
    in force): a JSON-ready mapping (module doc).  Raises what :func:`validate_file`
    raises for a file that is not a trajectory of this robot."""
    rep = validate_file(path, robot)
    validation = validation_record(str(path), rep)
    out: dict[str, Any] = {"format": FORMAT, "file": str(path), "validation": validation}
    if rep.exit_code == 2 or rep.data is None or rep.header is None:
        out["refused"] = "the file is not a consistent motion of this robot: " + \
            "; ".join(rep.messages())
        return out
    motion = motion_of(rep.data, float(rep.header["rate_hz"]))
    what = judged(rep.header.get("pfl"), rep.header.get("pfl_links"))
    # nothing judged: the speeds at every point are still shown
    shown = what if what else Judged((), link_names(["legs"]))
    prof = pfl_profile(rep, robot, motion, shown)
    all_links = link_names(["legs"])
    out["coverage"] = {
        "regions": [r.name for r in what.regions],
        "region limits [N]": {r.name: r.transient_force for r in what.regions},
        "regions not covered": [n for n in REGIONS if n not in {r.name for r in
                                                                 what.regions}],
        "leg links": list(what.links),
        "leg links not covered": [n for n in all_links if n not in what.links],
        "points": list(prof.points),
        "never covered": list(NEVER_COVERED),
        "site requires": {"regions": list(hardware.active().pfl),
                          "leg links": list(hardware.active().pfl_links)}}
    t = motion.t
    path_: dict[str, Any] = {"t": _round(t), "points": {}}
    for j, name in enumerate(prof.points):
        path_["points"][name] = {"speed [m/s]": _round(prof.speed[:, j]), "regions": {
            r.name: {"effective mass [kg]": _round(prof.mass[:, j, k]),
                     "force [N]": _round(prof.force[:, j, k])}
            for k, r in enumerate(prof.regions)} if what else {}}
    out["path"] = path_
    if what:
        k, where, r = prof.worst()
        region = what.regions[r]
        out["largest"] = {"ratio": rep.max_pfl_ratio, "where": rep.max_pfl_where,
                          "t [s]": float(t[k]), "region": region.name,
                          "force [N]": float(prof.force[k, prof.points.index(where), r]),
                          "limit [N]": region.transient_force,
                          "speed [m/s]": float(prof.speed[k, prof.points.index(where)])}
    out["stop"] = _stop(rep, robot, motion, prof)
    out["guard"] = _guard()
    out["assumptions"] = list(ASSUMPTIONS) + _loop_assumption()
    return out


def _loop_assumption() -> list[str]:
    """What the site's declared position loop adds to the assumptions (none: nothing)."""
    hw = hardware.active()
    if hw.position_loop is None:
        return ["The site declares no position loop: the two-body model (torques held) "
                "alone. A stiff loop meets harder (docs/safety.md, 'The drive in the "
                "contact')."]
    return [f"The site's position loop (Kp {hw.position_loop.kp:g} N m/rad, Kd "
            f"{hw.position_loop.kd:g} N m s/rad, at the file's rate, within the drive's "
            "limit) is in every contact too, the larger of the two models judged "
            "(dynamics/drive_contact.py); the reference runs on through a free contact "
            f"and stands {hw.guard_detection * 1e3:g} ms and one tick after a clamp's "
            "onset: a clamp is judged safe only with the contact guard running."]


def _stop(rep: Any, robot: Robot, motion: Any, prof: Any) -> dict[str, Any]:
    """From each sample: the stop table's stop time and the distances (module doc)."""
    lim = Limits(**rep.limits) if rep.limits else robot.limits
    beta = stop_table(robot, rep, motion, lim)
    vnorm = np.linalg.norm(motion.theta_dot, axis=1)
    times, s_end = stop_runs(beta, vnorm, motion.rate)
    grid = np.arange(len(beta), dtype=float)
    tcp = prof.points.index("tcp")
    arcs = [_arc(prof.position[:, j]) for j in range(len(prof.points))]
    dist = np.stack([np.interp(s_end, grid, a) - a for a in arcs], axis=1)  # (n, P)
    fastest = np.argmax(dist, axis=1)
    # before the stop: the guard's worst measured detection at the plan's speed
    detect = max(float(m["detection worst [ms]"]) for m in GUARD_MEASURED) / 1e3
    before = prof.speed * detect  # (n, P)
    return {"torque share": TORQUE_SHARE,
            "detection assumed [s]": detect,
            "tcp distance with detection [m]": _round(before[:, tcp] + dist[:, tcp]),
            "max tcp distance with detection [m]": float((before[:, tcp]
                                                          + dist[:, tcp]).max()),
            "max distance with detection [m]": float((before + dist).max()),
            "file's table": "checked: the recomputed table" if rep.stop_deceleration
            is not None else "none in the file (the guard computes its own)",
            "deceleration [1/s]": _round(beta), "stop time [s]": _round(times),
            "tcp distance [m]": _round(dist[:, tcp]),
            "largest distance [m]": _round(dist.max(axis=1)),
            "largest distance at": [prof.points[j] for j in fastest],
            "max stop time [s]": float(times.max()),
            "max tcp distance [m]": float(dist[:, tcp].max()),
            "max distance [m]": float(dist.max())}


def _guard() -> dict[str, Any]:
    """The contact guard's settings (interaction/contact/guard.py) and its measured figures."""
    return {"settings": {
        "threshold lag window [s]": LAG,
        "model error, identified / prior": [IDENTIFIED.model_error, UNIDENTIFIED.model_error],
        "friction factor, identified / prior": [IDENTIFIED.friction, UNIDENTIFIED.friction],
        "command share of the torque limit": COMMAND_SHARE,
        "stop torque share": TORQUE_SHARE,
        "largest reading jump [rad]": MAX_JUMP,
        "drive rate feedback (default)": list(DEFAULT_RATE)},
        "measured": [dict(m) for m in GUARD_MEASURED]}


__all__ = ["ASSUMPTIONS", "FORMAT", "GUARD_MEASURED", "safety_report"]
