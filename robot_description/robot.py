"""The robot: its geometry (:mod:`sixplus3.robot_description.robot_geometry`), assembly
mode, masses and inertials, motors, limits, payload, tool, mounting and collision sizes,
its hash, and its file (YAML).  The named mountings and the built robot's defaults.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3 import fileio
from sixplus3.errors import GeometryError, InputError
from sixplus3.fileio import read_yaml
from sixplus3.robot_description.assembly import AssemblyMode
from sixplus3.robot_description.collision import CollisionModel
from sixplus3.robot_description.geometry import GRAVITY, LegGeometry
from sixplus3.robot_description.hardware import (
    catalogue_envelope,
    check_robot_limits,
    people_limits,
)
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.masses import BodyInertials, MassModel
from sixplus3.robot_description.physical import MotorModel, Payload, Tool, _vec
from sixplus3.robot_description.robot_geometry import RobotGeometry, default_geometry

#: The built robot's assembly mode: the paper's §V assembly (cranks inward).
DEFAULT_ROBOT_MODE = AssemblyMode.parse("++--")
#: The built robot's home: the deepest point of its interference-free 2 g COW
#: (design.cow.deepest_point; tests/test_named_robots.py recomputes it).
DEFAULT_HOME = (0.0, 0.0, 0.58)


def _vec3(name: str, v: Any, unit: str) -> tuple[float, float, float]:
    x, y, z = _vec(name, v, 3, unit)
    return x, y, z


#: Gravity vectors in the robot frame of the named mountings [m/s^2].
MOUNTINGS = {"floor": (0.0, 0.0, -GRAVITY), "ceiling": (0.0, 0.0, GRAVITY)}


@dataclass(frozen=True)
class Robot:
    """Everything that defines one robot: the single value every part of sixplus3 takes.

    Frozen and validated; two robots with the same parameters are equal and have the
    same :attr:`hash` (SHA-256 of the canonical JSON of :meth:`as_dict`), which keys every
    cache (URDF text, Pinocchio model, CasADi functions, compiled libraries) and is
    recorded in every trajectory file.  Derive variants with :meth:`replace`.
    """

    geometry: RobotGeometry = field(default_factory=default_geometry, metadata={
        "doc": "leg geometry, base layout and platform [m, rad]"})
    mode: AssemblyMode = field(default=DEFAULT_ROBOT_MODE, metadata={
        "doc": "assembly mode: the IK branch of every leg, never switched in a motion"})
    masses: MassModel = field(default_factory=MassModel, metadata={
        "doc": "masses of the moving parts [kg]"})
    inertials: BodyInertials = field(default_factory=BodyInertials, metadata={
        "doc": "per-link mass, centre of mass and inertia replacing the rod model where "
               "a lab measured or identified them"})
    limits: Limits = field(default_factory=Limits, metadata={
        "doc": "hardware limits: the authority every plan and file is checked against"})
    motors: MotorModel = field(default_factory=MotorModel, metadata={
        "doc": "rotor inertia, transmission, friction, encoder of the actuated joints"})
    payload: Payload = field(default_factory=Payload, metadata={
        "doc": "rigid load fixed to the platform (mass, centre of mass, inertia)"})
    tool: Tool = field(default_factory=Tool, metadata={
        "doc": "tool centre point in the platform frame"})
    collision: CollisionModel = field(default_factory=CollisionModel, metadata={
        "doc": "sizes of the bodies every interference check measures [m]"})
    gravity: tuple[float, float, float] = field(default=MOUNTINGS["floor"], metadata={
        "doc": "gravity in the robot frame [m/s^2] (floor mounting: -z)"})
    home_position: tuple[float, float, float] = field(default=DEFAULT_HOME, metadata={
        "doc": "platform centre at the home pose, in the robot frame [m]"})
    home_psi: tuple[float, float, float] = field(default=(math.pi / 2,) * 3, metadata={
        "doc": "crank angles at the home pose [rad]"})
    name: str = field(default="sixplus3", metadata={"doc": "a label; not part of the hash"})

    def __post_init__(self) -> None:
        for attr, kind in (("geometry", RobotGeometry), ("masses", MassModel),
                           ("inertials", BodyInertials),
                           ("limits", Limits), ("motors", MotorModel),
                           ("payload", Payload), ("tool", Tool),
                           ("collision", CollisionModel)):
            if not isinstance(getattr(self, attr), kind):
                raise GeometryError(attr, getattr(self, attr), f"a {kind.__name__}")
        object.__setattr__(self, "mode", AssemblyMode.parse(self.mode))
        g = _vec3("gravity", self.gravity, "m/s^2")
        if not 0.0 <= math.hypot(*g) <= 100.0:
            raise GeometryError("gravity", g, "a vector of norm <= 100 m/s^2")
        object.__setattr__(self, "gravity", g)
        object.__setattr__(self, "home_position",
                           _vec3("home_position", self.home_position, "m"))
        psi = _vec3("home_psi", self.home_psi, "rad")
        if any(abs(math.sin(p)) < 0.05 for p in psi):
            raise GeometryError("home_psi", psi, "away from 0 and pi rad",
                                "a crank along its radius is a platform singularity")
        object.__setattr__(self, "home_psi", psi)
        if (not isinstance(self.name, str) or not 0 < len(self.name) <= 100
                or not self.name.isprintable()):
            raise GeometryError("name", fileio.short_repr(self.name, 40),
                                "1 to 100 printable characters (no control characters "
                                "such as ESC or newline)")
        check_robot_limits(self.limits, self.motors)

    # ------------------------------------------------------------------ construction
    @classmethod
    def default(cls) -> Robot:
        """The built robot: the paper's leg in its §V assembly on the layout of the layout
        study (docs/robot.md, "Named robots"; the dataclass defaults)."""
        return cls()

    @classmethod
    def named(cls, name: str) -> Robot:
        """One of the named robots of :data:`NAMED_ROBOTS` (docs/robot.md, "Named robots")."""
        key = str(name).strip().lower()
        if key not in NAMED_ROBOTS:
            raise GeometryError("robot name", name, f"one of {sorted(NAMED_ROBOTS)}")
        return NAMED_ROBOTS[key][0]()

    @classmethod
    def mounted(cls, mounting: str, **kw: Any) -> Robot:
        """The robot with a named mounting (``floor`` or ``ceiling``)."""
        if mounting not in MOUNTINGS:
            raise GeometryError("mounting", mounting, f"one of {sorted(MOUNTINGS)}")
        return cls(gravity=MOUNTINGS[mounting], **kw)

    def replace(self, **changes: Any) -> Robot:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)

    @property
    def leg(self) -> LegGeometry:
        return self.geometry.leg

    @property
    def mounting(self) -> str:
        """``floor``, ``ceiling`` or ``custom`` (a gravity vector of another direction)."""
        return next((k for k, v in MOUNTINGS.items() if v == self.gravity), "custom")

    @property
    def moving_mass(self) -> float:
        """Links plus payload [kg]."""
        return self.masses.total + self.payload.mass

    # ------------------------------------------------------------------ identity
    def as_dict(self) -> dict[str, Any]:
        """Every parameter as plain JSON-able values (SI units, angles in rad)."""
        return {
            "name": self.name,
            "geometry": {**{k: v for k, v in asdict(self.geometry).items() if k != "leg"},
                         "leg": asdict(self.geometry.leg)},
            "mode": self.mode.name,
            "masses": asdict(self.masses),
            **({"inertials": self.inertials.as_dict()} if self.inertials.bodies else {}),
            "limits": asdict(self.limits),
            "motors": {k: list(v) if isinstance(v, tuple) else v
                       for k, v in asdict(self.motors).items()},
            "payload": {k: list(v) if isinstance(v, tuple) else v
                        for k, v in asdict(self.payload).items()},
            "tool": {k: list(v) for k, v in asdict(self.tool).items()},
            "collision": self.collision.as_dict(),
            "gravity": list(self.gravity),
            "home_position": list(self.home_position),
            "home_psi": list(self.home_psi),
        }

    @classmethod
    def from_dict(cls, doc: object) -> Robot:
        """A robot from :meth:`as_dict`'s structure; missing keys keep their defaults.

        Unknown keys are refused (a typo must not silently give the default robot). A
        ``hash`` (as ``sixplus3 robot show --json`` prints) must be the parameters'.
        """
        if not isinstance(doc, dict):
            raise GeometryError("robot", type(doc).__name__, "a mapping of parameters")
        known = {f.name for f in fields(cls)} | {"mounting", "hash", "people"}
        _no_unknown("robot", doc, known)
        if "hash" in doc:  # what `robot show --json` prints: checked, not an input
            robot = cls.from_dict({k: v for k, v in doc.items() if k != "hash"})
            if doc["hash"] != robot.hash:
                raise GeometryError("hash", fileio.short_repr(doc["hash"], 20),
                                    f"{robot.hash[:12]}..., the hash of the parameters "
                                    "given", "remove the hash key after editing a "
                                    "parameter")
            return robot
        kw: dict[str, Any] = {}
        if "geometry" in doc:
            g = dict(_mapping("geometry", doc["geometry"]))
            _no_unknown("geometry", g, {f.name for f in fields(RobotGeometry)})
            leg = g.pop("leg", {})
            _no_unknown("geometry.leg", _mapping("geometry.leg", leg),
                        {f.name for f in fields(LegGeometry)})
            # missing keys keep the default robot's values (its leg and layout)
            base = default_geometry()
            kw["geometry"] = replace(base, leg=replace(base.leg, **leg), **g)
        if "masses" in doc:
            m = _mapping("masses", doc["masses"])
            _no_unknown("masses", m, {f.name for f in fields(MassModel)})
            kw["masses"] = MassModel(**m)
        if "inertials" in doc:
            kw["inertials"] = BodyInertials.from_dict(doc["inertials"])
        if "limits" in doc:
            lim = _mapping("limits", doc["limits"])
            _no_unknown("limits", lim, {f.name for f in fields(Limits)})
            kw["limits"] = Limits(**lim)
        if "people" in doc:  # a named set of platform limits: tightens, is not stored
            lim_ = kw.get("limits", Limits())
            kw["limits"] = lim_.replace_upper(**{
                k: min(v, getattr(lim_, k)) for k, v in people_limits(doc["people"]).items()})
        for key, kind in (("motors", MotorModel), ("payload", Payload), ("tool", Tool),
                          ("collision", CollisionModel)):
            if key in doc:
                sub = _mapping(key, doc[key])
                _no_unknown(key, sub, {f.name for f in fields(kind)})
                kw[key] = kind(**sub)
        if "mounting" in doc:
            if "gravity" in doc:
                raise GeometryError("mounting", doc["mounting"], "either mounting or "
                                    "gravity, not both")
            if not isinstance(doc["mounting"], str) or doc["mounting"] not in MOUNTINGS:
                raise GeometryError("mounting", doc["mounting"], f"one of {sorted(MOUNTINGS)}")
            kw["gravity"] = MOUNTINGS[doc["mounting"]]
        for key in ("mode", "gravity", "home_position", "home_psi", "name"):
            if key in doc:
                kw[key] = doc[key]
        return cls(**kw)

    @functools.cached_property
    def hash(self) -> str:
        """SHA-256 of the canonical JSON of every parameter except ``name``."""
        doc = self.as_dict()
        doc.pop("name")
        text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()

    def summary(self) -> str:
        """One line naming the design, the assembly and the mounting."""
        leg = self.leg
        return (f"{self.name}: l2 = {leg.l2:.3f}, l4 = {leg.l4:.3f}, ex = {leg.ex:.3f}, "
                f"ey = {leg.ey:.3f} m; assembly mode {self.mode.name}; {self.mounting} "
                f"mounting; rotor {self.motors.armature:.4f} kg m^2 at the joint; payload "
                f"{self.payload.mass:g} kg; hash {self.hash[:12]}")


def _paper_assembly(mode: str, name: str) -> Robot:
    """The paper's leg design in the assembly of its §V study on the layout its text
    states (tangential axes, gamma = 0, platform phase -45 deg): E = F (ey = 0, the
    paper's simplifying assumption), cranks on the branch that reproduces its optimum.
    Home is the deepest point of its 2 g-capable, singularity-free COW on the central
    vertical (``design.cow``; tests/test_named_robots.py recomputes it).  Its legs
    intersect: it is kept for the paper's numbers, not for motion."""
    return Robot(geometry=RobotGeometry(leg=LegGeometry(ey=0.0, fy=0.0)),
                 mode=AssemblyMode.parse(mode),
                 home_position=(0.0, 0.0, 0.54), name=name)


def _compact() -> Robot:
    """The robot built before the layout study: the paper's leg in mode ++++ (cranks
    outward), ey = 0.02 m, on the paper's stated layout, home z = 0.30 m.  Free of
    interference, with a 2.7 L torque-limited 2 g COW at z 0.18-0.32 m."""
    return Robot(geometry=RobotGeometry(), mode=AssemblyMode.parse("++++"),
                 home_position=(0.0, 0.0, 0.30), name="compact")


#: Named robots: name -> (constructor, one-line description).  ``--robot NAME`` on the CLI.
NAMED_ROBOTS: dict[str, tuple[Any, str]] = {
    "default": (Robot.default,
                "the built robot: the paper's leg in its §V assembly (mode ++--, cranks "
                "inward), ey = 0.01 m, actuated axes turned 28 deg (the layout study's "
                f"winner), home z = {DEFAULT_HOME[2]:.2f} m"),
    "paper-as-stated": (lambda: _paper_assembly("++--", "paper-as-stated"),
                        "the paper's §V assembly on the layout its text states: mode ++--, "
                        "ey = 0, tangential axes, home z = 0.54 m; adjacent legs' distal "
                        "links intersect at the base corners (kept for the paper's numbers)"),
    "paper-mirror": (lambda: _paper_assembly("-+++", "paper-mirror"),
                     "its theta1 mirror: mode -+++ (elbows inward), ey = 0, home z = 0.54 m; "
                     "the proximal links cross on the central axis"),
    "compact": (_compact,
                "the robot built before the layout study: mode ++++ (cranks outward), "
                "ey = 0.02 m, tangential axes, home z = 0.30 m; a 2.7 L 2 g COW"),
}


def hardware_envelope(motors: MotorModel) -> Limits:
    """The loosest limits any robot file may give: the envelope of the catalogue drive
    train its motors name (:func:`sixplus3.robot_description.hardware.catalogue_envelope`;
    never a figure of the file itself)."""
    return catalogue_envelope(motors.model)


def _mapping(name: str, v: object) -> dict[str, Any]:
    if not isinstance(v, dict):
        raise GeometryError(name, type(v).__name__, "a mapping of parameters")
    return v


def _no_unknown(where: str, doc: dict[str, Any], known: set[str]) -> None:
    bad = next((k for k in doc if not isinstance(k, str)), None)
    if bad is not None:
        raise GeometryError(f"{where} key", fileio.short_repr(bad, 40),
                            f"one of the known keys {sorted(known)} (text)", "not text")
    extra = sorted(set(doc) - known)
    if extra:
        raise GeometryError(f"{where}.{extra[0]}", doc[extra[0]],
                            f"one of the known keys {sorted(known)}", "unknown key")


def require_robot(robot: object) -> Robot:
    """``robot`` itself if it is a :class:`Robot`, else an InputError: library functions
    take their robot explicitly (only the CLI and ``sixplus3.plan`` choose the default)."""
    if not isinstance(robot, Robot):
        raise InputError("robot must be a Robot (Robot.default(), load_robot)",
                         value=type(robot).__name__, valid="a Robot")
    return robot


def load_robot(path: str | Path) -> Robot:
    """A robot from a YAML or JSON file of :meth:`Robot.as_dict`'s structure (missing
    keys keep the defaults; unknown keys are refused)."""

    robot = Robot.from_dict(read_yaml(path, "robot file"))
    arm = robot.motors.armature_per_joint
    if float(np.min(arm)) <= 0.0:  # a drive has a rotor; 0 is a model, not a measurement
        raise GeometryError("motors rotor inertia at the joint", [float(a) for a in arm],
                            "nine values in (0, 1] kg m^2 (every drive has a rotor)",
                            "a robot file describes a built robot; a zero rotor "
                            "inertia is not one")
    return robot
