"""The body regions of ISO/TS 15066:2016 Annex A, as data (docs/safety.md).

Each region: the effective mass m_H of the body region [kg] and its effective spring
constant k [N/m] (Table A.3), the maximum permissible quasi-static contact force F_qs [N]
and the smallest maximum permissible quasi-static pressure of its locations [N/cm^2]
(Table A.2), and the factor a transient contact may reach over the quasi-static force
(2, where a transient contact is permitted).

Sources: ISO/TS 15066:2016, "Robots and robotic devices - Collaborative robots", Annex A,
Tables A.2 and A.3 (as reproduced in the standard's commentary literature); the
biomechanical data behind them: Behrens et al., "A statistical model to determine
biomechanical limits for physically safe interactions with collaborative robots",
Frontiers in Robotics and AI 8:667818 (2022).  Where ISO/TS 15066 does not permit a
transient contact (the skull and forehead, the face: sensitive regions that the
standard asks to keep out of reach) and for the neck (not permitted here, an
assumption of ours on the safe side), the transient factor is 1: the quasi-static limit
holds for a transient contact too.  A lab applies its own risk assessment; these values
are the standard's, not a certification.

The two-body model (ISO/TS 15066 Annex A.3): a transient contact at relative speed v
along the contact normal n transfers E = 1/2 mu v^2, mu = (1/m_R + 1/m_H)^-1 with m_R
the robot's effective mass along n; the region's spring holds it at
F = v sqrt(mu k), so the contact stays below F_max = factor F_qs while
E <= F_max^2 / (2 k).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

from sixplus3.errors import InputError


@dataclass(frozen=True)
class BodyRegion:
    name: str
    mass: float  #: effective mass of the body region m_H [kg] (Table A.3)
    stiffness: float  #: effective spring constant k [N/m] (Table A.3, N/mm x 1000)
    force: float  #: maximum permissible quasi-static force [N] (Table A.2)
    pressure: float  #: the smallest max. permissible quasi-static pressure [N/cm^2]
    transient_factor: float  #: F_transient / F_quasi-static (1: transient not permitted)

    @property
    def transient_force(self) -> float:
        """The largest force a transient contact may reach [N]."""
        return self.transient_factor * self.force

    @property
    def energy(self) -> float:
        """The largest energy a transient contact may transfer [J]: F_max^2 / (2 k)."""
        return self.transient_force ** 2 / (2.0 * self.stiffness)

    def speed_limit(self, robot_mass: float) -> float:
        """The largest relative speed [m/s] of a transient contact with a robot of
        effective mass ``robot_mass`` [kg] along the normal: F_max / sqrt(mu k)."""
        mu = 1.0 / (1.0 / robot_mass + 1.0 / self.mass)
        return float(self.transient_force / (mu * self.stiffness) ** 0.5)


def _r(name: str, mass: float, k_n_per_mm: float, force: float, pressure: float,
       transient: bool) -> BodyRegion:
    return BodyRegion(name, mass, k_n_per_mm * 1000.0, force, pressure,
                      2.0 if transient else 1.0)


#: ISO/TS 15066:2016 Annex A, region by region (module doc).
REGIONS: dict[str, BodyRegion] = {r.name: r for r in (
    _r("skull", 4.4, 150.0, 130.0, 110.0, False),  # skull and forehead
    _r("face", 4.4, 75.0, 65.0, 110.0, False),
    _r("neck", 1.2, 50.0, 150.0, 140.0, False),
    _r("back", 40.0, 35.0, 210.0, 160.0, True),  # back and shoulders
    _r("chest", 40.0, 25.0, 140.0, 120.0, True),
    _r("abdomen", 40.0, 10.0, 110.0, 140.0, True),
    _r("pelvis", 40.0, 25.0, 180.0, 210.0, True),
    _r("upper_arm", 3.0, 30.0, 150.0, 190.0, True),  # upper arms and elbow joints
    _r("lower_arm", 2.0, 40.0, 160.0, 180.0, True),  # lower arms and wrist joints
    _r("hand", 0.6, 75.0, 140.0, 190.0, True),  # hands and fingers
    _r("thigh", 75.0, 50.0, 220.0, 220.0, True),  # thighs and knees
    _r("lower_leg", 75.0, 60.0, 130.0, 210.0, True),
)}


#: The suffix that names a region as clamped: backed by something that cannot move (a
#: wall, a table), so the whole impact goes into its spring (m_H infinite).
CLAMPED = "-clamped"


def clamped(region: BodyRegion) -> BodyRegion:
    """``region`` backed by a wall: the two-body model with an infinite m_H (the robot's
    own effective mass takes the place of the reduced mass)."""
    return replace(region, name=region.name + CLAMPED, mass=math.inf)


def all_names() -> list[str]:
    """Every name a pfl list may hold: each region, free and clamped."""
    return list(REGIONS) + [n + CLAMPED for n in REGIONS]


def regions(names: Iterable[str] | str | None) -> tuple[BodyRegion, ...]:
    """The regions named (a list, or one comma-separated string: ``"hand,chest"``; a
    name ending in ``-clamped`` is that region clamped, :func:`clamped`), in
    :func:`all_names` order, without repeats; an unknown name is an InputError naming
    the valid ones.  ``None`` or empty: no region."""
    if names is None:
        return ()
    if isinstance(names, str):
        items = [n.strip() for n in names.split(",") if n.strip()]
    elif isinstance(names, (list, tuple)):
        items = list(names)
    else:
        raise InputError(f"pfl must be a list of body region names, got {names!r}",
                         value=names, valid=", ".join(REGIONS))
    valid = all_names()
    for n in items:
        if not isinstance(n, str) or n not in valid:
            raise InputError(f"unknown body region {n!r} in pfl", value=n,
                             valid=", ".join(REGIONS) + f" (each also with {CLAMPED})")
    out = []
    for name in valid:
        if name in items:
            base = REGIONS[name.removesuffix(CLAMPED)]
            out.append(clamped(base) if name.endswith(CLAMPED) else base)
    return tuple(out)


def names_of(rs: Iterable[BodyRegion]) -> list[str]:
    return [r.name for r in rs]


__all__ = ["CLAMPED", "REGIONS", "BodyRegion", "all_names", "clamped", "names_of",
           "regions"]
