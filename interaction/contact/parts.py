"""The contact guard's parts that are not its state machine (interaction/contact/guard.py):
the offline slope of the velocity torque, the model torque's variance from an
identification, and where a contact is."""

from __future__ import annotations

import numpy as np

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.dynamics.regressor import regressor_batch

#: [m] the residual's crank torques per newton of its force beyond which a contact is on
#: a leg (a platform force has none; a leg link's, its lever under the cranks: cm).
LEG_LEVER = 0.002


def velocity_slope(dyn: ClosedLoopDynamics, q: np.ndarray, theta_d: np.ndarray
                   ) -> np.ndarray:
    """D_k (n, 9, 9) = d c / d theta_dot at sample k's planned rates: the velocity
    torque c (Coriolis and centripetal) is a quadratic form in the rates, so a
    central difference of it is exact, and c(v_k + d) = c_k + D_k d + c(d) with
    c(d) of second order in the tracking error d (docs/safety.md)."""
    n = len(q)
    D = np.empty((n, 9, 9))
    zero = np.zeros((n, 9))
    assert dyn.robot is not None
    fr = dyn.robot.motors.friction
    for j in range(9):
        e = np.zeros(9)
        e[j] = 1.0
        up, _ = dyn.actuated_inverse_dynamics_batch(q, theta_d + e, zero)
        dn, _ = dyn.actuated_inverse_dynamics_batch(q, theta_d - e, zero)
        D[:, :, j] = 0.5 * ((up - fr(theta_d + e)) - (dn - fr(theta_d - e)))
    return D


def parameter_std2(dyn: ClosedLoopDynamics, q: np.ndarray, theta_dot: np.ndarray,
                   theta_ddot: np.ndarray, parameter_cov: tuple[np.ndarray, np.ndarray]
                   ) -> np.ndarray:
    """(n, 9) the variance of each joint's model torque at the states (q, rates,
    accelerations) from an identification's base parameters' covariance
    (``parameter_cov``: (the base columns, the covariance), its parameters.npz):
    diag(Y_b Sigma Y_b^T), Y_b the base regressor (Pinocchio's, through the closures)."""
    from sixplus3.interaction.observer.wrench import (
        checked_covariance,  # deferred: only with a covariance (the wrench estimator's rule)
    )

    assert dyn.robot is not None
    base, cov = checked_covariance(dyn.robot, parameter_cov)
    out = np.empty((len(q), 9))
    for i in range(0, len(q), 2000):
        sl = slice(i, i + 2000)
        Y, _ = regressor_batch(dyn, q[sl], theta_dot[sl], theta_ddot[sl])
        Wb = base.reduce(Y)
        out[sl] = np.einsum("nja,ab,njb->nj", Wb, cov, Wb)
    return np.maximum(np.nan_to_num(out, nan=0.0), 0.0)


def contact_site(full: np.ndarray, bound: np.ndarray) -> str:
    """Where the contact is: a force on the platform does no work when the cranks
    turn with the platform held, so the residual's crank torques (J^T r)[6:9] stay
    within what the thresholds map to there (|J|^T thr), and small against the
    force (the observer's own error during an impact: below 1 mm of lever here).  A
    force on a leg link turns the cranks with a lever of its link's motion under
    them: beyond both, the contact is on a leg (docs/safety.md)."""
    crank = np.abs(full[6:9])
    lever = float(np.linalg.norm(full[6:9])) / max(float(np.linalg.norm(full[0:3])),
                                                   1e-9)
    return ("a leg" if bool(np.any(crank > bound[6:9])) and lever > LEG_LEVER
            else "the platform")


__all__ = ["LEG_LEVER", "contact_site", "parameter_std2", "velocity_slope"]
