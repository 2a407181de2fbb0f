"""Limits of the robot: the hardware's, and the tightened ones a task may ask for.

The robot's hardware limits (:attr:`sixplus3.robot_description.Robot.limits`) are the
authority.  A task or a trajectory file may only *tighten* them
(:meth:`Limits.tightened`): a looser, non-finite or non-positive value is refused with a
:class:`~sixplus3.errors.LimitError` naming the limit and its valid range.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from sixplus3.errors import LimitError

#: Rated speed of the motors [rpm] (Yaskawa SGMCS-05B).
RATED_SPEED_RPM = 300.0
#: Joint speed limit [rad/s]: the rated motor speed through the 72/34 belt.
VELOCITY_LIMIT = RATED_SPEED_RPM * 2.0 * math.pi / 60.0 * 34.0 / 72.0


#: The default platform-space limits: none (values no motion of this robot reaches).
TCP_SPEED_NONE = 10.0
TCP_ACCELERATION_NONE = 1000.0

#: The smallest fraction of a hardware limit a tightened limit may be.
MIN_FRACTION = 1e-3


def _lim(default: float, doc: str, unit: str) -> Any:
    return field(default=default, metadata={"doc": doc, "unit": unit})


@dataclass(frozen=True)
class Limits:
    """Every limit a motion of the robot must respect (SI units)."""

    torque: float = _lim(10.0, "|tau| of every actuated joint (5 N m motors x 72/34 belts, "
                         "limited to 10)", "N m")
    velocity: float = _lim(VELOCITY_LIMIT, "|theta_dot| of every actuated joint", "rad/s")
    acceleration: float = _lim(200.0, "|theta_ddot| of every actuated joint (a comfort "
                               "limit for pHRI; no datasheet value)", "rad/s^2")
    jerk: float = _lim(2.0e5, "|d theta_ddot / dt| of every actuated joint: the bound the "
                       "smoothing enforces and the validator derives its consistency "
                       "tolerances from (about 2x the largest jerk of the planned example "
                       "tasks; the drives' torque rise allows far more)", "rad/s^3")
    torque_rate: float = _lim(2000.0, "|d tau / dt| of every actuated joint, bounded "
                              "inside the planner (a smoothness choice: a full 10 N m "
                              "swing takes at least 10 ms; no datasheet value; the planned "
                              "examples reached 1.1-2.7 kN m/s without it)", "N m/s")
    margin: float = _lim(0.05, "smallest admissible singularity margin (leg type I/II, "
                         "platform; scale-free, 0 singular .. 1 ideal)", "1")
    theta_min: float = _lim(0.0, "lower end of the actuated range", "rad")
    theta_max: float = _lim(1.5 * math.pi, "upper end of the actuated range: (270, 360) "
                            "deg hits the base plate (paper §V-A)", "rad")
    spherical: float = _lim(math.radians(150.0), "largest tilt of every spherical joint "
                            "from its mounting axis", "rad")
    tcp_speed: float = _lim(TCP_SPEED_NONE, "|v| of the tool centre point: none by default "
                            "(10 m/s binds nothing the motors can do); near people a lab "
                            "sets e.g. 0.25 m/s, the reduced speed of ISO 10218-1", "m/s")
    tcp_acceleration: float = _lim(TCP_ACCELERATION_NONE, "|a| of the tool centre point: "
                                   "none by default (1000 m/s^2); e.g. 19.62 m/s^2, the "
                                   "paper's 2 g", "m/s^2")

    #: limits where a smaller value is tighter (the others: margin larger, theta range
    #: narrower)
    UPPER = ("torque", "velocity", "acceleration", "jerk", "torque_rate", "spherical",
             "tcp_speed", "tcp_acceleration")

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise LimitError(f.name, v, f"a finite number [{f.metadata['unit']}]")
            v = float(v)
            if not math.isfinite(v):
                raise LimitError(f.name, v, f"finite [{f.metadata['unit']}]")
            object.__setattr__(self, f.name, v)
        for name in self.UPPER:
            if getattr(self, name) <= 0.0:
                raise LimitError(name, getattr(self, name), "> 0")
        if self.spherical > math.pi:
            raise LimitError("spherical", self.spherical, "in (0, pi] rad")
        if not 0.0 < self.margin < 1.0:
            raise LimitError("margin", self.margin, "in (0, 1)")
        if not (-math.pi <= self.theta_min < self.theta_max <= 2.0 * math.pi):
            raise LimitError("theta_min/theta_max", (self.theta_min, self.theta_max),
                             "-pi <= theta_min < theta_max <= 2 pi rad")

    def tightened(self, **values: float | None) -> Limits:
        """These limits with some tightened; ``None`` keeps a value.

        Raises :class:`LimitError` for an unknown name, a non-finite or non-positive
        value, or a value looser than this one (the hardware is the authority).
        """
        names = {f.name for f in fields(self)}
        new = {}
        for name, v in values.items():
            if name not in names:
                raise LimitError(name, v, f"one of {sorted(names)}", "unknown limit")
            if v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise LimitError(name, v, f"a finite number [{self.unit(name)}]")
            v = float(v)
            hw = getattr(self, name)
            if name in self.UPPER and not MIN_FRACTION * hw <= v <= hw * (1.0 + 1e-12):
                raise LimitError(name, v, f"in [{MIN_FRACTION * hw:g}, {hw:g}] "
                                 f"{self.unit(name)}", "a limit may only tighten the "
                                 f"hardware's, and not below {MIN_FRACTION:g} of it (no "
                                 "motion within the sample cap)")
            if name in self.UPPER:
                v = min(v, hw)
            if name == "margin" and not hw <= v < 1.0:
                raise LimitError(name, v, f"in [{hw:g}, 1)",
                                 "a task may only tighten the robot's margin")
            if name == "theta_min" and v < hw:
                raise LimitError(name, v, f">= {hw:g} rad", "only a narrower actuated range")
            if name == "theta_max" and v > hw:
                raise LimitError(name, v, f"<= {hw:g} rad", "only a narrower actuated range")
            new[name] = v
        return Limits(**{**asdict(self), **new})

    def without_tcp(self) -> Limits:
        """These limits with the platform-space ones at their defaults (none): the
        joint-space limits of the planner's NLP, which bounds the platform-space ones in
        rows of their own (:mod:`sixplus3.planner.tcp_rows`; docs/planner.md,
        "Platform-space limits")."""
        return self.replace_upper(tcp_speed=TCP_SPEED_NONE,
                                  tcp_acceleration=TCP_ACCELERATION_NONE)

    @property
    def has_tcp(self) -> bool:
        """Whether a platform-space limit is set (tighter than none)."""
        return (self.tcp_speed < TCP_SPEED_NONE
                or self.tcp_acceleration < TCP_ACCELERATION_NONE)

    def replace_upper(self, **values: float) -> Limits:
        """These limits with some upper limits replaced (no tightening check: for the
        hardware envelope, :func:`sixplus3.robot_description.robot.hardware_envelope`)."""
        return Limits(**{**asdict(self), **values})

    def within(self, hardware: Limits) -> bool:
        """Whether every limit here is at least as tight as ``hardware``'s."""
        try:
            hardware.tightened(**asdict(self))
        except LimitError:
            return False
        return True

    @staticmethod
    def unit(name: str) -> str:
        for f in fields(Limits):
            if f.name == name:
                return str(f.metadata["unit"])
        return ""

    def as_dict(self) -> dict[str, float]:
        return asdict(self)
