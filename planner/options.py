"""The planner's options (:class:`PlannerOptions`) and the constants of its transcription."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from sixplus3.errors import InputError

#: the node intervals next to a rest, from the rest outward, as shares of a regular one;
#: together they replace one regular interval (Problem.interval_fractions)
REST_GRADING: tuple[float, ...] = (0.15, 0.5)
#: the scale [(m or rad)/s^2] of the NLP's acceleration variables (u, theta_ddot)
ACC_SCALE = 100.0
#: the NLP's torque-balance rows [N, N m] and theta_ddot ties [rad/s^2] are divided by
#: these (the nominal joint torque and the acceleration variables' scale)
ROW_SCALE = {"torque": 10.0, "acceleration": ACC_SCALE}


@dataclass(frozen=True)
class PlannerOptions:
    lock_redundancy: bool = False  # psi fixed at 90 deg (or the waypoints' psi) throughout
    torque_safety: float = 0.98  # initial node bound = safety * limit (then tightened only
    #                              where the dense re-check finds an overshoot between nodes)
    max_iter: int = 600  # the held-out set was measured at 250 (BENCHMARKS.md); the fixed-
    #                      duration effort solve needs more (tests/test_motion.py)
    start_max_iter: int = 250  # the cap of an NLP start that a fallback follows
    tol: float = 1e-4  # IPOPT's tol (acceptable: 10x for 5 iterations); 4-35% fewer
    #                    iterations than 1e-6, the same durations to 4 digits (BENCHMARKS.md)
    # IPOPT's constr_viol_tol, also for an acceptable stop (IPOPT's default there is
    # 1e-2): the largest residual of a row left in a returned solution: [rad] or [m] in
    # the integration rows, [10 N m] in the dynamics rows (ROW_SCALE).  The written
    # torques are Pinocchio's, not these variables (control/gate/validation.py)
    constr_viol_tol: float = 1e-4
    regularisation: float = 1e-4
    verbose: bool = False
    #: the share of each body region's energy limit the power and force limiting rows
    #: plan to (docs/safety.md): 0.95^2, the speed 5 % below the limit; the pipeline
    #: lowers it when the gate finds the smoothed file beyond the limit
    pfl_share: float = 0.9025
    #: extra IPOPT options as (name, value) pairs, applied over the planner's own (expert
    #: use: the planner's settings are the fastest measured, BENCHMARKS.md; e.g.
    #: ``(("print_timing_statistics", "yes"), ("print_level", 5))`` shows where a solve's
    #: time goes).  A name or value IPOPT rejects raises InputError when the NLP is built.
    ipopt_options: tuple[tuple[str, Any], ...] | dict[str, Any] = ()

    def __post_init__(self) -> None:
        if not (isinstance(self.pfl_share, (int, float)) and 0.01 <= self.pfl_share <= 1.0):
            raise InputError(f"pfl_share must be in [0.01, 1], got {self.pfl_share!r}",
                             value=self.pfl_share, valid="[0.01, 1]")
        try:
            pairs = (tuple(self.ipopt_options.items()) if isinstance(self.ipopt_options, dict)
                     else tuple(tuple(p) for p in self.ipopt_options))
        except TypeError:
            raise InputError(f"ipopt_options: {self.ipopt_options!r}; valid: (name, value) "
                             "pairs or a dict", value=self.ipopt_options,
                             valid="(name, value) pairs or a dict") from None
        for pair in pairs:
            if len(pair) != 2 or not isinstance(pair[0], str):
                raise InputError(f"ipopt_options: {pair!r} is not a (name, value) pair",
                                 value=pair, valid="a (name, value) pair")
            name, value = pair
            number = isinstance(value, (int, float)) and not isinstance(value, bool)
            if not (isinstance(value, str) or (number and math.isfinite(value))):
                raise InputError(f"ipopt_options: {name} = {value!r}; valid: a finite "
                                 "number or a string", value=value,
                                 valid="a finite number or a string")
        object.__setattr__(self, "ipopt_options", pairs)


__all__ = ["ACC_SCALE", "REST_GRADING", "ROW_SCALE", "PlannerOptions"]
