"""A person in the virtual prototype (docs/safety.md, "A simulated person"): a body
region in the platform's way, as ISO/TS 15066's two-body model, with the trajectory run
on a MuJoCo plant by the drives through the one drive loop, a controller in it (the
contact guard: :func:`~sixplus3.interaction.people.person.run_contact` builds it) or
the plan followed as it is (:func:`meet`).  A test harness beside the plant it drives,
not a part a controller uses.

The region is a plane through the tool centre point's planned position at the contact
instant ``at``, facing the motion along the normal n (default: the direction of the
planned velocity there).  Its surface is a spring of the region's constant k; a free
region (``kind: free``, a transient contact) is a mass m_H on that spring, pushed
along n; a clamped one (``kind: clamp``) is backed by a wall.  The force
F = k max(0, (p - p_s).n - x_H) acts on the platform at the point (MuJoCo's
``xfrc_applied``, along -n); it is the model's force, not MuJoCo's contact solver's.

A contact file (YAML): ``region`` (a body region name), ``kind`` (free or clamp),
``at`` [s] (the file's time of contact), optional ``normal`` [3] (base frame) and
``point`` (tcp or centre; default tcp).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.control.drive.command import DriveCommand, FileController, TickController
from sixplus3.control.drive.loop import KD, KP, DriveSettings, Tick, run
from sixplus3.control.drive.mujoco_model import MujocoRobot
from sixplus3.control.drive.simulation import first_configuration
from sixplus3.control.file.drive_log import DriveLog
from sixplus3.control.file.file_format import columns
from sixplus3.control.gate.interval import held_torque
from sixplus3.control.report import ValidationReport
from sixplus3.errors import InputError, ValidationFailed, check_number
from sixplus3.fileio import read_yaml
from sixplus3.kinematics import rotations as rot
from sixplus3.kinematics.robot import robot_ik
from sixplus3.kinematics.robot_fk import ik_jacobian
from sixplus3.kinematics.tcp import tcp_velocity
from sixplus3.robot_description.body_regions import REGIONS, BodyRegion
from sixplus3.robot_description.leg_links import VERTICES
from sixplus3.robot_description.robot import Robot, require_robot

#: A stopped point: its speed along the normal at most this [m/s].
STOPPED = 0.01
#: The transient phase: the first this many seconds after the onset of contact.
TRANSIENT = 0.05
#: Leg links a body region may meet (at the link's centre of mass): each leg's distal
#: links (the RU chain's D links, the RUS chains' G and H rods) and its cranks (A, B, C).
LEG_LINKS = tuple(f"leg{i}_{b}" for i in range(3)
                  for b in ("A", "B", "C", "Ds2", "Ds3", "Ga", "Gb", "Ha", "Hb"))
#: Leg vertices a body region may meet (robot_description/leg_links.py: the joint
#: centres that bound the leg links, where they move fastest).
LEG_VERTICES = tuple(f"leg{i}_{v}" for i in range(3) for v in VERTICES)
#: Where the contact may be: the tool centre point, the platform centre, a leg link, a
#: leg vertex.
POINTS = ("tcp", "centre", *LEG_LINKS, *LEG_VERTICES)


@dataclass(frozen=True)
class Contact:
    region: BodyRegion
    kind: str  # "free" or "clamp"
    at: float  # [s] the file's time of contact
    normal: tuple[float, float, float] | None = None  # base frame; None: along the motion
    point: str = "tcp"


def contact_from_dict(doc: object, name: str = "contact") -> Contact:
    if not isinstance(doc, dict):
        raise InputError(f"{name} must be a mapping (region, kind, at, normal, point)",
                         value=type(doc).__name__, valid="a mapping")
    extra = sorted(set(doc) - {"region", "kind", "at", "normal", "point"})
    if extra:
        raise InputError(f"{name}: unknown key {extra[0]!r}", value=extra[0],
                         valid="region, kind, at, normal, point")
    region = doc.get("region")
    if not isinstance(region, str) or region not in REGIONS:  # a list or a mapping too
        raise InputError(f"{name}: region must be one of {', '.join(REGIONS)}, got "
                         f"{str(region)[:80]!r}", value=str(region)[:80],
                         valid=", ".join(REGIONS))
    kind = doc.get("kind", "free")
    if not isinstance(kind, str) or kind not in ("free", "clamp"):
        raise InputError(f"{name}: kind must be free or clamp, got {kind!r}", value=kind,
                         valid="free or clamp")
    at = check_number(f"{name}: at [s]", doc.get("at"), 0.0, 600.0)
    normal = doc.get("normal")
    nv: tuple[float, float, float] | None = None
    if normal is not None:
        if not (isinstance(normal, list) and len(normal) == 3):
            raise InputError(f"{name}: normal must be 3 numbers", value=normal,
                             valid="[nx, ny, nz]")
        vals = [check_number(f"{name}: normal", x, -1e3, 1e3) for x in normal]
        norm = math.sqrt(sum(x * x for x in vals))
        if norm < 1e-9:
            raise InputError(f"{name}: normal must not be zero", value=normal,
                             valid="a non-zero vector")
        nv = (vals[0] / norm, vals[1] / norm, vals[2] / norm)
    point = doc.get("point", "tcp")
    if not isinstance(point, str) or point not in POINTS:
        raise InputError(f"{name}: point must be one of {', '.join(POINTS)}, got "
                         f"{point!r}", value=point, valid=", ".join(POINTS))
    return Contact(REGIONS[str(region)], str(kind), at, nv, str(point))


def read_contact(path: str | Path) -> Contact:
    return contact_from_dict(read_yaml(path, "contact file"), f"contact file {Path(path).name}")


@dataclass
class ContactRun:
    """What the contact did (module doc); forces [N], times [s], speeds [m/s]."""

    region: str
    kind: str
    guard: bool
    speed: float  # the point's speed along n at the onset of contact
    onset: float | None  # when the force first rose (None: no contact happened)
    peak_transient: float  # largest force within TRANSIENT of the onset
    quasi_static: float  # the force at the end of the run
    limit_transient: float
    limit_quasi_static: float
    detection_delay: float | None  # the guard's first contact flag after the onset
    stop_time: float | None  # the point stopped (or moving away) after the onset
    false_alarm: bool  # the guard flagged before any force
    peak_command: float  # [N m] the largest |tau_ff + PD| the drives were asked for
    site: str | None = None  # where the guard placed the contact (the platform, a leg)
    modes: list[str] = field(default_factory=list)
    events: list[str] = field(default_factory=list)
    log: DriveLog | None = field(default=None, repr=False)  # what the drives measured
    #: (n,) [m/s] the contact point's speed along the normal each tick (MuJoCo's)
    speed_n: np.ndarray | None = field(default=None, repr=False)

    @property
    def within_limits(self) -> bool:
        return (self.peak_transient <= self.limit_transient
                and self.quasi_static <= self.limit_quasi_static)

    def summary(self) -> dict[str, Any]:
        out = {k: getattr(self, k) for k in (
            "region", "kind", "guard", "speed", "onset", "peak_transient", "quasi_static",
            "limit_transient", "limit_quasi_static", "detection_delay", "stop_time",
            "false_alarm", "peak_command", "site", "modes", "events")}
        out["within_limits"] = self.within_limits
        return out


def checked_run(kp: float, kd: float, after: float, drive: DriveSettings | None
                ) -> DriveSettings:
    """A run's drive gains, its time after the contact and its drive settings checked
    with their ranges (the default drive: the encoder's difference)."""
    drive = DriveSettings.of(drive)
    for name, v, lo, hi in (("after", after, 0.0, 30.0), ("kp", kp, 0.0, 1e5),
                            ("kd", kd, 0.0, 1e4), ("seed", drive.seed, 0, 2 ** 32 - 1)):
        check_number(name, v, lo, hi, integer=name == "seed")
    return drive


def meet(rep: ValidationReport, path: str | Path, model: Robot, plant: Robot,
         contact: Contact | None, controller: TickController | None, kp: float = KP,
         kd: float = KD, after: float = 0.5, drive: DriveSettings | None = None
         ) -> ContactRun:
    """Run the file ``path`` (``rep``: the gate's report of it, which it passed) on
    ``plant`` with the person ``contact`` (None: nobody, for false alarms) in the way
    (module doc), ``controller`` in the loop (the contact guard; None: the plan followed
    as it is), for ``after`` seconds past the contact (or the file's end); ``drive``:
    the drives' rate feedback, torque noise, seed and MuJoCo's step (loop.py; default:
    the encoder's difference).  The controller's ``events`` and ``contact_site``, when it
    has them, are the run's."""
    model, plant = require_robot(model), require_robot(plant)
    drive = checked_run(kp, kd, after, drive)
    seed, timestep, torque_noise = drive.seed, drive.timestep, drive.torque_noise
    if not rep.ok or rep.data is None or rep.header is None:
        raise ValidationFailed("not run: " + "; ".join(rep.messages()), rep.exit_code, rep)
    rate = float(rep.header["rate_hz"])
    data = rep.data
    t_file = data[:, 0]
    n_file = len(t_file)
    theta_ref, vel_ref = columns(data, "pos"), columns(data, "vel")
    ff_file = held_torque(columns(data, "tau"), "mean")
    assert rep.position is not None and rep.quaternion is not None and rep.psi is not None
    cfg = robot_ik(rep.position, rot.matrix_from_quat(rep.quaternion), rep.psi, model,
                   platform_margins=False)
    body_name, tool = contact_site(model, contact)
    if contact is not None and contact.at > t_file[-1]:
        raise InputError(f"the contact at {contact.at:g} s is after the file's end "
                         f"({t_file[-1]:g} s)", value=contact.at,
                         valid=f"[0, {t_file[-1]:g}] s")
    n = n_file + int(round(after * rate))
    k_on = 0  # the body region is there from when the point last approached it
    p_s = normal = None
    if contact is not None:
        n = min(n, int(round((contact.at + after) * rate)) + 1)
        p_s, normal, k_on = _where(contact, model, rep, cfg, rate, (body_name, tool),
                                   timestep)
    g = controller
    # the drives: the one drive loop, with the rate feedback a drive without an
    # observer has (the encoder's difference, which the guard's bound assumes too)
    loop = drive.loop(plant, rate, kp, kd)
    loop.start(first_configuration(model, rep))
    mj, m, d = loop.sim.mj, loop.sim.model, loop.sim.data
    body = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, body_name)
    person = None
    if contact is not None:
        assert p_s is not None and normal is not None
        person = _Region(contact, p_s, normal, d, body, tool, timestep)
    force, speed_n = np.zeros(n), np.zeros(n)

    def before_tick(k: int, _cmd: DriveCommand) -> Callable[[int], None] | None:
        return person.push if person is not None and k >= k_on else None

    def after_tick(k: int, _tick: Tick) -> None:
        if person is not None:
            force[k] = person.peak
            person.peak = 0.0
            jac = np.zeros((3, m.nv))
            mj.mj_jac(m, d, jac, None, site_point(d, body, tool), body)
            speed_n[k] = float((jac @ d.qvel) @ person.n)
        d.xfrc_applied[body] = 0.0

    # the guard, or the file followed as it is, through the one drive loop; before the
    # first tick the drives held the file's first torque
    ctrl = g if g is not None else FileController(theta_ref, vel_ref, ff_file,
                                                  hold_tau=columns(data, "tau")[-1])
    out = run(loop, ctrl, n, initial=ff_file[0], before=before_tick, after=after_tick)
    flags = np.array([c.contact for c in out.commands]) if g is not None else np.zeros(n, bool)
    modes: list[str] = []
    for c in out.commands if g is not None else []:
        if not modes or modes[-1] != c.mode:
            modes.append(c.mode)
    peak_cmd = float(np.abs(out.command).max())
    th_log, tau_log = out.theta, out.readings[:n]
    result = _outcome(contact, g is not None, rate, force, speed_n, flags, modes, peak_cmd,
                      list(getattr(g, "events", [])))
    result.site = getattr(g, "contact_site", None)
    result.speed_n = speed_n
    result.log = DriveLog(
        t=np.arange(n) / rate, theta=th_log, tau=tau_log, name=Path(path).name,
        meta={"plant": plant.name, "seed": seed, "torque_noise": torque_noise,
              "guard": g is not None, "contact": None if contact is None else
              {"region": contact.region.name, "kind": contact.kind, "at": contact.at}})
    return result


def contact_site(model: Robot, contact: Contact | None) -> tuple[str, np.ndarray | None]:
    """(MuJoCo's body, the point in its frame [m]; None: its centre of mass) of the
    contact's point: the platform's at the tool centre point or the centre, a leg
    link's centre of mass, or a leg vertex (a joint centre, robot_description/urdf.py:
    D, G and H the universal joints' crosses, E, F and P on the RU chain's body)."""
    if contact is None or contact.point in ("tcp", "centre"):
        at_tool = contact is None or contact.point == "tcp"
        return "platform_free", np.asarray(model.tool.xyz if at_tool else (0.0,) * 3,
                                           dtype=float)
    if contact.point in LEG_LINKS:
        return contact.point, None
    i, v = contact.point[:4], contact.point[5:]
    leg = model.geometry.leg
    body = {"D": "Ds2", "G": "Ga", "H": "Ha"}.get(v, "Ds3")
    offset = {"E": leg.e_b, "F": leg.f_b, "P": (leg.dp, 0.0, 0.0)}.get(v, (0.0,) * 3)
    return f"{i}_{body}", np.asarray(offset, dtype=float)


def _where(contact: Contact, model: Robot, rep: Any, cfg: Any, rate: float,
           site: tuple[str, np.ndarray | None], timestep: float
           ) -> tuple[np.ndarray, np.ndarray, int]:
    """Where the body region is (module doc): the contact point's planned position at
    the contact, the surface's normal (given, or the point's direction of motion) and
    the sample from which the region is in the way (the point's last approach)."""
    data = rep.data
    n_file = len(data)
    k_c = int(round(contact.at * rate))
    rates = columns(data, "vel")
    tool = site[1]
    if site[0] != "platform_free":  # a leg's point, from MuJoCo's kinematics of the model
        planned, v_c = _link_path(model, cfg, rates, k_c, site, timestep)
    else:
        assert tool is not None
        R_all = rot.matrix_from_quat(rep.quaternion[:k_c + 1])
        planned = rep.position[:k_c + 1] + np.einsum("nij,j->ni", R_all, tool)
        one = cfg.take(np.arange(n_file) == k_c)
        if contact.point == "tcp":
            v_c = tcp_velocity(one, rates[k_c:k_c + 1])[0]
        else:  # the centre's velocity: the first three of J^-1 theta_dot
            v_c = np.linalg.solve(ik_jacobian(one), rates[k_c:k_c + 1, :, None])[0, 0:3, 0]
    p_s = planned[k_c]
    if contact.normal is not None:
        normal = np.asarray(contact.normal, dtype=float)
    else:
        sp = float(np.linalg.norm(v_c))
        if sp < 1e-6:
            raise InputError(f"the point does not move at {contact.at:g} s: give the "
                             "contact's normal", value=contact.at, valid="a moving instant")
        normal = v_c / sp
    ahead = (planned - p_s) @ normal <= 1e-9
    k_on = k_c
    while k_on > 0 and ahead[k_on - 1]:
        k_on -= 1
    return p_s, normal, k_on


class _Region:
    """The body region in the way (module doc): its surface's displacement x_h along n
    and rate v_h; :meth:`push` (before each MuJoCo sub-step) puts the model's force on
    the body and keeps the tick's largest in :attr:`peak`."""

    def __init__(self, contact: Contact, p_s: np.ndarray, normal: np.ndarray, d: Any,
                 body: int, offset: np.ndarray | None, timestep: float) -> None:
        self.c, self.p_s, self.n, self.d = contact, p_s, normal, d
        self.body, self.offset, self.dt = body, offset, timestep
        self.x_h = self.v_h = self.peak = 0.0
        self.armed = False  # the point has been outside the region since it appeared

    def push(self, _sub: int) -> None:
        d, body = self.d, self.body
        p = site_point(d, body, self.offset)
        depth = float((p - self.p_s) @ self.n) - self.x_h
        self.armed = self.armed or depth <= 0.0
        f = self.c.region.stiffness * depth if (depth > 0 and self.armed) else 0.0
        if self.c.kind == "free":  # the region's mass on its spring
            self.v_h += f / self.c.region.mass * self.dt
            self.x_h += self.v_h * self.dt
        fv = -f * self.n
        d.xfrc_applied[body, :3] = fv
        d.xfrc_applied[body, 3:] = np.cross(p - d.xipos[body], fv)
        self.peak = max(self.peak, f)


def site_point(d: Any, body: int, offset: np.ndarray | None) -> np.ndarray:
    """The contact point in MuJoCo's data: the body's centre of mass (``offset`` None),
    or the point at ``offset`` in its frame."""
    if offset is None:
        return np.array(d.xipos[body])
    return np.asarray(d.xpos[body] + d.xmat[body].reshape(3, 3) @ offset)


def _link_path(model: Robot, cfg: Any, rates: np.ndarray, k_c: int,
               site: tuple[str, np.ndarray | None], timestep: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(the planned positions (k_c + 1, 3) of the leg's point ``site``
    (:func:`contact_site`) up to sample k_c, its velocity (3,) there): MuJoCo's
    kinematics of the model at the file's configurations, with the tree velocities
    that realise the actuated rates."""
    sim = MujocoRobot(model, timestep)
    mj, m, d = sim.mj, sim.model, sim.data
    body = mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, site[0])
    out = np.empty((k_c + 1, 3))
    for k in range(k_c + 1):
        sim.set_state(np.asarray(cfg.q[k]), rates[k])
        out[k] = site_point(d, body, site[1])
    jac = np.zeros((3, m.nv))
    mj.mj_jac(m, d, jac, None, out[k_c], body)
    return out, jac @ d.qvel


def _outcome(contact: Contact | None, guard: bool, rate: float, force: np.ndarray,
             speed_n: np.ndarray, flags: np.ndarray, modes: list[str], peak_cmd: float,
             events: list[str]) -> ContactRun:
    touched = np.flatnonzero(force > 0.0)
    onset = None if len(touched) == 0 else int(touched[0])
    first_flag = np.flatnonzero(flags)
    false_alarm = bool(len(first_flag) and (onset is None or first_flag[0] < onset))
    region = contact.region if contact is not None else REGIONS["hand"]
    out = ContactRun(region=region.name if contact is not None else "none",
                     kind=contact.kind if contact is not None else "none", guard=guard,
                     speed=0.0, onset=None, peak_transient=0.0,
                     quasi_static=float(force[-1]) if len(force) else 0.0,
                     limit_transient=region.transient_force,
                     limit_quasi_static=region.force, detection_delay=None, stop_time=None,
                     false_alarm=false_alarm, peak_command=peak_cmd, modes=modes,
                     events=list(events))
    if onset is None:
        return out
    out.onset = onset / rate
    out.speed = float(speed_n[max(onset - 1, 0)])
    win = int(round(TRANSIENT * rate))
    out.peak_transient = float(force[onset:onset + win + 1].max())
    later = np.flatnonzero(flags[onset:])
    out.detection_delay = None if len(later) == 0 else later[0] / rate
    stopped = np.flatnonzero(speed_n[onset:] <= STOPPED)
    out.stop_time = None if len(stopped) == 0 else stopped[0] / rate
    return out


__all__ = ["LEG_LINKS", "LEG_VERTICES", "POINTS", "STOPPED", "TRANSIENT", "Contact",
           "ContactRun", "checked_run", "contact_from_dict", "contact_site", "meet",
           "read_contact",
           "site_point"]
