"""The masses of the robot's moving parts: the rod model of each body kind
(:class:`MassModel`), and per-body inertial parameters that replace it where a lab has
measured or identified them (:class:`BodyInertials`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sixplus3.errors import GeometryError

NUM_LEGS = 3


@dataclass(frozen=True)
class MassModel:
    """Masses [kg] of the moving parts; each body is a uniform rod/plate (see docs).

    Leg (about 0.5 kg of moving parts, paper §V-A): aluminium proximal link AD 0.16 kg,
    the body DEFP (aluminium, with the 3 spherical-joint housings) 0.15 kg, two
    aluminium cranks 0.05 kg each, two carbon-fibre distal tubes 0.03 kg each, three
    U-joint crosses 0.01 kg each: 0.50 kg.  Platform (a Wen et al. style plate with three
    bearings, no motors): 0.30 kg, cranks 0.03 kg each.  ``point_mass`` is the paper's
    design model instead: every link massless and ``point_mass_value`` at each P_i.
    """

    proximal: float = 0.16
    body: float = 0.15
    crank: float = 0.05
    distal: float = 0.03
    ucross: float = 0.01
    platform: float = 0.30
    platform_crank: float = 0.03
    point_mass: bool = False
    point_mass_value: float = 0.5

    def __post_init__(self) -> None:
        for name in ("proximal", "body", "crank", "distal", "ucross", "platform",
                     "platform_crank", "point_mass_value"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v)
                                           and 0.0 <= v <= 100.0):
                raise GeometryError(name, v, "a number in [0, 100] kg")
        if not isinstance(self.point_mass, bool):
            raise GeometryError("point_mass", self.point_mass, "true or false")

    @property
    def leg_total(self) -> float:
        if self.point_mass:
            return self.point_mass_value
        return self.proximal + self.body + 2 * self.crank + 2 * self.distal + 3 * self.ucross

    @property
    def total(self) -> float:
        if self.point_mass:
            return NUM_LEGS * self.point_mass_value
        return NUM_LEGS * self.leg_total + self.platform + NUM_LEGS * self.platform_crank


POINT_MASS = MassModel(point_mass=True)


#: The links a body's inertial parameters may be given for: every moving link of the
#: URDF (leg i's proximal link, U-joint crosses, body, cranks, distal links; the
#: platform and its cranks).
BODY_LINKS: tuple[str, ...] = tuple(
    [f"leg{i}_{n}" for i in range(NUM_LEGS)
     for n in ("proximal", "ucrossD", "body", "crankB", "ucrossG", "distalB", "crankC",
               "ucrossH", "distalC")]
    + ["platform"] + [f"platform_crank{i}_link" for i in range(NUM_LEGS)])


@dataclass(frozen=True)
class BodyInertial:
    """One link's mass [kg], centre of mass [m] in the link frame, and inertia about the
    centre of mass in the link frame's axes (ixx, iyy, izz, ixy, ixz, iyz) [kg m^2]."""

    mass: float
    com: tuple[float, float, float]
    inertia: tuple[float, float, float, float, float, float]

    @property
    def inertia_matrix(self) -> np.ndarray:
        ixx, iyy, izz, ixy, ixz, iyz = self.inertia
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


@dataclass(frozen=True)
class BodyInertials:
    """Per-link inertial parameters that replace the rod model (:class:`MassModel`) for
    the links they name: a lab's weighed and CAD values, or an identified robot's
    (docs/identification.md).  ``bodies``: (link, BodyInertial) pairs, sorted by link."""

    bodies: tuple[tuple[str, BodyInertial], ...] = ()

    def __post_init__(self) -> None:
        items = dict(self.bodies) if not isinstance(self.bodies, dict) else self.bodies
        out = []
        for name in sorted(items):
            out.append((name, _check_body(name, items[name])))
        object.__setattr__(self, "bodies", tuple(out))

    def get(self, link: str) -> BodyInertial | None:
        return dict(self.bodies).get(link)

    def as_dict(self) -> dict[str, Any]:
        return {n: {"mass": b.mass, "com": list(b.com), "inertia": list(b.inertia)}
                for n, b in self.bodies}

    @classmethod
    def from_dict(cls, doc: object) -> BodyInertials:
        if not isinstance(doc, dict):
            raise GeometryError("inertials", type(doc).__name__,
                                "a mapping of link name to {mass, com, inertia}")
        out = {}
        for name, v in doc.items():
            if not isinstance(v, dict) or set(v) - {"mass", "com", "inertia"} or \
                    not {"mass", "com", "inertia"} <= set(v):
                raise GeometryError(f"inertials.{str(name)[:40]}", "?",
                                    "a mapping with mass [kg], com [m] (3) and inertia "
                                    "(ixx, iyy, izz, ixy, ixz, iyz) [kg m^2]")
            out[name] = v
        return cls(bodies=tuple(out.items()))  # type: ignore[arg-type]  # checked in __post_init__


def _check_body(name: object, v: Any) -> BodyInertial:
    if not isinstance(name, str) or name not in BODY_LINKS:
        raise GeometryError("inertials link", str(name)[:40],
                            f"one of the moving links {BODY_LINKS[0]} .. {BODY_LINKS[-1]}")
    if isinstance(v, dict):
        v = BodyInertial(v.get("mass"), v.get("com"), v.get("inertia"))  # type: ignore[arg-type]
    if not isinstance(v, BodyInertial):
        raise GeometryError(f"inertials.{name}", type(v).__name__, "a BodyInertial")
    m = v.mass
    if isinstance(m, bool) or not isinstance(m, (int, float)) or not (
            math.isfinite(m) and 0.0 <= m <= 100.0):
        raise GeometryError(f"inertials.{name}.mass", m, "in [0, 100] kg")
    try:
        com = tuple(float(c) for c in v.com)
        inertia = tuple(float(c) for c in v.inertia)
    except (TypeError, ValueError):
        raise GeometryError(f"inertials.{name}", "?", "com: 3 numbers [m], inertia: 6 "
                            "numbers [kg m^2]") from None
    if len(com) != 3 or len(inertia) != 6 or not all(
            math.isfinite(x) for x in com + inertia):
        raise GeometryError(f"inertials.{name}", "?", "com: 3 finite numbers [m], "
                            "inertia: 6 finite numbers [kg m^2]")
    if max(abs(c) for c in com) > 1.0 or max(abs(c) for c in inertia) > 10.0:
        raise GeometryError(f"inertials.{name}", "?", "com within 1 m, inertia "
                            "components within 10 kg m^2")
    b = BodyInertial(float(m), com, inertia)  # type: ignore[arg-type]
    eig = np.linalg.eigvalsh(b.inertia_matrix)
    tol = 1e-12 + 1e-9 * max(abs(x) for x in inertia)
    if eig[0] < -tol or eig[2] > eig[0] + eig[1] + tol:
        raise GeometryError(f"inertials.{name}.inertia", inertia,
                            "a physical inertia: positive semi-definite, principal "
                            "moments satisfying the triangle inequality")
    return b


__all__ = ["BODY_LINKS", "POINT_MASS", "BodyInertial", "BodyInertials", "MassModel"]
