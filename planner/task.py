"""Planning tasks: platform waypoints + limits, from YAML, validated against a schema.

Example (units: m and degrees in the file, SI inside)::

    name: tilt-30-x
    waypoints:
      - position: [0.0, 0.0, 0.30]
        rpy: [0, 0, 0]              # roll, pitch, yaw [deg] (R = Rz Ry Rx), or
      - position: [0.0, 0.0, 0.30]
        quaternion: [0.2588, 0, 0, 0.9659]   # x, y, z, w
        psi: [90, 90, 90]           # optional crank angles [deg]; free otherwise
        stop: true                  # optional: come to rest here (v = 0, a = 0)
        dwell: 0.5                  # optional: then hold the pose [s] (implies stop)
    pfl: [hand, lower_arm]          # optional: power and force limiting (docs/safety.md)
    pfl_links: [legs]               # optional: the leg links with them (default: all)
    people: collaborative           # optional: named platform limits (PEOPLE_LIMITS)
    limits:                         # optional: only tightens the robot's hardware limits
      torque: 9                     # |tau| [N m]            (robot: 10)
      velocity: 10                  # |theta_dot| [rad/s]    (robot: 14.8)
      acceleration: 150             # |theta_ddot| [rad/s^2] (robot: 200)
      margin: 0.08                  # every singularity margin (robot: 0.05)
      jerk: 1.0e5                   # |d theta_ddot/dt| [rad/s^3]  (robot: 2e5)
      torque_rate: 1500             # |d tau/dt| [N m/s]           (robot: 2000)
      tcp_speed: 0.25               # |v| of the tool centre point [m/s]    (robot: none)
      tcp_acceleration: 19.62       # |a| of the tool centre point [m/s^2]  (robot: none)
    nodes_per_segment: 12           # optional: node intervals per segment (default: 18 for
                                    # one segment, 12 for more; Task.segment_nodes)
    torque_fraction: 0.9            # plan to this share of the torque limit (default 0.9)
    duration: 2.0                   # optional: exactly this long [s], minimum effort; or
    speed: 0.5                      # optional: the minimum time / 0.5 (also minimum effort)
    frame: platform                 # or tcp: waypoints give the tool centre point's pose
    start: {theta: [...9 deg...]}   # optional: the robot's current actuated angles
    start_psi: home                 # or free: first crank angles (when not given)
    end_psi: start                  # or free: last crank angles (when not given)
    setup:                          # optional: the physical setup of the day
      mounting: floor               # or ceiling (gravity +z in the robot frame)
      payload: {mass: 0.5, com: [0, 0, 0.05], inertia: [1e-3, 1e-3, 1e-3, 0, 0, 0]}
      tool: {xyz: [0, 0, 0.12], rpy: [0, 0, 0]}   # TCP in the platform frame [m, deg]

The motion starts and ends at rest and passes through the waypoints in order (stopping
where asked); the timing is free.  A bad file raises :class:`TaskError` naming the
field, its value and the range; a limit looser than the robot's raises
:class:`LimitError` when the task is planned for a robot (:meth:`Task.limits_for`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.errors import ConvergenceError, GeometryError, InputError, TaskError
from sixplus3.fileio import first_non_finite, read_yaml, short_repr
from sixplus3.kinematics.robot_fk import robot_fk
from sixplus3.planner.waypoint import Waypoint
from sixplus3.robot_description.body_regions import all_names, regions
from sixplus3.robot_description.hardware import PEOPLE_LIMITS, effective_limits, people_limits
from sixplus3.robot_description.leg_links import link_names
from sixplus3.robot_description.limits import Limits
from sixplus3.robot_description.physical import Payload, Tool
from sixplus3.robot_description.robot import MOUNTINGS, Robot

#: Default share of the torque limit a plan may use: 10 % is left for the feedback of the
#: drives' position/velocity loops (measured need: docs/planner.md, "Feedback reserve").
DEFAULT_TORQUE_FRACTION = 0.9
#: Node intervals per segment when a task does not give them: (one segment, more)
#: (:attr:`Task.segment_nodes`)
AUTO_NODES = (18, 12)

_VEC3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}
SCHEMA = {
    "type": "object",
    "required": ["waypoints"],
    "additionalProperties": False,
    "properties": {
        "name": {"type": "string", "maxLength": 200},
        "description": {"type": "string"},
        "waypoints": {
            "type": "array", "minItems": 1, "maxItems": 50,
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
                    "stop": {"type": "boolean"},
                    "dwell": {"type": "number", "minimum": 0, "maximum": 60},
                },
                "not": {"required": ["rpy", "quaternion"]},
            },
        },
        "limits": {
            "type": "object", "additionalProperties": False,
            "properties": {
                "torque": {"type": "number", "exclusiveMinimum": 0},
                "velocity": {"type": "number", "exclusiveMinimum": 0},
                "acceleration": {"type": "number", "exclusiveMinimum": 0},
                "jerk": {"type": "number", "exclusiveMinimum": 0},
                "torque_rate": {"type": "number", "exclusiveMinimum": 0},
                "tcp_speed": {"type": "number", "exclusiveMinimum": 0},
                "tcp_acceleration": {"type": "number", "exclusiveMinimum": 0},
                "margin": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1},
            },
        },
        "people": {"enum": sorted(PEOPLE_LIMITS)},
        "pfl": {"type": "array", "items": {"enum": all_names()}, "maxItems": 24},
        "pfl_links": {"type": "array", "items": {"type": "string"}, "maxItems": 24},
        "nodes_per_segment": {"type": "integer", "minimum": 4, "maximum": 60},
        "frame": {"enum": ["platform", "tcp"]},
        "start": {
            "type": "object", "additionalProperties": False, "required": ["theta"],
            "properties": {"theta": {"type": "array", "minItems": 9, "maxItems": 9,
                                     "items": {"type": "number", "minimum": -90,
                                               "maximum": 360}}},
        },
        "duration": {"type": "number", "exclusiveMinimum": 0, "maximum": 600},
        "speed": {"type": "number", "exclusiveMinimum": 0, "maximum": 1},
        "start_psi": {"enum": ["home", "free"]},
        "end_psi": {"enum": ["start", "free"]},
        "torque_fraction": {"type": "number", "minimum": 0.5, "maximum": 1.0},
        "setup": {
            "type": "object", "additionalProperties": False,
            "properties": {
                "mounting": {"enum": sorted(MOUNTINGS)},
                "payload": {
                    "type": "object", "additionalProperties": False, "required": ["mass"],
                    "properties": {
                        "mass": {"type": "number", "minimum": 0, "maximum": 20},
                        "com": {**_VEC3, "items": {"type": "number", "minimum": -1,
                                                   "maximum": 1}},
                        "inertia": {"type": "array", "items": {"type": "number"},
                                    "minItems": 6, "maxItems": 6},
                    },
                },
                "tool": {
                    "type": "object", "additionalProperties": False,
                    "properties": {
                        "xyz": {**_VEC3, "items": {"type": "number", "minimum": -1,
                                                   "maximum": 1}},
                        "rpy": {**_VEC3, "items": {"type": "number", "minimum": -180,
                                                   "maximum": 180}},
                    },
                },
            },
        },
    },
}


@dataclass(frozen=True)
class Task:
    waypoints: tuple[Waypoint, ...]
    #: limits the task asks for, tightening the robot's (name -> value, SI units)
    limits: dict[str, float] = field(default_factory=dict)
    name: str = "task"
    #: node intervals per segment; None: :data:`AUTO_NODES` (see :attr:`segment_nodes`)
    nodes_per_segment: int | None = None
    source: dict[str, Any] | None = None  # the validated file content, for the trajectory header
    #: "platform": waypoints are the platform centre's poses; "tcp": the tool's
    frame: str = "platform"
    #: the physical setup the task replaces on the robot (None: the robot's own)
    payload: Payload | None = None
    tool: Tool | None = None
    mounting: str | None = None
    #: the share of the (task's) torque limit the plan may use; the rest is the reserve
    #: for the controller's feedback (the validator checks the hardware limit)
    torque_fraction: float = DEFAULT_TORQUE_FRACTION
    #: the robot's current 9 actuated angles [rad]: the motion starts there (forward
    #: kinematics gives the first waypoint, crank angles included)
    start_theta: np.ndarray | None = None
    #: crank angles at the first waypoint when not given: the robot's home ones ("home")
    #: or chosen by the planner ("free"); at the last: the first's ("start") or "free"
    start_psi: str = "home"
    end_psi: str = "start"
    #: timing: None/None is minimum time; ``duration`` [s] fixes it (minimum effort
    #: within the limits); ``speed`` in (0, 1] is the minimum time divided by it
    duration: float | None = None
    speed: float | None = None
    pfl: tuple[str, ...] = ()  #: body regions for power and force limiting (docs/safety.md)
    #: the leg links judged with them (robot_description.leg_links; None: every
    #: reachable link, the default; the site's are judged whatever a task says)
    pfl_links: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        wps = self.waypoints
        if not isinstance(wps, (tuple, list)) or not all(isinstance(w, Waypoint) for w in wps):
            raise TaskError("task waypoints must be a sequence of Waypoint",
                            value=type(wps).__name__, valid="a tuple of Waypoint")
        need = 1 if self.start_theta is not None else 2
        if len(wps) < need:
            raise TaskError(f"a task needs at least {need} waypoint(s)"
                            + (" besides its start state" if need == 1 else ""),
                            value=len(wps), valid=f">= {need}")
        object.__setattr__(self, "waypoints", tuple(wps))
        if not isinstance(self.limits, dict):
            raise TaskError("task limits must be a mapping of name to value",
                            value=type(self.limits).__name__, valid="a dict")
        # checked here, where a Task is built (task_from_dict's schema, or
        # dataclasses.replace, which skips the schema), and nowhere else
        n = self.nodes_per_segment
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or not 4 <= n <= 60):
            raise TaskError(f"task field nodes_per_segment must be an integer in [4, 60], got "
                            f"{n!r}", value=n, valid="[4, 60]")
        for name, lo, hi in (("duration", 0.0, 600.0), ("speed", 0.0, 1.0)):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))
                                  or not lo < v <= hi):
                raise TaskError(f"task field {name} must be in ({lo:g}, {hi:g}], got {v!r}",
                                value=v, valid=f"({lo:g}, {hi:g}]")

    @property
    def segment_nodes(self) -> int:
        """Node intervals per segment: ``nodes_per_segment``, or when it is not given
        18 for a one-segment motion and 12 for more (:data:`AUTO_NODES`).  On the
        held-out set, 12 intervals left one-segment plans up to 5.5 % slower than the
        fastest re-timing of their own path (the certificate); 18 brought every one
        within 2 % (BENCHMARKS.md)."""
        if self.nodes_per_segment is not None:
            return self.nodes_per_segment
        return AUTO_NODES[0] if self.n_segments == 1 else AUTO_NODES[1]

    @property
    def n_segments(self) -> int:
        """Segments of the motion (a start state adds one)."""
        return len(self.waypoints) - 1 + (self.start_theta is not None)

    def robot_for(self, robot: Robot) -> Robot:
        """``robot`` with the task's payload, tool and mounting (its limits unchanged)."""
        changes: dict[str, Any] = {}
        if self.payload is not None:
            changes["payload"] = self.payload
        if self.tool is not None:
            changes["tool"] = self.tool
        if self.mounting is not None:
            changes["gravity"] = MOUNTINGS[self.mounting]
        return robot.replace(**changes) if changes else robot

    def resolved(self, robot: Robot) -> Task:
        """The task as the planner takes it, for ``robot`` (:meth:`robot_for`'s):

        - every waypoint a platform pose (TCP waypoints converted with ``robot.tool``);
        - a ``start_theta`` turned into the first waypoint by forward kinematics (from
          the robot's home branch), crank angles included;
        - the crank angles of the first waypoint, when not given, the robot's home ones
          (``start_psi: home``), and those of the last the first's (``end_psi: start``).
        """
        wps = list(self.waypoints)
        if self.frame == "tcp":
            wps = [Waypoint(*robot.tool.platform_pose(wp.position, wp.rotation), wp.psi,
                            wp.stop, wp.dwell) for wp in wps]
        if self.start_theta is not None:
            try:
                fk = robot_fk(self.start_theta, robot)
            except ConvergenceError as exc:
                raise TaskError(f"task field start.theta: no assembly of the robot has "
                                f"these actuated angles ({exc})",
                                value=np.degrees(self.start_theta).round(3).tolist(),
                                valid="the actuated angles of a reachable state") from None
            wps.insert(0, Waypoint(fk.position, fk.rotation, fk.psi, stop=True))
        if len(wps) < 2:
            raise TaskError("a task needs at least two waypoints (or a start state and "
                            "one waypoint)", value=len(wps), valid=">= 2")
        if wps[0].psi is None and self.start_psi == "home":
            wps[0] = replace(wps[0], psi=np.asarray(robot.home_psi, dtype=float))
        if wps[-1].psi is None and self.end_psi == "start" and wps[0].psi is not None:
            wps[-1] = replace(wps[-1], psi=np.array(wps[0].psi, dtype=float))
        return replace(self, waypoints=tuple(wps), frame="platform", start_theta=None,
                       start_psi="free", end_psi="free")


    def limits_for(self, robot: Robot) -> Limits:
        """The limits to plan to: the robot's hardware limits (and the site's,
        :func:`~sixplus3.robot_description.hardware.effective_limits`), tightened by the task's,
        with the torque limit scaled by :attr:`torque_fraction` (the feedback reserve).
        Raises :class:`~sixplus3.errors.LimitError` if the task asks for a looser one."""
        lim = effective_limits(robot).tightened(**self.limits)
        return lim.tightened(torque=lim.torque * self.torque_fraction)


def _path(error: jsonschema.ValidationError) -> str:
    out = ""
    for p in error.absolute_path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(top level)"


def task_from_dict(doc: object, name: str = "task") -> Task:
    """Validate a task document (as loaded from YAML) and build the :class:`Task`."""
    bad = first_non_finite(doc)
    if bad:
        raise TaskError(f"task field {bad}: NaN or infinite; every number must be finite",
                        value=float("nan"), valid="finite numbers")
    validator = jsonschema.Draft202012Validator(SCHEMA)
    errors = sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path))
    if errors:
        e = errors[0]
        raise TaskError(f"task field {_path(e)}: {short_repr(e.message, 200)} (value "
                        f"{short_repr(e.instance)})", value=short_repr(e.instance),
                        valid=short_repr(e.schema, 200))
    assert isinstance(doc, dict)
    if "duration" in doc and "speed" in doc:
        raise TaskError("task fields duration and speed: give one of them, not both",
                        value=(doc["duration"], doc["speed"]),
                        valid="duration [s] or speed in (0, 1]")
    if len(doc["waypoints"]) < 2 and "start" not in doc:
        raise TaskError("task field waypoints: one waypoint needs a start state (start: "
                        "{theta: [...]}); otherwise give at least two",
                        value=len(doc["waypoints"]), valid=">= 2 waypoints, or a start")
    wps = []
    for k, w in enumerate(doc["waypoints"]):
        pos = np.array(w["position"], dtype=float)
        if "quaternion" in w:
            qq = np.array(w["quaternion"], dtype=float)
            norm = np.linalg.norm(qq)
            if not (abs(norm - 1.0) < 1e-3):
                raise TaskError(f"task field waypoints[{k}].quaternion: norm {norm:.6f}, must "
                                "be a unit quaternion (x, y, z, w) within 1e-3",
                                value=float(norm), valid="|q| = 1 within 1e-3")
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
                                "(3, 177) deg or (-177, -3) deg",
                                value=w['psi'], valid="(3, 177) or (-177, -3) deg")
        dwell = float(w.get("dwell", 0.0))
        wps.append(Waypoint(pos, rot, psi, stop=bool(w.get("stop", False)) or dwell > 0,
                            dwell=dwell))
    lim = {k: float(v) for k, v in doc.get("limits", {}).items()}
    for name, value in people_limits(doc.get("people")).items():  # a named set tightens
        lim[name] = min(lim.get(name, value), value)
    setup = doc.get("setup", {})
    try:
        payload = Payload(**setup["payload"]) if "payload" in setup else None
        tool = None
        if "tool" in setup:
            t = setup["tool"]
            roll, pitch, yaw = (math.radians(a) for a in t.get("rpy", (0.0, 0.0, 0.0)))
            tool = Tool(xyz=t.get("xyz", (0.0, 0.0, 0.0)), rpy=(roll, pitch, yaw))
    except GeometryError as exc:
        raise TaskError(f"task field setup.{exc.name}: {exc}", value=exc.value,
                        valid=exc.valid) from None
    return Task(tuple(wps), lim, str(doc.get("name", name)),
                int(doc["nodes_per_segment"]) if "nodes_per_segment" in doc else None,
                source=doc,
                frame=str(doc.get("frame", "platform")), payload=payload, tool=tool,
                mounting=setup.get("mounting"),
                torque_fraction=float(doc.get("torque_fraction", DEFAULT_TORQUE_FRACTION)),
                start_theta=(np.radians(np.array(doc["start"]["theta"], dtype=float))
                             if "start" in doc else None),
                start_psi=str(doc.get("start_psi", "home")),
                end_psi=str(doc.get("end_psi", "start")),
                duration=float(doc["duration"]) if "duration" in doc else None,
                speed=float(doc["speed"]) if "speed" in doc else None, pfl=tuple(
                    r.name for r in regions(doc.get("pfl", []))),
                pfl_links=link_names(doc["pfl_links"]) if "pfl_links" in doc else None)


def load_task(path: str | Path) -> Task:
    """Read and validate a YAML task file; raises :class:`TaskError`."""
    try:
        doc = read_yaml(path, "task file")
    except InputError as exc:
        raise TaskError(str(exc), value=exc.value, valid=exc.valid) from None
    return task_from_dict(doc, name=Path(path).stem)


def move_to_start(task: Task, theta: np.ndarray, robot: Robot) -> Task:
    """A task from the robot's current actuated angles ``theta`` [rad] to ``task``'s start
    state (its first waypoint with its crank angles, at rest), for ``robot``."""
    first = task.resolved(task.robot_for(robot)).waypoints[0]
    return replace(task, waypoints=(replace(first, stop=True, dwell=0.0),),
                   name=f"{task.name}_move_to_start", source=None, frame="platform",
                   start_theta=np.asarray(theta, dtype=float), start_psi="free",
                   end_psi="free", duration=None, speed=None)

