"""Kinematics of one RU/2-RUS leg: IK, FK, Jacobians, singularities, static torques.

Paper §III-IV with the conventions of docs/conventions.md (see :mod:`robot_description.geometry`).
All batch functions take points with a leading batch axis, shape (n, 3), and report a
per-point ``status`` (0 = solved) instead of raising; the ``*_point`` variants take one
point and raise a named error.

Equations (leg frame, a = 0):

- RU chain: |p - d| = dp  =>  y cos th1 + z sin th1 = (|p|^2 + l1^2 - dp^2) / (2 l1);
- Q p_b = p - d gives th_s3 (two branches, sign of cos th_s3) and th_s2 (atan2);
- RUS chains: |e - g| = l4, |f - h| = l5 give th2 and th3 (two branches each);
- J pdot = K thdot (paper §III-C), tau = K^T J^-T f for a force f at P;
- tau_ext = max over f in F = F_g + 2 m g B^3 of max_j |tau_j|
          = m g max_j ( sqrt(M_jy^2 + M_jz^2) + 2 |M_j| ),  M = K^T J^-T.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sixplus3.errors import ConvergenceError, InputError, UnreachableError, as_float_array
from sixplus3.kinematics import _leg_fk_kernel as fk_kern
from sixplus3.kinematics import _leg_kernel as kern
from sixplus3.robot_description.assembly import DEFAULT_MODE, AssemblyMode
from sixplus3.robot_description.geometry import LegGeometry, LegLoad

#: Margin below which a configuration is classified as singular (scale-free, see margins).
SINGULAR_TOL = 1e-3


DEFAULT_GEOMETRY = LegGeometry()
DEFAULT_LOAD = LegLoad()


def status_reason(status: int) -> str:
    """Human-readable reason for a status bitmask (0 -> 'ok')."""
    if status == 0:
        return "ok"
    parts = []
    if status & kern.STATUS_INPUT:
        parts.append("input is not finite")
    if status & kern.STATUS_RU:
        parts.append("RU chain: P is outside the torus |P - D| = dp (or on the actuated axis)")
    if status & kern.STATUS_RUS_B:
        parts.append("RUS chain B: |E - B| is outside [|l2 - l4|, l2 + l4] for every crank angle")
    if status & kern.STATUS_RUS_C:
        parts.append("RUS chain C: |F - C| is outside [|l3 - l5|, l3 + l5] for every crank angle")
    if status & kern.STATUS_FK_NOCONV:
        parts.append("forward kinematics did not converge from any seed")
    if status & kern.STATUS_FK_MODE:
        parts.append("forward kinematics found no assembly in the requested mode")
    return "; ".join(parts)


def failing_chain(status: int) -> str:
    """Name of the first chain that fails for a status bitmask."""
    if status & kern.STATUS_RU:
        return "RU"
    if status & kern.STATUS_RUS_B:
        return "RUS-B"
    if status & kern.STATUS_RUS_C:
        return "RUS-C"
    return "input"


@dataclass(frozen=True)
class LegState:
    """Everything known about leg configurations, batched along the leading axis.

    Points whose ``status`` is not 0 carry zeros except ``margin_I = margin_II = 0`` and
    ``tau_ext = inf``, so any limit check on them fails; no NaN is produced.
    """

    status: np.ndarray  # (n,) int, 0 = solved, bitmask otherwise (status_reason)
    theta: np.ndarray  # (n, 3) actuated angles [rad] in [-pi/2, 3pi/2)
    theta_s: np.ndarray  # (n, 2) passive U-joint angles th_s2, th_s3 [rad]
    Q: np.ndarray  # (n, 3, 3) body rotation
    p: np.ndarray  # (n, 3) end-effector [m]
    d: np.ndarray  # (n, 3) [m]
    e: np.ndarray  # (n, 3) [m]
    f: np.ndarray  # (n, 3) [m]
    g: np.ndarray  # (n, 3) [m]
    h: np.ndarray  # (n, 3) [m]
    J_scaled: np.ndarray  # (n, 3, 3) diag(1, det Jp, det Jp) J  [m, m^3]
    K: np.ndarray  # (n, 3, 3) [m^2]
    J_tilde: np.ndarray  # (n, 3, 3) Proposition 1
    M: np.ndarray  # (n, 3, 3) tau = M f  [m]
    det_J: np.ndarray  # (n,) [m^3]
    det_K: np.ndarray  # (n,) [m^6]
    det_J_tilde: np.ndarray  # (n,)
    det_Jp: np.ndarray  # (n,) det of J_p; zero at type I
    margin_I: np.ndarray  # (n,) in [0, 1]: min_j |K_jj| / (|link_j| |u_j|)
    margin_II: np.ndarray  # (n,) in [0, 1]: sigma_min of row-normalised J
    tau_ext: np.ndarray  # (n,) [N m]

    @classmethod
    def _from_rows(cls, rows: np.ndarray) -> LegState:
        n = rows.shape[0]

        def v(i: int) -> np.ndarray:
            return rows[:, i:i + 3].copy()

        def m(i: int) -> np.ndarray:
            return rows[:, i:i + 9].reshape(n, 3, 3).copy()

        return cls(
            status=rows[:, kern.ST].astype(np.int64),
            theta=v(kern.TH), theta_s=rows[:, kern.TS:kern.TS + 2].copy(), Q=m(kern.QM),
            p=v(kern.PP), d=v(kern.PD), e=v(kern.PE), f=v(kern.PF), g=v(kern.PG),
            h=v(kern.PH), J_scaled=m(kern.JR), K=m(kern.KM), J_tilde=m(kern.JT),
            M=m(kern.MM), det_J=rows[:, kern.DET_J].copy(), det_K=rows[:, kern.DET_K].copy(),
            det_J_tilde=rows[:, kern.DET_JT].copy(), det_Jp=rows[:, kern.DET_JP].copy(),
            margin_I=rows[:, kern.MARGIN_I].copy(), margin_II=rows[:, kern.MARGIN_II].copy(),
            tau_ext=rows[:, kern.TAU_EXT].copy(),
        )

    def __len__(self) -> int:
        return int(self.status.shape[0])

    @property
    def ok(self) -> np.ndarray:
        """(n,) bool: the point was solved."""
        return self.status == 0

    @property
    def J(self) -> np.ndarray:
        """(n, 3, 3) the paper's J [m].  Unbounded at type I (det Jp = 0): use J_scaled."""
        den = np.ones((len(self), 3, 1))
        den[:, 1:, 0] = self.det_Jp[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            J = self.J_scaled / den
        # Exactly at type I: +-inf where J' != 0, and 0 (not 0/0) where J' = 0.
        J[np.isnan(J)] = 0.0
        return np.where(self.ok[:, None, None], J, 0.0)

    def dtheta_dp(self) -> np.ndarray:
        """(n, 3, 3) K^-1 J, the IK Jacobian d theta / d p [rad/m] (0 where unsolved)."""
        usable = self.ok & (self.det_K != 0.0)
        K = np.where(usable[:, None, None], self.K, np.eye(3))
        return np.where(usable[:, None, None], np.linalg.solve(K, self.J), 0.0)

    def torques(self, force: np.ndarray) -> np.ndarray:
        """Static actuator torques tau = K^T J^-T f [N m] for forces f at P [N], (n, 3)."""
        force = np.broadcast_to(np.asarray(force, dtype=float), (len(self), 3))
        return np.einsum("nij,nj->ni", self.M, force)

    def singularity(self, tol: float = SINGULAR_TOL) -> np.ndarray:
        """(n,) array of 'none' | 'type1' | 'type2' ('unsolved' for failed points)."""
        out = np.full(len(self), "none", dtype=object)
        out[self.margin_II < tol] = "type2"
        out[self.margin_I < tol] = "type1"  # type I takes precedence: J is undefined there
        out[~self.ok] = "unsolved"
        return out

    def point(self, i: int) -> LegState:
        """The i-th configuration as a batch of one."""
        return LegState(**{k: getattr(self, k)[i:i + 1] for k in self.__dataclass_fields__})


def _as_points(points: np.ndarray | list[Any], name: str = "points") -> np.ndarray:
    arr = as_float_array(points, name, "(n, 3) or (3,) [m]")
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must have shape (n, 3) or (3,), got {np.shape(points)}",
                         value=np.shape(points), valid="(n, 3) or (3,)")
    return np.ascontiguousarray(arr)


def _mass_terms(load: LegLoad) -> tuple[float, float]:
    return load.mass * load.gravity, load.accel_g


def leg_ik(
    points: np.ndarray,
    geometry: LegGeometry = DEFAULT_GEOMETRY,
    mode: AssemblyMode | str = DEFAULT_MODE,
    load: LegLoad = DEFAULT_LOAD,
) -> LegState:
    """Inverse kinematics, Jacobians and statics of (n, 3) points p [m] in the leg frame."""
    pts = _as_points(points)
    mg, ag = _mass_terms(load)
    batch = kern.full_batch if len(pts) >= kern.SERIAL_BELOW else kern.full_batch_serial
    rows = batch(pts, geometry.packed(), AssemblyMode.parse(mode).array(), mg, ag)
    return LegState._from_rows(rows)


def leg_ik_point(
    p: np.ndarray | list[Any],
    geometry: LegGeometry = DEFAULT_GEOMETRY,
    mode: AssemblyMode | str = DEFAULT_MODE,
    load: LegLoad = DEFAULT_LOAD,
) -> LegState:
    """IK of one point; raises :class:`UnreachableError` naming the chain that fails."""
    arr = np.asarray(p, dtype=np.float64)
    if arr.shape != (3,):
        raise InputError(f"p must be 3 numbers [m], got shape {arr.shape}",
                         value=arr.shape, valid="(3,) [m]")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"p must be finite, got {arr.tolist()}",
                         value=arr.tolist(), valid="finite [m]")
    state = leg_ik(arr, geometry, mode, load)
    st = int(state.status[0])
    if st != 0:
        raise UnreachableError(failing_chain(st), tuple(arr.tolist()), status_reason(st))
    return state


@dataclass(frozen=True)
class LegEval:
    """Compact per-point evaluation for workspace and design searches."""

    status: np.ndarray  # (n,)
    theta: np.ndarray  # (n, 3) [rad]
    det_J: np.ndarray  # (n,)
    det_K: np.ndarray  # (n,)
    margin_I: np.ndarray  # (n,)
    margin_II: np.ndarray  # (n,)
    tau_ext: np.ndarray  # (n,) [N m]

    @property
    def ok(self) -> np.ndarray:
        return self.status == 0


def leg_eval(
    points: np.ndarray,
    geometry: LegGeometry = DEFAULT_GEOMETRY,
    mode: AssemblyMode | str = DEFAULT_MODE,
    load: LegLoad = DEFAULT_LOAD,
    margin_ii: bool = True,
) -> LegEval:
    """Batched IK + J + K + tau_ext with a compact output (the throughput kernel).

    ``margin_ii=False`` skips the type II margin (``margin_II`` is then 0), ~10% faster.
    """
    return leg_eval_packed(_as_points(points), geometry.packed(),
                           AssemblyMode.parse(mode), load, margin_ii)


def leg_eval_packed(pts: np.ndarray, geo: np.ndarray, mode: AssemblyMode,
                    load: LegLoad = DEFAULT_LOAD, margin_ii: bool = True,
                    out: np.ndarray | None = None) -> LegEval:
    """:func:`leg_eval` on an already packed geometry (no validation: hot loops only).

    ``out`` is an optional reusable (n, E_NF) float64 buffer; the returned arrays are
    views into it.
    """
    mg, ag = _mass_terms(load)
    r = np.empty((pts.shape[0], kern.E_NF)) if out is None else out[:pts.shape[0]]
    kern.eval_into(pts, geo, mode.array(), mg, ag, margin_ii, r)
    return LegEval(
        status=r[:, kern.E_ST].astype(np.int64), theta=r[:, kern.E_TH:kern.E_TH + 3],
        det_J=r[:, kern.E_DET_J], det_K=r[:, kern.E_DET_K], margin_I=r[:, kern.E_MARGIN_I],
        margin_II=r[:, kern.E_MARGIN_II], tau_ext=r[:, kern.E_TAU_EXT],
    )


def _fk_seeds(mode: AssemblyMode) -> np.ndarray:
    """Newton seeds (th_s2, th_s3), ordered from the home-like configuration outwards."""
    s3 = np.array([0.0, 0.6, -0.6, 1.2, -1.2])
    if mode.signs[1] < 0:
        s3 = math.pi - s3
    s2 = math.pi / 2 + np.array([0, 1, -1, 2, -2, 3, -3, 4]) * (math.pi / 4)
    seeds = [(a, b) for b in s3 for a in s2]
    return np.array(seeds, dtype=np.float64)


def leg_fk(
    theta: np.ndarray,
    geometry: LegGeometry = DEFAULT_GEOMETRY,
    mode: AssemblyMode | str = DEFAULT_MODE,
    hint_theta_s: np.ndarray | None = None,
    load: LegLoad = DEFAULT_LOAD,
) -> LegState:
    """Forward kinematics theta (n, 3) [rad] -> full state, by Newton on (th_s2, th_s3).

    With ``hint_theta_s`` (n, 2), Newton starts from the hint (e.g. the previous sample of
    a trajectory) and so tracks that assembly; the fixed seed grid of :func:`_fk_seeds`
    follows as a fallback.  The accepted solution is the first whose IK in ``mode``
    reproduces theta to 1e-9 rad.  Failed points have status 16 (no convergence) or 32
    (no assembly in that mode).
    """
    mode = AssemblyMode.parse(mode)
    th = _as_points(theta, "theta")
    base = _fk_seeds(mode)
    n = th.shape[0]
    if hint_theta_s is None:
        seeds = np.broadcast_to(base, (n, *base.shape))
    else:
        hint = np.asarray(hint_theta_s, dtype=np.float64).reshape(-1, 2)
        hint = np.broadcast_to(hint, (n, 2))
        seeds = np.concatenate([hint[:, None, :], np.broadcast_to(base, (n, *base.shape))],
                               axis=1)
    mg, ag = _mass_terms(load)
    batch = fk_kern.fk_batch if n >= kern.SERIAL_BELOW else fk_kern.fk_batch_serial
    rows = batch(th, geometry.packed(), mode.array(), np.ascontiguousarray(seeds), mg, ag)
    return LegState._from_rows(rows)


def leg_fk_point(theta: np.ndarray | list[Any], geometry: LegGeometry = DEFAULT_GEOMETRY,
                 mode: AssemblyMode | str = DEFAULT_MODE,
                 hint_theta_s: np.ndarray | None = None) -> LegState:
    """FK of one theta (3,); raises :class:`ConvergenceError` when no assembly is found."""
    arr = np.asarray(theta, dtype=np.float64)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise InputError(f"theta must be 3 finite angles [rad], got {np.asarray(theta)!r}",
                         value=np.asarray(theta).tolist(), valid="3 finite angles [rad]")
    state = leg_fk(arr, geometry, mode, hint_theta_s)
    st = int(state.status[0])
    if st != 0:
        raise ConvergenceError(f"leg forward kinematics failed for theta={arr.tolist()} rad "
                               f"in mode {AssemblyMode.parse(mode)}: {status_reason(st)}",
                               value=arr.tolist(),
                               valid="angles the leg can assemble in this mode")
    return state
