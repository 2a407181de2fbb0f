"""The hardware envelope: the authority no robot, task or trajectory file can raise.

The limits every motion is judged by come from two places only, never from a file that
travels with a trajectory, task or robot:

1. the **built-in catalogue** of drive trains (:data:`CATALOGUE`), keyed by model: a motor
   and its transmission, with the ratings they are sold with.  A robot file names its
   drive train (``motors.model``); the figures that follow from it (rated torque, belt
   ratio, encoder resolution) must be the catalogue's, and the robot's limits must lie
   within the envelope they give (:func:`catalogue_envelope`);
2. an optional **site hardware file** the operator installs outside the robot file
   (``--hardware FILE`` on the command line, or the ``SIXPLUS3_HARDWARE`` environment
   variable): it names the drive train fitted and may tighten any limit, among them the
   platform's speed and acceleration that protect people (e.g. the named set
   ``collaborative``).  It may never loosen the catalogue.

A robot file may change what a lab measures (rotor inertia, friction, zero offsets,
directions, masses) and may tighten limits; :func:`check_robot_within` refuses one that
raises an envelope figure, naming the figure, the file's value and the envelope's.  The
gate judges by :func:`effective_limits`: the robot's limits tightened by the site's.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

from sixplus3.errors import GeometryError, InputError, LimitError
from sixplus3.fileio import parse_yaml, read_bytes
from sixplus3.robot_description.body_regions import regions
from sixplus3.robot_description.leg_links import ALL, link_names
from sixplus3.robot_description.limits import Limits


@dataclass(frozen=True)
class DriveTrain:
    """One catalogue entry: a motor model and its transmission to the joint."""

    key: str
    motor: str
    rated_torque: float  #: continuous motor torque [N m]
    peak_torque: float  #: instantaneous peak motor torque [N m]
    rated_speed_rpm: float  #: rated motor speed [rpm]
    gear_ratio: float  #: motor turns per joint turn
    encoder_bits: int  #: encoder counts per motor turn, as a power of 2
    joint_torque: float  #: the torque limit at the joint [N m] (<= rated x ratio)
    source: str = field(default="")

    @property
    def joint_velocity(self) -> float:
        """Joint speed at the motor's rated speed [rad/s]."""
        return self.rated_speed_rpm * 2.0 * math.pi / 60.0 / self.gear_ratio


#: The drive trains sixplus3 knows.  Add an entry here (with its source) to fit another
#: motor: nothing a robot file says can stand in for it.
CATALOGUE: dict[str, DriveTrain] = {
    "SGMCS-05B+belt-72/34": DriveTrain(
        key="SGMCS-05B+belt-72/34", motor="Yaskawa SGMCS-05B (direct drive, 135 mm)",
        rated_torque=5.0, peak_torque=15.0, rated_speed_rpm=300.0,
        gear_ratio=72.0 / 34.0, encoder_bits=20, joint_torque=10.0,
        source="rated torque 5 N m: the model code '05' of the SGMCS small-capacity series "
               "(Sigma-7 catalogue, model designations); 20-bit encoder: the same "
               "designation's 4th digit '3'/'D'; 15 N m peak and 300 rpm rated speed: "
               "ASSUMED (the ratings table was not found in the searchable corpus; the "
               "3x peak and 300 rpm are the series' usual figures); belt 72/34: the "
               "paper's section V-A; 10 N m at the joint: the design card (5 N m x "
               "72/34 = 10.6, limited to 10)"),
}
DEFAULT_DRIVE_TRAIN = "SGMCS-05B+belt-72/34"

#: Named sets of platform limits a site or robot file may select.
PEOPLE_LIMITS: dict[str, dict[str, Any]] = {
    "collaborative": {
        "tcp_speed": 0.25, "tcp_acceleration": 2.0,
        "source": "tcp_speed 0.25 m/s: the reduced speed of ISO 10218-1:2011 5.6 for "
                  "work near people; tcp_acceleration 2 m/s^2: ASSUMED, a gentle start "
                  "(about 0.2 g: no standard gives a platform acceleration)"},
}

def people_limits(name: object) -> dict[str, float]:
    """The limits of the named set ``name`` of :data:`PEOPLE_LIMITS` (None: none), or a
    GeometryError naming the known sets."""
    if name is None:
        return {}
    if not isinstance(name, str) or name not in PEOPLE_LIMITS:
        raise GeometryError("people", name, f"one of {sorted(PEOPLE_LIMITS)}")
    return {k: float(v) for k, v in PEOPLE_LIMITS[name].items() if k != "source"}


#: Environment variable naming the site hardware file.
ENV = "SIXPLUS3_HARDWARE"


def drive_train(key: object) -> DriveTrain:
    """The catalogue entry ``key``, or a GeometryError naming the known ones."""
    if not isinstance(key, str) or key not in CATALOGUE:
        raise GeometryError("motors.model", key, f"one of the catalogue's drive trains "
                            f"{sorted(CATALOGUE)}", "the envelope comes from the catalogue")
    return CATALOGUE[key]


def catalogue_envelope(key: str) -> Limits:
    """The loosest limits any robot with drive train ``key`` may give: the joint torque
    and speed of the catalogue entry, and the built robot's own limits for what no
    motor datum sets (acceleration, jerk, torque rate, margin, actuated range,
    spherical tilt, platform limits)."""
    d = drive_train(key)
    return Limits().replace_upper(torque=d.joint_torque, velocity=d.joint_velocity)


#: The contact guard's detection the gate assumes for a clamp with a declared position
#: loop [s]: the worst measured in the contact batteries (BENCHMARKS.md, "Safe in
#: contact, the stop and the reaction": detection median 4 ms, worst 10 ms).
GUARD_DETECTION = 0.010


class PositionLoop(NamedTuple):
    """The site's drives' position loop (docs/safety.md, "The drive in the contact"): PD
    gains at the joint, the same on each of the nine, running at the file's rate on the
    encoder's difference, the command within the drive's torque limit."""

    kp: float  #: [N m/rad]
    kd: float  #: [N m s/rad]


def position_loop_from(doc: object) -> PositionLoop | None:
    """A site file's ``position_loop`` ({kp, kd}) checked, or None (not declared)."""
    if doc is None:
        return None
    if not isinstance(doc, dict) or set(doc) != {"kp", "kd"}:
        raise GeometryError("hardware.position_loop", str(doc)[:60],
                            "a mapping {kp: N m/rad, kd: N m s/rad}")
    out = []
    for name, hi in (("kp", 1e5), ("kd", 1e4)):
        v = doc[name]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= hi:
            raise GeometryError(f"hardware.position_loop.{name}", v, f"a number in [0, {hi:g}]")
        out.append(float(v))
    return PositionLoop(*out)


@dataclass(frozen=True)
class Hardware:
    """The site's hardware: a catalogue drive train and the site's tightening of its
    envelope.  ``origin`` says where it came from (the catalogue, or a site file and
    its SHA-256)."""

    drive_train: str = DEFAULT_DRIVE_TRAIN
    limits: Limits = field(default_factory=lambda: catalogue_envelope(DEFAULT_DRIVE_TRAIN))
    origin: str = "built-in catalogue"
    #: the body regions every motion must be safe for (ISO/TS 15066 power and force
    #: limiting, docs/safety.md): no task or file can drop them
    pfl: tuple[str, ...] = ()
    #: the leg links every PFL motion must be safe at (``leg{i}_{link}``,
    #: dynamics/leg_points.py): no task or file can drop them
    pfl_links: tuple[str, ...] = ()
    #: the drives' position loop, when the site declares it: power and force limiting
    #: then judges free regions with the loop in the contact (dynamics/drive_contact.py)
    position_loop: PositionLoop | None = None
    #: with a position loop: how long after a clamp's onset the contact guard has
    #: stopped the reference at the latest [s] (its detection; one tick is added)
    guard_detection: float = GUARD_DETECTION

    def __post_init__(self) -> None:
        drive_train(self.drive_train)
        object.__setattr__(self, "pfl", tuple(r.name for r in regions(list(self.pfl))))
        object.__setattr__(self, "pfl_links", link_names(list(self.pfl_links)))

    def describe(self) -> str:
        return f"{self.drive_train} ({self.origin})"


def _limits_within(what: str, limits: Limits, envelope: Limits, whose: str) -> None:
    """A GeometryError naming the first figure of ``limits`` looser than ``envelope``."""
    for name in Limits.UPPER:
        v, hw = getattr(limits, name), getattr(envelope, name)
        if v > hw * (1.0 + 1e-12):
            raise GeometryError(f"{what}.{name}", v, f"<= {hw:g} {Limits.unit(name)} "
                                f"({whose})", "a file may tighten the hardware, never "
                                "raise it")
    if limits.margin < envelope.margin:
        raise GeometryError(f"{what}.margin", limits.margin, f">= {envelope.margin:g} "
                            f"({whose})", "a file may tighten the hardware, never raise it")
    if limits.theta_min < envelope.theta_min or limits.theta_max > envelope.theta_max:
        raise GeometryError(f"{what}.theta_min/theta_max",
                            (limits.theta_min, limits.theta_max),
                            f"within [{envelope.theta_min:g}, {envelope.theta_max:g}] rad "
                            f"({whose})", "only a narrower actuated range")


def check_motors(motors: Any) -> None:
    """Refuse motor figures that differ from the catalogue entry the robot names: they
    set the envelope and the drive units, which a robot file may not change."""
    d = drive_train(motors.model)
    for name, mine, theirs, unit in (
            ("rated_torque", motors.rated_torque, d.rated_torque, "N m"),
            ("gear_ratio", motors.gear_ratio, d.gear_ratio, ""),
            ("encoder_bits", motors.encoder_bits, d.encoder_bits, "bit")):
        if not math.isclose(float(mine), float(theirs), rel_tol=1e-12, abs_tol=0.0):
            raise GeometryError(f"motors.{name}", mine, f"{theirs:g} {unit} (catalogue "
                                f"{d.key})".replace("  ", " "), "a robot file names its "
                                "drive train; its ratings come from the catalogue")


def check_robot_limits(limits: Limits, motors: Any) -> None:
    """The robot's limits within its catalogue envelope (GeometryError otherwise)."""
    check_motors(motors)
    _limits_within("limits", limits, catalogue_envelope(motors.model),
                   f"catalogue {motors.model}")


def check_robot_within(robot: Any, hw: Hardware | None = None) -> None:
    """Refuse a robot (from a file) whose limits or drive train exceed the site's."""
    hw = active() if hw is None else hw
    if robot.motors.model != hw.drive_train:
        raise GeometryError("motors.model", robot.motors.model,
                            f"{hw.drive_train} (the site's, {hw.origin})",
                            "the robot names another drive train than the one fitted")
    _limits_within("limits", robot.limits, hw.limits, f"site hardware, {hw.origin}")


def tightest(lim: Limits, other: Limits) -> Limits:
    """Each limit at the tighter of the two (neither can loosen the other)."""
    new: dict[str, float] = {name: min(getattr(lim, name), getattr(other, name))
                             for name in Limits.UPPER}
    new["margin"] = max(lim.margin, other.margin)
    new["theta_min"] = max(lim.theta_min, other.theta_min)
    new["theta_max"] = min(lim.theta_max, other.theta_max)
    return Limits(**{**asdict(lim), **new})


def effective_limits(robot: Any, hw: Hardware | None = None) -> Limits:
    """The limits ``robot``'s motions are planned to and judged by: its own, tightened
    by the site's (the site wins where it is tighter; nothing here can loosen either)."""
    hw = active() if hw is None else hw
    return tightest(robot.limits, hw.limits)


def judged_limits(robot: Any, *tightenings: Limits | None) -> Limits:
    """The limits a motion of ``robot`` is judged by: the hardware's
    (:func:`effective_limits`: the robot's and the site's), tightened by each of
    ``tightenings`` (a header's, a task's; None skips).  Each is first checked against
    the robot's hardware limits, so that none can loosen them (a looser value raises
    :class:`~sixplus3.errors.LimitError`).  The gate's one rule for its limits."""
    lim = effective_limits(robot)
    for t in tightenings:
        if t is not None:
            lim = tightest(lim, robot.limits.tightened(**t.as_dict()))
    return lim


def hardware_from_dict(doc: object, origin: str) -> Hardware:
    """A site's hardware from its file's mapping: ``drive_train`` (a catalogue key),
    optional ``people`` (a named set of :data:`PEOPLE_LIMITS`) and ``limits`` (each a
    tightening of the catalogue's envelope)."""
    if not isinstance(doc, dict):
        raise GeometryError("hardware", type(doc).__name__, "a mapping")
    known = {"drive_train", "people", "limits", "pfl", "pfl_links", "position_loop",
             "guard_detection"}
    extra = sorted(str(k) for k in doc if k not in known)
    if extra:
        raise GeometryError(f"hardware.{extra[0]}", "?", f"one of {sorted(known)}",
                            "unknown key")
    key = doc.get("drive_train", DEFAULT_DRIVE_TRAIN)
    env = catalogue_envelope(key) if isinstance(key, str) else catalogue_envelope("?")
    values: dict[str, Any] = {}
    try:
        values.update(people_limits(doc.get("people")))
    except GeometryError as exc:
        raise GeometryError("hardware.people", doc.get("people"),
                            f"one of {sorted(PEOPLE_LIMITS)}") from exc
    lim = doc.get("limits", {})
    if not isinstance(lim, dict):
        raise GeometryError("hardware.limits", type(lim).__name__, "a mapping of limits")
    values.update(lim)
    try:
        limits = env.tightened(**values)
    except LimitError as exc:
        raise GeometryError(f"hardware.limits.{exc.name}", exc.value,
                            f"{exc.valid} (catalogue {key})",
                            "a site file may tighten the catalogue, never raise it") from None
    pfl = doc.get("pfl", [])
    if not isinstance(pfl, list):
        raise GeometryError("hardware.pfl", pfl, "a list of body regions "
                            "(robot_description.body_regions.REGIONS)")
    try:
        names = tuple(r.name for r in regions(pfl))
    except InputError as exc:
        raise GeometryError("hardware.pfl", exc.value, str(exc.valid)) from None
    links = doc.get("pfl_links", [])
    try:
        legs = link_names(links)
    except InputError as exc:
        raise GeometryError("hardware.pfl_links", exc.value, str(exc.valid)) from None
    return Hardware(drive_train=key, limits=limits, origin=origin, pfl=names,
                    pfl_links=legs, position_loop=position_loop_from(doc.get("position_loop")),
                    guard_detection=_guard_detection(doc.get("guard_detection", GUARD_DETECTION)))


def _guard_detection(v: object) -> float:
    """A site's ``guard_detection`` [s] checked: no shorter than the worst measured
    (a site may assume a slower guard, never a faster one), at most 1 s."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (
            GUARD_DETECTION <= v <= 1.0):
        raise GeometryError("hardware.guard_detection", v,
                            f"a time in [{GUARD_DETECTION:g}, 1] s")
    return float(v)


def load_hardware(path: str | Path) -> Hardware:
    """The site hardware file at ``path`` (YAML or JSON); its SHA-256 is its origin."""

    raw = read_bytes(path, "hardware file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise GeometryError("hardware file", str(path), "UTF-8 text") from None
    doc = parse_yaml(text, f"hardware file {path}")
    digest = hashlib.sha256(raw).hexdigest()
    return hardware_from_dict(doc, f"site file {Path(path).name}, sha256 {digest[:16]}")


_ACTIVE: list[Hardware] = []


def active() -> Hardware:
    """The hardware in force: the one set by :func:`use`, else the file named by
    ``$SIXPLUS3_HARDWARE``, else the built-in catalogue's default drive train."""
    if _ACTIVE:
        return _ACTIVE[-1]
    path = os.environ.get(ENV)
    if path:
        hw = load_hardware(path)
        _ACTIVE.append(hw)
        return hw
    return Hardware()


def judged_links(named: object) -> tuple[str, ...]:
    """The leg links judged for power and force limiting where a task or a file names
    ``named`` (None: every reachable link, :data:`leg_links.ALL`): those and the site's,
    which no task or file can drop (:func:`leg_links.link_names`' form)."""
    own = link_names([ALL] if named is None else named)
    return link_names(list(active().pfl_links) + list(own))


def use(hw: Hardware | None) -> None:
    """Put ``hw`` in force for this process (``None``: back to the environment's)."""
    _ACTIVE.clear()
    if hw is not None:
        _ACTIVE.append(hw)


def envelope_record(hw: Hardware | None = None) -> dict[str, Any]:
    """What a report prints of the envelope: its drive train, origin and limits."""
    hw = active() if hw is None else hw
    return {"drive_train": hw.drive_train, "origin": hw.origin,
            "limits": json.loads(json.dumps(hw.limits.as_dict())), "pfl": list(hw.pfl),
            "pfl_links": list(hw.pfl_links),
            "position_loop": None if hw.position_loop is None else hw.position_loop._asdict(),
            "guard_detection": hw.guard_detection}
