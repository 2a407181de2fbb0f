"""From drive logs to an identified robot (docs/identification.md).

:func:`dataset` filters each log (:mod:`.signals`), computes the closed-loop regressor
of its states (:mod:`sixplus3.dynamics.regressor`) and keeps, per joint, the rows where
that joint moves faster than ``v_min`` (near zero speed a joint's dry friction holds
any torque within its band: those rows say nothing about the model, the classic
exclusion of identification practice).  :func:`identify` then estimates the base
parameters (OLS, WLS, IRLS) and a physically consistent full set
(:mod:`.estimate`), and returns the robot that realises it
(:func:`.plants.robot_with_parameters`); the estimator is a parameter
(:mod:`.estimators`).  :func:`check` measures a robot's torque
prediction on a log.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sixplus3.control.file.drive_log import DriveLog
from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.regressor import N_BODY, N_MOTOR, parameters
from sixplus3.errors import InputError
from sixplus3.identification.base import BaseParameters, base_parameters, stacked_regressor
from sixplus3.identification.estimate import (
    MAX_CONDITION,
    PRIOR_WEIGHT,
    check_consistent,
    pseudo_inertia,
)
from sixplus3.identification.estimators import (
    ConsistentEstimator,
    Estimate,
    Estimator,
    Problem,
)
from sixplus3.identification.plants import robot_with_parameters
from sixplus3.identification.signals import Filtered, filter_log
from sixplus3.robot_description.robot import Robot, require_robot
from sixplus3.robot_description.urdf import actuated_joint_names

#: Rows of a joint slower than this are left out [rad/s] (module doc).
V_MIN = 0.1


@dataclass
class Dataset:
    """Stacked rows over the logs: the base regressor Wb (N, r), the torques (N,), the
    joint of each row, and the filtered logs."""

    Wb: np.ndarray
    tau: np.ndarray
    joint: np.ndarray
    filtered: list[Filtered]
    names: list[str]

    @property
    def rows(self) -> int:
        return len(self.tau)


#: Samples whose regressor is computed at once (the full regressor of a chunk, 337
#: columns, is reduced to the base columns before the next: memory stays flat).
CHUNK = 2000


def dataset(logs: list[DriveLog], robot: Robot, base: BaseParameters,
            cutoff: float | None = None, v_min: float = V_MIN) -> Dataset:
    """The rows of ``logs`` for ``robot`` in ``base``'s columns (module doc)."""
    dyn = ClosedLoopDynamics(robot)
    Ws, taus, joints, fs = [], [], [], []
    wc = robot.motors.coulomb_velocity
    nb = dyn.model.njoints - 1
    idx = np.arange(9)
    for log in logs:
        f = filter_log(log, cutoff, coulomb_velocity=wc)
        assert f.coulomb is not None
        for i in range(0, len(f.t), CHUNK):
            sl = slice(i, i + CHUNK)
            Y = stacked_regressor(dyn, f.theta[sl], f.theta_dot[sl], f.theta_ddot[sl])
            Y[:, idx, N_BODY * nb + N_MOTOR * idx + 2] = f.coulomb[sl]  # the filtered switch
            keep = np.abs(f.theta_dot[sl]) > v_min  # (n, 9)
            Ws.append(base.reduce(Y[keep]))
            taus.append(f.tau[sl][keep])
            joints.append(np.nonzero(keep)[1])
        fs.append(f)
    return Dataset(Wb=np.vstack(Ws), tau=np.concatenate(taus),
                   joint=np.concatenate(joints), filtered=fs, names=[lg.name for lg in logs])


@dataclass
class Identification:
    robot: Robot  # the identified robot (physically consistent)
    base: BaseParameters
    estimate: Estimate  # the estimator's (identification/estimators.py)
    estimator: str  # its name
    #: the smallest eigenvalue of the written robot's bodies' pseudo-inertias, computed
    #: here from the robot written, whatever the estimator said
    min_eigenvalue: float
    beta_nominal: np.ndarray
    beta_consistent: np.ndarray
    rows: int
    cutoffs: list[float]
    residual_rms: np.ndarray  # (9,) of the consistent set on the data [N m]
    nominal_rms: np.ndarray  # (9,) of the nominal robot on the data [N m]
    seconds: float
    notes: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        return {
            "base_parameters": self.base.rank, "parameters": self.base.layout.size,
            "rows": self.rows, "estimator": self.estimator,
            "condition": self.estimate.facts.get("condition"), "cutoff_hz": self.cutoffs,
            "irls_iterations": self.estimate.facts.get("irls_iterations"),
            "residual_rms_n_m": self.residual_rms.tolist(),
            "nominal_rms_n_m": self.nominal_rms.tolist(),
            "prior_weight": self.estimate.facts.get("prior_weight"),
            "distance_from_nominal": self.estimate.facts.get("distance_from_nominal"),
            "min_pseudo_inertia_eigenvalue": self.min_eigenvalue,
            "solver": self.estimate.facts.get("solver"), "seconds": self.seconds,
            "robot_hash": self.robot.hash, "notes": self.notes,
            "not_measured": not_measured(self.residual_rms),
        }

    @property
    def condition(self) -> float:
        """The estimator's condition number (NaN when it does not say)."""
        c = self.estimate.facts.get("condition")
        return float(c) if isinstance(c, (int, float)) else math.nan

    def table(self) -> list[dict[str, Any]]:
        """One row per base parameter: its combination, nominal, WLS estimate with its
        standard deviation, and the consistent set's value."""
        out = []
        beta, std = self.estimate.beta, self.estimate.std
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = 100.0 * std / np.abs(beta)
        for k in range(self.base.rank):
            out.append({"k": k, "combination": self.base.combination(k),
                        "nominal": float(self.beta_nominal[k]),
                        "wls": float(beta[k]), "std": float(std[k]),
                        "relative_std_pct": float(rel[k]),
                        "consistent": float(self.beta_consistent[k])})
        return out


def not_measured(values: Any, v_min: float = V_MIN) -> dict[str, str]:
    """Why a per-joint figure is missing (NaN, ``null`` in JSON), by joint name."""
    return {name: f"never moved faster than {v_min:g} rad/s: no rows (dry friction is not "
                  "fitted at rest)"
            for name, v in zip(actuated_joint_names(), values, strict=True)
            if not math.isfinite(float(v))}


def per_joint_rms(err: np.ndarray, joint: np.ndarray, n: int = 9) -> np.ndarray:
    return np.array([math.sqrt(float(np.mean(err[joint == j] ** 2)))
                     if np.any(joint == j) else math.nan for j in range(n)])


def identify(logs: list[DriveLog], robot: Robot, cutoff: float | None = None,
             prior_weight: float = PRIOR_WEIGHT, robust: bool = True,
             max_condition: float = MAX_CONDITION, name: str | None = None,
             estimator: Estimator | None = None) -> Identification:
    """Identify ``robot``'s dynamics from ``logs`` (module doc) with ``estimator``
    (:mod:`.estimators`; default: :class:`~.estimators.ConsistentEstimator` with
    ``prior_weight``, ``robust`` and ``max_condition``, which refuses a poorly excited
    data set: a condition number of the weighted base regressor above
    ``max_condition``, naming both).  Whatever the estimator, its full parameters are
    checked to be physically consistent before a robot is made of them."""
    robot = require_robot(robot)
    est_of: Estimator
    if estimator is None:
        est_of = ConsistentEstimator(prior_weight, robust, max_condition)
    elif isinstance(estimator, Estimator):
        est_of = estimator
    else:
        raise InputError("estimator must be an Estimator (a name and a call; "
                         "sixplus3.identification.estimators)",
                         value=type(estimator).__name__, valid="an Estimator")
    if not logs:
        raise InputError("no log given", value=0, valid="at least one log")
    t0 = time.perf_counter()
    base = base_parameters(robot)
    ds = dataset(logs, robot, base, cutoff)
    Wb = ds.Wb
    if ds.rows <= 2 * base.rank:
        raise InputError(f"{ds.rows} rows of moving joints for {base.rank} base parameters: "
                         "the logs are too short or the joints barely move", value=ds.rows,
                         valid=f"> {2 * base.rank} rows")
    pi0 = parameters(ClosedLoopDynamics(robot))
    est = est_of(Problem(Wb, ds.tau, ds.joint, base, pi0))
    if not isinstance(est, Estimate):
        raise InputError(f"the estimator {getattr(est_of, 'name', '?')!r} returned "
                         f"{type(est).__name__}, not an Estimate", value=type(est).__name__,
                         valid="identification.estimators.Estimate")
    check_consistent(est.pi, base.layout, tol=1e-12)
    new = robot_with_parameters(robot, est.pi, base.layout,
                                name=name or f"{robot.name}-identified")
    # what the written robot realises, as its own model computes it
    pi_new = parameters(ClosedLoopDynamics(new))
    check_consistent(pi_new, base.layout, tol=1e-12)
    nb = len(base.layout.bodies)
    min_ev = min(float(np.linalg.eigvalsh(pseudo_inertia(pi_new[N_BODY * b:N_BODY * (b + 1)]))[0])
                 for b in range(nb))
    beta_c = base.beta(pi_new)
    res = ds.tau - Wb @ beta_c
    res0 = ds.tau - Wb @ base.beta(pi0)
    return Identification(
        robot=new, base=base, estimate=est, estimator=str(est_of.name),
        min_eigenvalue=min_ev,
        beta_nominal=base.beta(pi0),
        beta_consistent=beta_c, rows=ds.rows, cutoffs=[f.cutoff_hz for f in ds.filtered],
        residual_rms=per_joint_rms(res, ds.joint), nominal_rms=per_joint_rms(res0, ds.joint),
        seconds=time.perf_counter() - t0)


@dataclass
class Check:
    rms: np.ndarray  # (9,) per joint [N m]
    peak: np.ndarray  # (9,)
    rms_all: float
    rows: int
    cutoff_hz: float


def check(log: DriveLog, robot: Robot, cutoff: float | None = None,
          v_min: float = V_MIN) -> Check:
    """Per-joint RMS and peak of the measured minus the predicted torque of ``robot`` on
    ``log`` (the same filter and rows as identification)."""
    robot = require_robot(robot)
    base = base_parameters(robot)
    ds = dataset([log], robot, base, cutoff, v_min)
    err = ds.tau - ds.Wb @ base.beta(parameters(ClosedLoopDynamics(robot)))
    peak = np.array([float(np.abs(err[ds.joint == j]).max()) if np.any(ds.joint == j)
                     else math.nan for j in range(9)])
    return Check(rms=per_joint_rms(err, ds.joint), peak=peak,
                 rms_all=math.sqrt(float(np.mean(err ** 2))), rows=ds.rows,
                 cutoff_hz=ds.filtered[0].cutoff_hz)


__all__ = ["V_MIN", "Check", "Dataset", "Identification", "check", "dataset", "identify"]
