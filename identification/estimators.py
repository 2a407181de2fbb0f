"""Estimators of a robot's dynamic parameters from its data set (docs/identification.md).

An estimator is any object with a ``name`` and a call that takes the weighted problem
of :func:`sixplus3.identification.identify.identify` and returns an :class:`Estimate`:
the base parameters by least squares (with their uncertainty, for the report and the
wrench's confidence) and a full set of parameters that is physically consistent (every
body's pseudo-inertia positive definite, every motor's parameters non-negative), which
:func:`identify` checks again and writes as the identified robot.  :data:`ESTIMATORS`
lists the built-in ones by name; a lab passes its own to ``identify(estimator=...)``.

- ``consistent`` (:class:`ConsistentEstimator`, the default): OLS, WLS per joint and
  Huber IRLS for the base parameters (:func:`~.estimate.least_squares`), refused above
  ``max_condition``; then the physically consistent semidefinite program with a prior
  towards the nominal parameters (:func:`~.estimate.consistent`, cvxpy + Clarabel).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from sixplus3.errors import InputError, check_number
from sixplus3.identification.base import BaseParameters
from sixplus3.identification.estimate import (
    MAX_CONDITION,
    MAX_PRIOR_WEIGHT,
    MIN_PRIOR_WEIGHT,
    PRIOR_WEIGHT,
    Consistent,
    LeastSquares,
    consistent,
    least_squares,
)


@dataclass(frozen=True)
class Problem:
    """The weighted identification problem: the base regressor ``Wb`` (N, r) and the
    measured torques ``tau`` (N,) of the kept rows, each row's ``joint`` (N,), the
    ``base`` parameters' map and the nominal full parameters ``pi0`` (P,)."""

    Wb: np.ndarray
    tau: np.ndarray
    joint: np.ndarray
    base: BaseParameters
    pi0: np.ndarray


@dataclass(frozen=True, eq=False)
class Estimate:
    """What any estimator returns, in terms every method has: ``beta`` (r,) the base
    parameters; ``cov`` (r, r) their covariance [SI^2], or None (no confidence: the
    wrench's parameter term and ``parameters.npz`` are then left out); ``pi`` (P,) the
    full parameters, which :func:`~sixplus3.identification.identify.identify` checks to
    be physically consistent before it writes a robot; ``facts``: what the estimator
    says of itself for the report, by name (numbers or words: the built-in's condition
    number, IRLS iterations, prior weight, distance from the nominal, solver)."""

    beta: np.ndarray
    cov: np.ndarray | None
    pi: np.ndarray
    facts: dict[str, float | int | str] = field(default_factory=dict)

    @property
    def std(self) -> np.ndarray:
        """(r,) the base parameters' standard deviations (NaN without a covariance)."""
        if self.cov is None:
            return np.full(len(self.beta), np.nan)
        return np.sqrt(np.maximum(np.diag(self.cov), 0.0))


@runtime_checkable
class Estimator(Protocol):
    """What :func:`~sixplus3.identification.identify.identify` takes (module doc)."""

    @property
    def name(self) -> str: ...

    def __call__(self, problem: Problem) -> Estimate: ...


@dataclass(frozen=True)
class ConsistentEstimator:
    """The default estimator (module doc): ``prior_weight`` of the prior towards the
    nominal parameters, ``robust`` Huber IRLS, refused above ``max_condition``."""

    prior_weight: float = PRIOR_WEIGHT
    robust: bool = True
    max_condition: float = MAX_CONDITION
    name: str = "consistent"

    def __post_init__(self) -> None:
        check_number("the prior weight", self.prior_weight, MIN_PRIOR_WEIGHT, MAX_PRIOR_WEIGHT)
        check_number("max_condition", self.max_condition, 1.0, 1e12)

    def __call__(self, problem: Problem) -> Estimate:
        ls = least_squares(problem.Wb, problem.tau, problem.joint, self.robust)
        if not ls.condition <= self.max_condition:
            raise InputError(f"the logs excite the base parameters too poorly: condition "
                             f"number {ls.condition:.3g} > {self.max_condition:g} (plan an "
                             "excitation with 'sixplus3 identify excite')",
                             value=ls.condition, valid=f"<= {self.max_condition:g}")
        cons = consistent(problem.Wb, problem.tau, ls.weights, problem.base, problem.pi0,
                          self.prior_weight)
        return built_in_estimate(ls, cons)


def built_in_estimate(ls: LeastSquares, cons: Consistent) -> Estimate:
    """The :class:`Estimate` of a least-squares fit of the base parameters and a
    consistent full set (what :class:`ConsistentEstimator` computes), with their facts."""
    return Estimate(beta=ls.beta, cov=ls.cov, pi=cons.pi, facts={
        "condition": float(ls.condition), "irls_iterations": int(ls.iterations),
        "prior_weight": float(cons.prior_weight), "distance_from_nominal": float(cons.distance),
        "min_pseudo_inertia_eigenvalue": float(cons.min_eigenvalue), "solver": cons.solver})


#: The built-in estimators by name (each with its defaults).
ESTIMATORS: dict[str, type[ConsistentEstimator]] = {"consistent": ConsistentEstimator}

__all__ = ["ESTIMATORS", "ConsistentEstimator", "Estimate", "Estimator", "Problem",
           "built_in_estimate"]
