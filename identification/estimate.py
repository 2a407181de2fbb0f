"""Estimators: least squares on the base parameters, and a physically consistent set.

1. **Ordinary least squares** on the base regressor W_b beta = tau (stacked over the
   samples and the nine joints).
2. **Weighted least squares** (Gautier's): each joint's rows weighted by 1 / sigma_j, the
   standard deviation of that joint's OLS residual.  Standard deviations of beta from
   sigma^2 (W^T W)^-1; relative ones in % of |beta|.
3. **Iteratively reweighted** for outliers: Huber weights (k = 1.345) on the WLS
   residuals, until the weights settle (at most :data:`IRLS_ITERATIONS`).
4. **Physically consistent** (Wensing, Kim and Slotine 2017; Sousa and Cortesao 2014):
   the full parameter vector pi minimising the same weighted residual, subject to every
   body's pseudo-inertia J = [[tr(I)/2 1 - I, h], [h^T, m]] being positive
   semi-definite (mass >= 0, inertia physical about the centre of mass, the triangle
   inequality) and every motor's I_a, f_v, f_c >= 0, plus a prior
   w * mean_info * sum(((pi - pi_0) / s)^2) towards the nominal pi_0 (s: each
   parameter's natural scale), which decides the directions the data leave unexcited
   (the null space of the regressor) and changes the excited ones by little.  A
   semidefinite program solved by Clarabel through cvxpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sixplus3.dynamics.regressor import N_BODY, N_MOTOR, Layout
from sixplus3.errors import InputError, check_number
from sixplus3.identification.base import BaseParameters

IRLS_ITERATIONS = 10
HUBER_K = 1.345
#: Default prior weight (relative to the mean information per scaled parameter).
PRIOR_WEIGHT = 1e-7
#: The prior weight's range: at MAX_PRIOR_WEIGHT the prior weighs as much as the data's
#: mean information per parameter (beyond it the log would be ignored and the nominal
#: robot written back, as 1e300 once did, saying nothing); below MIN_PRIOR_WEIGHT it no
#: longer regularises the unexcited directions.
MIN_PRIOR_WEIGHT, MAX_PRIOR_WEIGHT = 1e-12, 1.0
#: The largest condition number of the weighted base regressor an estimate accepts.
MAX_CONDITION = 1e4


@dataclass
class LeastSquares:
    beta: np.ndarray  # (r,) base parameters
    std: np.ndarray  # (r,) their standard deviations
    sigma: np.ndarray  # (9,) per-joint residual standard deviation [N m]
    weights: np.ndarray  # (N,) the final row weights (WLS x Huber)
    condition: float  # of the weighted, column-scaled base regressor
    iterations: int = 0
    cov: np.ndarray | None = None  # (r, r) covariance of beta [SI^2]

    @property
    def relative_std(self) -> np.ndarray:
        """Standard deviations in % of |beta| (inf where beta is 0)."""
        with np.errstate(divide="ignore"):
            return 100.0 * self.std / np.abs(self.beta)


def condition_number(Wb: np.ndarray) -> float:
    """Of the column-scaled matrix (each column to unit norm): the identifiability
    criterion of the excitation and of an estimate (from the eigenvalues of its Gram
    matrix: the squares of its singular values)."""
    s = np.linalg.norm(Wb, axis=0)
    s[s == 0] = 1.0
    A = Wb / s
    ev = np.linalg.eigvalsh(A.T @ A)
    return float(math.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else math.inf


def _solve_gram(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """beta of the normal equations G beta = b, solved column-scaled (each column of the
    weighted system to unit norm: s = sqrt(diag G)); the scaled system's condition
    number is below MAX_CONDITION, so its square is far from double precision's limit."""
    s = np.sqrt(np.maximum(np.diag(G), 0.0))
    s[s == 0] = 1.0
    return np.linalg.solve(G / s[:, None] / s[None, :], b / s) / s


class _Normal:
    """The normal equations of ``Wb`` (N, r) and ``tau`` by joint: G_j = A_j^T A_j and
    b_j = A_j^T tau_j, formed once (the only pass over all N rows).  A weighting that is
    one weight per joint times a factor h_i <= 1 on some rows (Huber's down-weighted
    outliers) is then G = sum_j w_j^2 G_j - sum_{h_i < 1} w_j^2 (1 - h_i) a_i a_i^T: each
    IRLS step touches only its outliers, not the 10^5 rows of a long log."""

    def __init__(self, Wb: np.ndarray, tau: np.ndarray, joint: np.ndarray, n: int) -> None:
        self.Wb, self.tau, self.joint, self.n = Wb, tau, joint, n
        r = Wb.shape[1]
        self.G = np.zeros((n, r, r))
        self.b = np.zeros((n, r))
        for j in range(n):
            rows = joint == j
            if rows.any():
                A = Wb[rows]
                self.G[j] = A.T @ A
                self.b[j] = A.T @ tau[rows]

    def solve(self, wj: np.ndarray, h: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """(beta, the Gram matrix A^T A of the weighted rows) for the row weights
        ``wj[joint] * sqrt(h)`` (h None: all ones)."""
        w2 = np.asarray(wj, dtype=float) ** 2
        G = np.einsum("j,jab->ab", w2, self.G)
        b = w2 @ self.b
        if h is not None:
            out = np.flatnonzero(h < 1.0)
            if len(out):
                c = w2[self.joint[out]] * (1.0 - h[out])
                A = self.Wb[out]
                G = G - (A * c[:, None]).T @ A
                b = b - A.T @ (c * self.tau[out])
        return _solve_gram(G, b), G


def least_squares(Wb: np.ndarray, tau: np.ndarray, joint: np.ndarray | None = None,
                  robust: bool = True, n_joints: int = 9) -> LeastSquares:
    """OLS, then WLS per joint, then (``robust``) Huber IRLS; ``Wb`` (N, r), ``tau``
    (N,), ``joint`` (N,) each row's joint (default: rows sample by sample, joint by
    joint)."""
    N, r = Wb.shape
    if N <= r:
        raise InputError(f"{N} equations for {r} base parameters: the log is too short",
                         value=N, valid=f"> {r} rows")
    joint = np.arange(N) % n_joints if joint is None else np.asarray(joint)
    ne = _Normal(Wb, tau, joint, n_joints)
    beta, _ = ne.solve(np.ones(n_joints))
    res = tau - Wb @ beta
    sigma = _rms_by_joint(res, joint, n_joints)
    sigma = np.where(np.isfinite(sigma), sigma, 1.0)
    sigma = np.maximum(sigma, 1e-6 * max(float(sigma.max()), 1e-12))
    wj = 1.0 / sigma
    w_joint = wj[joint]
    h: np.ndarray | None = None
    it = 0
    if robust:
        while it < IRLS_ITERATIONS:
            it += 1
            beta, _ = ne.solve(wj, h)
            u = (tau - Wb @ beta) * w_joint
            s = 1.4826 * float(np.median(np.abs(u - np.median(u)))) or 1.0
            hub = np.minimum(1.0, HUBER_K * s / np.maximum(np.abs(u), 1e-300))
            old = np.ones_like(hub) if h is None else h
            h = hub
            if np.max(w_joint * np.abs(np.sqrt(hub) - np.sqrt(old))) <= \
                    1e-6 * np.max(w_joint * np.sqrt(old)):
                break
    beta, gram = ne.solve(wj, h)
    w = w_joint if h is None else w_joint * np.sqrt(h)
    res_w = (tau - Wb @ beta) * w
    dof = max(N - r, 1)
    s2 = float(res_w @ res_w) / dof
    cov: np.ndarray | None
    try:
        cov = s2 * np.linalg.inv(gram)
        std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        cov, std = None, np.full(r, np.inf)
    res = tau - Wb @ beta
    sigma = _rms_by_joint(res, joint, n_joints)
    d = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    ev = np.linalg.eigvalsh(gram / d[:, None] / d[None, :])
    cond = float(math.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else math.inf
    return LeastSquares(beta=beta, std=std, sigma=sigma, weights=w, condition=cond,
                        iterations=it, cov=cov)


def _rms_by_joint(res: np.ndarray, joint: np.ndarray, n: int) -> np.ndarray:
    return np.array([math.sqrt(float(np.mean(res[joint == j] ** 2))) if np.any(joint == j)
                     else math.nan for j in range(n)])


def parameter_scales(pi0: np.ndarray, layout: Layout, length: float = 0.05) -> np.ndarray:
    """Each parameter's natural scale: a body's mass (+10 g), its first moments m L, its
    inertias m L^2 (L = 5 cm), a motor's nominal values (+ a floor)."""
    s = np.empty_like(pi0)
    nb = len(layout.bodies)
    for b in range(nb):
        m = abs(pi0[N_BODY * b]) + 0.01
        s[N_BODY * b] = m
        s[N_BODY * b + 1:N_BODY * b + 4] = m * length
        s[N_BODY * b + 4:N_BODY * b + 10] = m * length ** 2
    mot = pi0[N_BODY * nb:].reshape(-1, N_MOTOR)
    floors = np.array([1e-3, 1e-3, 1e-2])
    s[N_BODY * nb:] = (np.abs(mot) + floors).reshape(-1)
    return s


@dataclass
class Consistent:
    pi: np.ndarray  # (P,) the physically consistent parameters
    prior_weight: float
    min_eigenvalue: float  # smallest eigenvalue over the bodies' pseudo-inertias
    solver: str
    status: str
    distance: float  # RMS of (pi - pi_0) / s
    notes: list[str] = field(default_factory=list)


def pseudo_inertia(p: np.ndarray) -> np.ndarray:
    """The 4 x 4 pseudo-inertia of one body's 10 parameters (Pinocchio's order)."""
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = p
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    sig = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    J = np.zeros((4, 4))
    J[:3, :3], J[:3, 3], J[3, :3], J[3, 3] = sig, (hx, hy, hz), (hx, hy, hz), m
    return J


#: vec(J) = T p (column-major, 16 x 10): the pseudo-inertia as a linear map of a body's
#: 10 parameters (:func:`pseudo_inertia`, which is linear).
_PSEUDO_INERTIA_MAP = np.stack([pseudo_inertia(e).reshape(-1, order="F")
                                for e in np.eye(N_BODY)], axis=1)


def consistent(Wb: np.ndarray, tau: np.ndarray, weights: np.ndarray, base: BaseParameters,
               pi0: np.ndarray, prior_weight: float = PRIOR_WEIGHT) -> Consistent:
    """The physically consistent full parameters (module doc, 4): minimise
    ||w (W_b B pi - tau)||^2 + prior over pi, subject to the LMIs."""
    # deferred: cvxpy loads only when this runs
    import cvxpy as cp

    lay = base.layout
    P = lay.size
    check_number("the prior weight", prior_weight, MIN_PRIOR_WEIGHT, MAX_PRIOR_WEIGHT)
    B = base.matrix
    r = base.rank
    # compress the data term: ||w (Wb B pi - tau)||^2 = ||R_b B pi - c||^2 + const, with
    # R the Cholesky factor of the weighted base regressor's augmented Gram matrix
    Aw = np.c_[Wb * weights[:, None], tau * weights]
    sc = np.linalg.norm(Aw, axis=0)
    sc[sc == 0] = 1.0
    Gm = (Aw / sc).T @ (Aw / sc)
    Gm[np.diag_indices_from(Gm)] *= 1.0 + 1e-13  # the residual's pivot may be ~0
    R = np.linalg.cholesky(Gm).T * sc[None, :]
    R1, c = R[:r, :r] @ B, R[:r, r]
    s = parameter_scales(pi0, lay)
    Rs = R1 * s[None, :]  # (r, P)
    info = float(np.sum(Rs ** 2)) / P
    lam = prior_weight * info
    z = cp.Variable(P)  # pi = pi0 + s z
    cons = []
    nb = len(lay.bodies)
    T = _PSEUDO_INERTIA_MAP
    for b in range(nb):  # each body's pseudo-inertia, one affine map of its 10 (vectorised)
        sl = slice(N_BODY * b, N_BODY * (b + 1))
        J = cp.reshape(T @ pi0[sl] + (T * s[sl][None, :]) @ z[sl], (4, 4), order="F")
        cons.append(0.5 * (J + J.T) >> 0)
    cons.append(pi0[N_BODY * nb:] + cp.multiply(s[N_BODY * nb:], z[N_BODY * nb:]) >= 0)
    obj = cp.Minimize(cp.sum_squares(Rs @ z - (c - R1 @ pi0)) + lam * cp.sum_squares(z))
    prob = cp.Problem(obj, cons)
    try:
        prob.solve(solver="CLARABEL")
    except cp.error.SolverError:
        prob.solve(solver="SCS", eps=1e-9, max_iters=200000)
    if z.value is None or prob.status not in ("optimal", "optimal_inaccurate"):
        raise InputError(f"the physically consistent estimate failed ({prob.status})",
                         value=prob.status, valid="a solvable problem")
    out = pi0 + s * np.asarray(z.value)
    notes: list[str] = []
    # Tiny negative eigenvalues of the solver's tolerance: shift into the cone exactly.
    for b in range(nb):
        sl = slice(N_BODY * b, N_BODY * (b + 1))
        ev = np.linalg.eigvalsh(pseudo_inertia(out[sl]))
        if ev[0] < 0:
            out[sl] = _shift_into_cone(out[sl], -ev[0])
    out[N_BODY * nb:] = np.maximum(out[N_BODY * nb:], 0.0)
    mins = [np.linalg.eigvalsh(pseudo_inertia(out[N_BODY * b:N_BODY * (b + 1)]))[0]
            for b in range(nb)]
    return Consistent(pi=out, prior_weight=prior_weight, min_eigenvalue=float(min(mins)),
                      solver=str(prob.solver_stats.solver_name), status=str(prob.status),
                      distance=float(np.sqrt(np.mean(((out - pi0) / s) ** 2))), notes=notes)


def _shift_into_cone(p: np.ndarray, eps: float) -> np.ndarray:
    """Add eps (plus a margin) to the pseudo-inertia's diagonal: J + e I is J with the
    mass raised by e and the second moments (Sigma) by e, i.e. the inertia by 2e on
    the diagonal... mapped back to the 10 parameters."""
    e = 1.001 * eps + 1e-15
    q = p.copy()
    q[0] += e  # m
    # Sigma + e I  <=>  I' = tr(Sigma') 1 - Sigma' : I_xx' = I_xx + 2e (and yy, zz)
    for k in (4, 6, 9):
        q[k] += 2 * e
    return q


def check_consistent(pi: np.ndarray, layout: Layout, tol: float = 0.0) -> None:
    """Raise InputError unless every body's pseudo-inertia is PSD and every motor
    parameter non-negative (an inconsistent set is never written)."""
    nb = len(layout.bodies)
    for b in range(nb):
        ev = np.linalg.eigvalsh(pseudo_inertia(pi[N_BODY * b:N_BODY * (b + 1)]))
        if ev[0] < -tol:
            raise InputError(f"body {layout.bodies[b]} is not physically consistent "
                             f"(pseudo-inertia eigenvalue {ev[0]:.3g})", value=float(ev[0]),
                             valid=">= 0")
    mot = pi[N_BODY * nb:]
    if np.any(mot < -tol):
        k = int(np.argmin(mot))
        raise InputError(f"motor parameter {layout.names[N_BODY * nb + k]} is negative",
                         value=float(mot[k]), valid=">= 0")


__all__ = ["Consistent", "LeastSquares", "check_consistent", "condition_number",
           "consistent", "least_squares", "parameter_scales", "pseudo_inertia"]
