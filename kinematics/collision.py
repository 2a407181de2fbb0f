"""Interference of the whole robot: the capsules of the collision model at a
configuration, and their smallest clearance (docs/robot.md, "Collision model").

The sizes are the robot's :class:`~sixplus3.robot_description.collision.CollisionModel`;
this module places the 36 bodies (:data:`BODIES`) and measures the pairs that can touch
(:data:`PAIRS`): the clearance is the smallest surface distance over those pairs and the
platform's height above the base plate, negative where bodies overlap.  The planner's
rows (:mod:`sixplus3.dynamics.symbolic`), its dense check, the gate, the COW, the atlas and
the layout study all call this module or its compiled kernel.

Pairs compared, and why the others are not:

- the six links of a leg against the six links and the hub of every other leg;
- the two distal links GE, HF of one leg (they end 2 ey apart, at E and F);
- the hubs of different legs (static: the base layout; :func:`layout_clearance`);
- the platform's nine bodies against every leg link and every hub, except platform crank
  i with body DP of leg i (they meet at the spherical joint P_i);
- the platform's bodies against the base plate (half-space z <= ``base_top``).

Not compared: the other bodies of one leg with each other and with its own hub (joined
at shared joints, or kept apart by the leg's design: the paper's actuated range
[0, 270] deg keeps its links off its base, §V-A); the
legs' links with the base plate (the same rule: (270, 360) deg is where the base is).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from sixplus3.errors import GeometryError
from sixplus3.kinematics import _geometry_kernel
from sixplus3.kinematics.robot import home
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.robot_geometry import NUM_LEGS

if TYPE_CHECKING:
    from sixplus3.kinematics.robot import RobotConfig

#: The links of a leg, in order, with their end points: A-D, D-P, B-G, G-E, C-H, H-F.
LEG_LINKS = ("AD", "DP", "BG", "GE", "CH", "HF")
#: The hubs of a leg, on the actuated axis: the pulley stack at A.
HUBS = ("A",)
_N_LINK = len(LEG_LINKS)
_HUB0 = NUM_LEGS * _N_LINK  # 18
_PLAT0 = _HUB0 + NUM_LEGS * len(HUBS)  # 27
_SPOKE0, _EDGE0, _CRANK0 = _PLAT0, _PLAT0 + NUM_LEGS, _PLAT0 + 2 * NUM_LEGS
#: Names of the 30 bodies, in the order of :func:`capsules`.
BODIES: tuple[str, ...] = (
    tuple(f"leg{i}_{n}" for i in range(NUM_LEGS) for n in LEG_LINKS)
    + tuple(f"leg{i}_hub{h}" for i in range(NUM_LEGS) for h in HUBS)
    + tuple(f"platform_spoke{i}" for i in range(NUM_LEGS))
    + tuple(f"platform_edge{i}{(i + 1) % NUM_LEGS}" for i in range(NUM_LEGS))
    + tuple(f"platform_crank{i}" for i in range(NUM_LEGS)))
N_BODIES = len(BODIES)


def _pairs() -> tuple[np.ndarray, np.ndarray]:
    links = [[_N_LINK * i + k for k in range(_N_LINK)] for i in range(NUM_LEGS)]
    hubs = [[_HUB0 + len(HUBS) * i + k for k in range(len(HUBS))] for i in range(NUM_LEGS)]
    plat = list(range(_PLAT0, N_BODIES))
    pairs: list[tuple[int, int]] = []
    for i in range(NUM_LEGS):
        pairs.append((links[i][3], links[i][5]))  # GE and HF of one leg: ey against them
        for j in range(NUM_LEGS):
            if i < j:
                pairs += [(a, b) for a in links[i] for b in links[j]]
            if i != j:
                pairs += [(a, b) for a in links[i] for b in hubs[j]]
            if i < j:
                pairs += [(a, b) for a in hubs[i] for b in hubs[j]]
    for p in plat:
        for i in range(NUM_LEGS):
            pairs += [(p, a) for a in links[i]
                      if not (p == _CRANK0 + i and a == _N_LINK * i + 1)]
            pairs += [(p, h) for h in hubs[i]]
    return np.array(pairs, dtype=np.int64), np.array(plat, dtype=np.int64)


#: (P, 2) body pairs compared; (9,) bodies kept above the base plate.
PAIRS, BASE_BODIES = _pairs()
#: Which family each pair belongs to (reports name the closest pair and its family).
PAIR_FAMILY = np.array(
    ["platform" if a >= _PLAT0 else ("hubs" if a >= _HUB0 else
                                     ("hub" if b >= _HUB0 else "links"))
     for a, b in PAIRS])


def radii(robot: Robot) -> np.ndarray:
    """(30,) capsule radius of every body [m]."""
    c = robot.collision
    leg = [c.link_radius, c.link_radius, c.crank_radius, c.distal_radius, c.crank_radius,
           c.distal_radius]
    return np.array(leg * NUM_LEGS + [c.hub_radius] * (len(HUBS) * NUM_LEGS)
                    + [c.plate_radius] * (2 * NUM_LEGS) + [c.link_radius] * NUM_LEGS)


def hub_segments(robot: Robot) -> np.ndarray:
    """(3, 2, 3) the hubs' axis segments in the robot frame [m], one per leg, centred on
    A_i along the actuated axis."""
    geom, w = robot.geometry, robot.collision.hub_width
    out = np.zeros((NUM_LEGS * len(HUBS), 2, 3))
    for i in range(NUM_LEGS):
        x = geom.leg_rotation(i)[:, 0]
        a = geom.leg_origin(i)
        out[i] = (a - 0.5 * w * x, a + 0.5 * w * x)
    return out


def platform_segments(robot: Robot, position: np.ndarray, rotation: np.ndarray,
                      P: np.ndarray) -> np.ndarray:
    """(n, 9, 2, 3) spokes O-R_i, edges R_i-R_{i+1} (both ``plate_offset`` along the
    platform normal), cranks R_i-P_i in the robot frame [m], for platform positions
    (n, 3), rotations (n, 3, 3) and crank tips P (n, 3, 3)."""
    geom = robot.geometry
    n = position.shape[0]
    R_i = np.stack([position + np.einsum("nij,j->ni", rotation, geom.crank_axis_position(i))
                    for i in range(NUM_LEGS)], axis=1)
    up = robot.collision.plate_offset * rotation[:, :, 2]  # the plate above the cranks
    out = np.zeros((n, 3 * NUM_LEGS, 2, 3))
    for i in range(NUM_LEGS):
        out[:, i] = np.stack([position + up, R_i[:, i] + up], axis=1)
        out[:, NUM_LEGS + i] = np.stack([R_i[:, i] + up, R_i[:, (i + 1) % NUM_LEGS] + up],
                                        axis=1)
        out[:, 2 * NUM_LEGS + i] = np.stack([R_i[:, i], P[:, i]], axis=1)
    return out


def capsules(cfg: RobotConfig) -> np.ndarray:
    """(n, 30, 2, 3) every body's segment in the robot frame [m] (order of BODIES), of a
    :class:`~sixplus3.kinematics.robot.RobotConfig`."""
    robot = cfg.robot
    geom = robot.geometry
    n = len(cfg)
    out = np.zeros((n, N_BODIES, 2, 3))
    for i in range(NUM_LEGS):
        s = cfg.legs[i]
        a = np.zeros_like(s.d)
        b = np.zeros_like(s.d)
        b[:, 0] = geom.leg.l6
        c = np.zeros_like(s.d)
        c[:, 0] = -geom.leg.l7
        ends = ((a, s.d), (s.d, s.p), (b, s.g), (s.g, s.e), (c, s.h), (s.h, s.f))
        for k, (u, v) in enumerate(ends):
            out[:, _N_LINK * i + k, 0] = geom.from_leg(i, u)
            out[:, _N_LINK * i + k, 1] = geom.from_leg(i, v)
    out[:, _HUB0:_PLAT0] = hub_segments(robot)
    out[:, _PLAT0:] = platform_segments(robot, cfg.position, cfg.rotation, cfg.P)
    return out


def clearance(cfg: RobotConfig, rows: np.ndarray | None = None) -> np.ndarray:
    """(n,) the smallest clearance of the collision model [m]: surface distance between
    the bodies of every pair of :data:`PAIRS` and height of the platform's bodies above
    the base plate; negative where they overlap.  Unsolved rows (and rows outside
    ``rows``, (n,) bool) get -inf."""
    sel = cfg.ok if rows is None else cfg.ok & np.asarray(rows, dtype=bool)
    out = np.full(len(cfg), -np.inf)
    if sel.any():
        caps = np.ascontiguousarray(capsules(cfg.take(sel)))
        out[sel] = _geometry_kernel.batch_clearance(
            caps, radii(cfg.robot), PAIRS, BASE_BODIES, cfg.robot.collision.base_top)
    return out


def closest(cfg: RobotConfig, k: int = 0) -> tuple[str, str, float]:
    """The closest pair of bodies of sample ``k``: (body, body or "base plate",
    clearance [m]) -- what an interference error names."""
    caps = np.ascontiguousarray(capsules(cfg.take(np.arange(len(cfg)) == k)))
    r = radii(cfg.robot)
    d = _geometry_kernel.pair_distances(caps, r, PAIRS)[0]
    low = caps[0][BASE_BODIES][:, :, 2].min(axis=1) - r[BASE_BODIES] - cfg.robot.collision.base_top
    j, b = int(np.argmin(d)), int(np.argmin(low))
    if low[b] < d[j]:
        return BODIES[BASE_BODIES[b]], "base plate", float(low[b])
    return BODIES[PAIRS[j, 0]], BODIES[PAIRS[j, 1]], float(d[j])


def layout_clearance(robot: Robot) -> tuple[float, str, str]:
    """The static part: smallest surface distance between the hubs of different legs
    [m], with the closest pair's names.  Negative: the base layout cannot be built."""
    seg = hub_segments(robot)
    r = robot.collision.hub_radius
    best = (np.inf, "", "")
    for a in range(len(seg)):
        for b in range(a + 1, len(seg)):
            d = _geometry_kernel.segment_distance(seg[a, 0], seg[a, 1], seg[b, 0], seg[b, 1])
            if d - 2 * r < best[0]:
                best = (d - 2 * r, BODIES[_HUB0 + a], BODIES[_HUB0 + b])
    return best


def check_layout(robot: Robot) -> None:
    """Refuse a robot whose bodies overlap at its home pose (a layout that cannot be
    built, e.g. an axis turn that makes the legs collide), naming the pair and the
    overlap: :class:`~sixplus3.errors.GeometryError`.  A home the legs cannot reach is
    refused too (UnreachableError)."""

    h = home(robot)
    c = float(clearance(h)[0])
    if c < 0.0:
        a, b, d = closest(h)
        raise GeometryError(
            "layout", f"axis_turn {np.degrees(robot.geometry.axis_turn):g} deg",
            "a layout whose bodies are clear of each other at home",
            f"at home {list(robot.home_position)} m, {a} and {b} overlap by "
            f"{-d * 1e3:.1f} mm (collision model, docs/robot.md)")


def _segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray,
                      q2: np.ndarray) -> np.ndarray:
    """(n,) distance between segments [p1, q1] and [p2, q2] (batched, (n, 3) each): the
    numpy reference of the compiled kernel ``_geometry_kernel.segment_distance``."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.sum(d1 * d1, axis=1)
    e = np.sum(d2 * d2, axis=1)
    f = np.sum(d2 * r, axis=1)
    c = np.sum(d1 * r, axis=1)
    b = np.sum(d1 * d2, axis=1)
    den = a * e - b * b
    s = np.where(den > 1e-14, np.clip((b * f - c * e) / np.maximum(den, 1e-300), 0, 1), 0.0)
    t = (b * s + f) / np.maximum(e, 1e-300)
    t_c = np.clip(t, 0, 1)
    s = np.where(t < 0, np.clip(-c / np.maximum(a, 1e-300), 0, 1),
                 np.where(t > 1, np.clip((b - c) / np.maximum(a, 1e-300), 0, 1), s))
    diff = (p1 + d1 * s[:, None]) - (p2 + d2 * t_c[:, None])
    return np.linalg.norm(diff, axis=1)
