"""The gate's verdict: one :class:`Finding` per failed check (named fields: where it
first failed, where it failed worst) and the :class:`ValidationReport` of a motion.

Data only: :mod:`sixplus3.control.gate.findings` makes the findings, and
:mod:`sixplus3.control.gate.validation` the reports."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Finding:
    """One failed check: where it first failed and where it failed worst."""

    check: str  # e.g. "torque", "velocity consistency"
    kind: str  # "limit" (exit 1) or "defect" (exit 2)
    unit: str
    bound: float  # the limit or tolerance
    count: int  # samples (or intervals) that fail
    first_t: float
    first_where: str  # joint or part
    first_value: float
    worst_t: float
    worst_where: str
    worst_value: float
    excess: float = 0.0  # how far past the bound the worst is (in the check's own terms)

    def message(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        return (f"{self.check}: first at t = {self.first_t:.4f} s on {self.first_where}: "
                f"{self.first_value:.6g}{u} (bound {self.bound:.6g}{u}); worst at t = "
                f"{self.worst_t:.4f} s on {self.worst_where}: {self.worst_value:.6g}{u}; "
                f"{self.count} failing")


@dataclass(frozen=True)
class ValidationReport:
    ok: bool
    samples: int
    robot_hash: str
    max_torque_ratio: float  # max |tau| / limit (samples and midpoints)
    max_velocity_ratio: float
    max_acceleration_ratio: float
    max_jerk_ratio: float
    min_margin_leg_type1: float
    min_margin_leg_type2: float
    min_margin_platform: float
    min_clearance: float  # [m]
    max_spherical_tilt_deg: float
    theta_range_ok: bool
    findings: list[Finding] = field(default_factory=list)
    tolerances: dict[str, Any] = field(default_factory=dict[str, Any])
    checked_points: int = 0  # samples + midpoints evaluated with the full dynamics
    tau: np.ndarray | None = None  # (M, 9) [N m] on the samples
    position: np.ndarray | None = None  # (M, 3) platform [m]
    quaternion: np.ndarray | None = None  # (M, 4) x, y, z, w
    psi: np.ndarray | None = None  # (M, 3) [rad]
    feedforward_error: float | None = None  # max |tau_file - tau| [N m]
    #: max |tau(k+1) - tau(k)| / dt over the samples [N m/s]: reported, not a gate check
    #: (the planner bounds it between its own points, docs/validation.md)
    max_torque_rate: float | None = None
    duration: float | None = None  # [s]
    #: max |jerk| of the interpolant over the intervals / (C_JERK x the jerk limit): above
    #: 1 no motion within the jerk limit has these samples (control/gate/interval.py)
    max_interpolant_jerk_ratio: float = 0.0
    header: dict[str, Any] | None = field(default=None, repr=False)  # validate_file only
    #: the samples validated, exactly as read (validate_file): send these
    data: np.ndarray | None = field(default=None, repr=False)
    rate_hz: float | None = None  # the rate the samples were judged at [Hz]
    #: the judged motion's fingerprint (:attr:`sixplus3.motion.Motion.fingerprint`)
    fingerprint: str | None = field(default=None, repr=False)
    limits: dict[str, Any] | None = None  # the limits judged by (the robot's, or tighter)
    max_tcp_speed: float = 0.0  # [m/s] the tool centre point (samples and midpoints)
    max_tcp_acceleration: float = 0.0  # [m/s^2] (samples: finite difference)
    #: the body regions judged for power and force limiting (ISO/TS 15066), and the
    #: largest contact energy over them against its limit (<= 1 holds; docs/safety.md)
    pfl: tuple[str, ...] = ()
    max_pfl_ratio: float | None = None
    #: the leg links judged with them (``leg{i}_{link}``, dynamics/leg_points.py), and
    #: the point where the largest ratio is (``tcp``, ``centre``, ``leg0_G``, ...)
    pfl_links: tuple[str, ...] = ()
    max_pfl_where: str | None = None
    #: (n,) [1/s] the stop table the file carries, checked by the gate
    #: (control/gate/stop.py); None: the file carries none
    stop_deceleration: np.ndarray | None = field(default=None, repr=False)

    @property
    def defects(self) -> list[Finding]:
        return [f for f in self.findings if f.kind == "defect"]

    @property
    def violations(self) -> list[str]:
        """Messages of every finding (defects first)."""
        return self.messages()

    def messages(self) -> list[str]:
        order = sorted(self.findings, key=lambda f: f.kind != "defect")
        return [f.message() for f in order]

    @property
    def exit_code(self) -> int:
        """0 valid; 2 the file is not a consistent motion of this robot; 1 a limit."""
        if self.defects:
            return 2
        return 1 if self.findings else 0

    def summary(self) -> dict[str, Any]:
        keys = ("ok", "samples", "robot_hash", "max_torque_ratio", "max_velocity_ratio",
                "max_acceleration_ratio", "max_jerk_ratio", "min_margin_leg_type1",
                "min_margin_leg_type2", "min_margin_platform", "min_clearance",
                "max_spherical_tilt_deg", "theta_range_ok", "checked_points", "tolerances",
                "max_torque_rate", "max_interpolant_jerk_ratio", "rate_hz", "limits",
                "max_tcp_speed", "max_tcp_acceleration", "pfl", "max_pfl_ratio",
                "pfl_links", "max_pfl_where")
        out = {k: getattr(self, k) for k in keys}
        out["exit_code"] = self.exit_code
        out["findings"] = self.messages()
        return out


__all__ = ["Finding", "ValidationReport"]
