"""Lead-through's data (interaction/lead/leadthrough.py): its settings
(:class:`LeadSettings`, read by name with their ranges), the tables computed once from
them, the robot and the site (:class:`LeadTables`), and the state a tick changes
(:class:`LeadState`, made anew by each ``reset``).  Per-axis values of the tool point
are a (translation, rotation) pair or six numbers."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from sixplus3.control.drive.command import Mode
from sixplus3.errors import InputError, check_number
from sixplus3.interaction.observer.wrench import GAIN, MODEL_SIGMA, N_SIGMA
from sixplus3.robot_description.limits import Limits

#: The walls near at once, at most (the four slacks' and a cliff ahead).
MAX_WALLS = 8


def six(name: str, value: object, lo: float, hi: float) -> np.ndarray:
    """Six values (translation x3, rotation x3) from a (translation, rotation) pair or
    six numbers, each within [lo, hi]."""
    vals = list(value) if isinstance(value, (list, tuple, np.ndarray)) else [value]
    if len(vals) == 2:
        vals = [vals[0]] * 3 + [vals[1]] * 3
    if len(vals) != 6:
        raise InputError(f"{name} must be (translation, rotation) or 6 numbers",
                         value=repr(value)[:80], valid="2 or 6 numbers")
    return np.array([check_number(name, v, lo, hi) for v in vals])


def pair(name: str, value: object, lo: float, hi: float) -> tuple[float, float]:
    """A (translation, rotation) pair of numbers, each within [lo, hi]."""
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 2:
        raise InputError(f"{name} must be a (translation, rotation) pair of numbers, got "
                         f"{repr(value)[:80]}", value=repr(value)[:80],
                         valid=f"2 numbers in [{lo:g}, {hi:g}]")
    return (check_number(name, value[0], lo, hi), check_number(name, value[1], lo, hi))


@dataclass(frozen=True, eq=False)
class LeadSettings:
    """Lead-through's settings (docs/leadthrough.md), checked when made: ``mass`` [kg,
    kg m^2] and ``damping`` [N s/m, N m s/rad] per axis of the tool point (a pair or
    six); ``speed`` [m/s, rad/s] and ``acceleration`` [m/s^2, rad/s^2], caps of the tool
    point's twist; ``crank_gain`` [rad/s per unit gradient] and ``crank_rate`` [rad/s],
    the cranks' climb; ``n_sigma``, the deadband; ``start_time`` and ``rest_time`` [s],
    the hysteresis; ``slow_every`` [ticks], the walls' update; ``energy`` [J], the
    tank's; the observer's ``gain`` [1/s], ``model_sigma`` and ``monitor_noise``
    [N m]; ``compiled``: its state from the compiled CasADi model."""

    mass: Any = (4.0, 0.08)
    damping: Any = (20.0, 0.4)
    speed: Any = (0.25, 1.0)
    acceleration: Any = (2.0, 10.0)
    crank_gain: float = 2.0
    crank_rate: float = 0.5
    n_sigma: float = N_SIGMA
    start_time: float = 0.005
    rest_time: float = 0.1
    slow_every: int = 10
    energy: float = 0.5
    gain: float = GAIN
    model_sigma: float = MODEL_SIGMA
    monitor_noise: float = 0.005
    compiled: bool = True

    def __post_init__(self) -> None:
        checked: dict[str, object] = {
            "mass": six("mass", self.mass, 1e-3, 1e3),
            "damping": six("damping", self.damping, 0.0, 1e4),
            "speed": pair("speed [m/s, rad/s]", self.speed, 1e-3, 10.0),
            "acceleration": pair("acceleration [m/s^2, rad/s^2]", self.acceleration,
                                 1e-2, 1e3),
            "crank_gain": check_number("crank_gain", self.crank_gain, 0.0, 100.0),
            "crank_rate": check_number("crank_rate", self.crank_rate, 0.0, 10.0),
            "n_sigma": check_number("n_sigma", self.n_sigma, 0.0, 100.0),
            "start_time": check_number("start_time", self.start_time, 0.0, 1.0),
            "rest_time": check_number("rest_time", self.rest_time, 0.0, 10.0),
            "slow_every": int(check_number("slow_every", self.slow_every, 1, 1000,
                                           integer=True)),
            "energy": check_number("energy", self.energy, 0.0, 100.0),
            "compiled": bool(self.compiled)}
        for name, value in checked.items():
            object.__setattr__(self, name, value)

    @classmethod
    def named(cls, base: LeadSettings | None, overrides: dict[str, object]) -> LeadSettings:
        """``base`` (default: the defaults) with the settings named in ``overrides``; a
        name that is not a setting is refused, naming the valid ones."""
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(overrides) - set(names))
        if unknown:
            raise InputError(f"not a lead-through setting: {', '.join(unknown)}",
                             value=unknown[0], valid=", ".join(names))
        got = {f: getattr(base, f) for f in names} if base is not None else {}
        return cls(**{**got, **overrides})


@dataclass(frozen=True, eq=False)
class LeadTables:
    """What lead-through computes once, from its settings, the robot and the site:
    the tick, the hysteresis in ticks, the envelope ``lim`` (the robot's limits
    tightened by the site's) and its torque ``cap``, the guided joint rates' cap, the
    tool point, the motors' friction law (viscous, coulomb, its speed), the twist's caps,
    the drive's (Kp, Kd) or None, and a fault's placeholder reference (the home pose's
    angles, never a target)."""

    rate: float
    dt: float
    start_ticks: int
    rest_ticks: int
    lim: Limits
    cap: float
    rate_cap: float
    tool: np.ndarray
    viscous: np.ndarray
    coulomb: np.ndarray
    cspeed: float
    accel_cap: np.ndarray
    speed_cap: np.ndarray
    gains: tuple[np.ndarray, np.ndarray] | None
    home: np.ndarray


@dataclass(eq=False)
class LeadState:
    """Lead-through's state while it runs (interaction/lead/leadthrough.py): made anew by
    each ``reset``.  ``sc``: the tank's scalars (interaction/lead/_lead_kernel.py: E0, PORT,
    TANK, MIN_TANK) [J]; the walls near are kept as the kernels' arrays (G, b, n_walls)
    behind :attr:`walls`; ``lu``, ``piv`` and ``no_anchor`` the kernels' work."""

    sc: np.ndarray
    mode: Mode = Mode.HOLD
    events: list[str] = field(default_factory=list)
    started: bool = False
    tick: int = 0
    above: int = 0  #: ticks the input has stayed beyond the rest threshold
    still: int = 0  #: ticks with no input and the platform still
    #: the tool point's twist (v, omega) [m/s, rad/s] and the crank rates [rad/s]
    v: np.ndarray = field(default_factory=lambda: np.zeros(6))
    psi_dot: np.ndarray = field(default_factory=lambda: np.zeros(3))
    psi_dot_target: np.ndarray = field(default_factory=lambda: np.zeros(3))
    theta_dot_ref: np.ndarray = field(default_factory=lambda: np.zeros(9))
    last_ff: np.ndarray = field(default_factory=lambda: np.zeros(9))
    prev_theta: np.ndarray = field(default_factory=lambda: np.zeros(9))
    vel: np.ndarray = field(default_factory=lambda: np.zeros(9))  #: the encoder's rate
    have_prev: bool = False
    anchor_theta: np.ndarray | None = None  #: this tick's slow update's angles
    last_good: np.ndarray | None = None  #: the last reading accepted
    since_good: int = 0  #: ticks since it
    resync: bool = False  #: the observer restarts at the next good reading
    cand: np.ndarray | None = None  #: readings that do not follow, agreeing ...
    cand_n: int = 0  #: ... this many in a row
    reading: np.ndarray | None = None  #: this tick's reading, until its rate is taken
    #: the reference: the platform's pose, the cranks, the joint angles
    p_ref: np.ndarray = field(default_factory=lambda: np.zeros(3))
    R_ref: np.ndarray = field(default_factory=lambda: np.eye(3))
    psi_ref: np.ndarray = field(default_factory=lambda: np.zeros(3))
    theta_ref: np.ndarray = field(default_factory=lambda: np.zeros(9))
    G: np.ndarray = field(default_factory=lambda: np.zeros((MAX_WALLS, 9)))
    b: np.ndarray = field(default_factory=lambda: np.zeros(MAX_WALLS))
    n_walls: int = 0
    wall_list: list[tuple[np.ndarray, float]] = field(default_factory=list)
    lu: np.ndarray = field(default_factory=lambda: np.zeros((9, 9)))
    piv: np.ndarray = field(default_factory=lambda: np.zeros(9, dtype=np.int64))
    no_anchor: np.ndarray = field(default_factory=lambda: np.zeros(9))

    @property
    def walls(self) -> list[tuple[np.ndarray, float]]:
        """The walls near: (gradient (9,) in the walls' metric, bound) each."""
        return list(self.wall_list)

    @walls.setter
    def walls(self, found: list[tuple[np.ndarray, float]]) -> None:
        self.wall_list = list(found)[:MAX_WALLS]
        for k, (g, b) in enumerate(self.wall_list):
            self.G[k] = g
            self.b[k] = b
        self.n_walls = len(self.wall_list)


__all__ = ["MAX_WALLS", "LeadSettings", "LeadState", "LeadTables", "pair", "six"]
