"""A transient contact with the drives' position loop in it (issue 70, docs/safety.md,
"The drive in the contact").

ISO/TS 15066's two-body model holds the motors' torques during the contact.  A drive
whose position loop runs through the contact does not: it sees the point fall behind its
reference and pushes, so a stiff loop makes the contact harder.  This module computes the
contact's peak force with the loop in it:

- the robot linearised about its configuration: the actuated angles' error e = theta -
  theta_ref obeys M e'' = d_tau - J^T u F (M the reduced inertia with the rotors, J the
  point's Jacobian in the actuated rates, u the contact's normal), while the reference
  runs on along the plan (the point at v t along u: no guard, the reference never stops);
- the drive: each tick (the file's rate) d_tau = -Kp e - Kd (e - e_prev) rate from the
  encoder's difference, held over the tick (zero-order hold), the whole command
  tau_ff + d_tau clipped to the drive's torque limit; before the first tick after the
  onset d_tau = 0 (the tracking error before the contact is taken as zero);
- the body region: a mass m_H on the spring k (ISO/TS 15066 Table A.3) the point meets
  at speed v; the force k max(0, x - y) until they part.

``Kp = Kd = 0`` is the two-body model with the torques held (the peak is then
v sqrt(mu k), checked in tests/test_drive_contact.py against the closed form, and the
whole model against an ODE solver's solution).  The onset falls anywhere in a tick; the
peak is the largest over :data:`PHASES` of it.  Measured against MuJoCo
(benchmarks/bench_drive_contact.py, BENCHMARKS.md): the model's increase from torques
held to a soft or a stiff drive is MuJoCo's to within 0.3 %, where a continuous,
unsaturated loop overstates it by up to 35 %.

A clamp (m_H infinite: the region backed by a wall) is met the same way, but its force
grows while the reference runs on, so the reference stands from ``stop`` on (the
contact guard's reaction, docs/safety.md): the actuated rates' jump to zero enters the
error's rates, and the loop then presses toward the standing reference.  Measured
against MuJoCo with the guard in the loop, the model with ``stop`` at the guard's own
detection delay gives MuJoCo's peaks to within a few per cent
(benchmarks/bench_drive_contact.py).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from sixplus3.robot_description import hardware
from sixplus3.robot_description.body_regions import BodyRegion
from sixplus3.robot_description.hardware import PositionLoop

#: Where in a tick the contact begins (a share of the tick after the drive's update).
PHASES = (0.0, 1.0 / 3.0, 2.0 / 3.0)
#: The integration's step, at most [s] (semi-implicit Euler): 1/200 of a 1 kHz tick,
#: 1/20 of a 10 kHz one, and at most 1/300 of the contact's own period.
MAX_STEP = 5e-6
#: The longest contact followed [s] (a free region's contact lasts a few ms; the
#: transient window of the simulated person, control/drive/person.py).
HORIZON = 0.05
#: A clamp is followed this long after its reference stands [s].
AFTER_STOP = 0.03


class DriveCase(NamedTuple):
    """A batch of contacts: ``Minv`` (N, 9, 9) the inverse reduced inertia, ``ju`` (N, 9)
    J^T u, ``speed`` (N,) the point's speed along u [m/s], ``tau`` (N, 9) the planned
    torques, ``cap`` (9,) the drives' torque limits [N m], ``mass`` and ``stiffness``
    (N,) the body region's m_H [kg] (inf: a clamp) and k [N/m], ``rates`` (N, 9) the
    reference's actuated rates [rad/s] (what stops when the reference stands)."""

    Minv: np.ndarray
    ju: np.ndarray
    speed: np.ndarray
    tau: np.ndarray
    cap: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    rates: np.ndarray


@njit(cache=True, error_model="numpy")
def _peak(Minv: np.ndarray, ju: np.ndarray, v: float, tau: np.ndarray, cap: np.ndarray,
          mH: float, kH: float, gains: np.ndarray, thd: np.ndarray) -> float:
    """The peak force of one contact (module doc); gains = (kp, kd, rate, phase,
    t_stop): the reference stands from t_stop on (inf: it runs on), thd (9) its rates
    before."""
    kp, kd, rate, phase, t_stop = gains[0], gains[1], gains[2], gains[3], gains[4]
    tick = 1.0 / rate
    inv_m = 0.0
    for i in range(9):
        for j in range(9):
            inv_m += ju[i] * Minv[i, j] * ju[j]
    w_c = math.sqrt(kH * (inv_m + 1.0 / mH))  # the contact's own frequency
    dt = min(MAX_STEP, 0.02 / w_c)
    clamp = not (mH < np.inf)
    horizon = min(HORIZON, t_stop + AFTER_STOP) if clamp else HORIZON
    w = np.zeros(9)  # M^-1 J^T u
    for i in range(9):
        for j in range(9):
            w[i] += Minv[i, j] * ju[j]
    e, ed, e_prev, dtau, acc = (np.zeros(9), np.zeros(9), np.zeros(9), np.zeros(9),
                                np.zeros(9))
    y = yd = 0.0
    t, t_next, peak = 0.0, (1.0 - phase) * tick, 0.0
    moving = True
    while t < horizon:
        if moving and t >= t_stop - 0.5 * dt:  # the reference stands: e' = theta'
            for i in range(9):
                ed[i] += thd[i]
            moving = False
        if t >= t_next - 0.5 * dt:
            for i in range(9):
                d = -kp * e[i] - kd * (e[i] - e_prev[i]) * rate
                dtau[i] = min(max(d, -cap[i] - tau[i]), cap[i] - tau[i])
                e_prev[i] = e[i]
            for i in range(9):
                acc[i] = 0.0
                for j in range(9):
                    acc[i] += Minv[i, j] * dtau[j]
            t_next += tick
        x = v * min(t, t_stop)
        for i in range(9):
            x += ju[i] * e[i]
        f = kH * (x - y) if x > y else 0.0
        if f > peak:
            peak = f
        elif f == 0.0 and peak > 0.0 and not clamp:
            break  # parted
        for i in range(9):
            ed[i] += dt * (acc[i] - w[i] * f)
            e[i] += dt * ed[i]
        yd += dt * f / mH
        y += dt * yd
        t += dt
    return peak


@njit(cache=True, error_model="numpy")
def _peaks(Minv: np.ndarray, ju: np.ndarray, speed: np.ndarray, tau: np.ndarray,
           cap: np.ndarray, mass: np.ndarray, stiffness: np.ndarray, gains: np.ndarray,
           phases: np.ndarray, thd: np.ndarray) -> np.ndarray:
    out = np.zeros(len(speed))
    g = np.zeros(5)
    g[0], g[1], g[2], g[4] = gains[0], gains[1], gains[2], gains[3]
    for n in range(len(speed)):
        if not (speed[n] > 0.0) or not np.isfinite(speed[n]):
            out[n] = 0.0 if speed[n] == 0.0 else np.inf
            continue
        for p in phases:
            g[3] = p
            f = _peak(Minv[n], ju[n], speed[n], tau[n], cap, mass[n], stiffness[n], g,
                      thd[n])
            if f > out[n]:
                out[n] = f
    return out


def drive_cap() -> np.ndarray:
    """(9,) [N m] what the drives can ask for in a contact: the site's drive train's
    catalogue torque, whatever its envelope (the loop's command is clipped there)."""
    return np.full(9, hardware.catalogue_envelope(hardware.active().drive_train).torque)


def reference_stop(region: BodyRegion, rate: float) -> float:
    """[s] when the reference stands after a contact's onset: never for a free region
    (no guard is assumed), the site's ``guard_detection`` and one tick for a clamp."""
    if np.isfinite(region.mass):
        return math.inf
    return hardware.active().guard_detection + 1.0 / rate


def contact_peaks(case: DriveCase, loop: PositionLoop, rate: float,
                  phases: tuple[float, ...] = PHASES, stop: float = math.inf
                  ) -> np.ndarray:
    """(N,) [N] the peak force of each contact of ``case`` with the drives' position loop
    ``loop`` at ``rate`` [Hz] in it (module doc; ``PositionLoop(0, 0)``: the torques
    held), the reference standing from ``stop`` [s] after the onset on (inf: it runs
    on).  A non-finite case: inf."""
    Minv = np.ascontiguousarray(case.Minv, dtype=float).reshape(-1, 9, 9)
    n = len(Minv)
    ju = np.ascontiguousarray(case.ju, dtype=float).reshape(n, 9)
    speed = np.ascontiguousarray(case.speed, dtype=float).reshape(n)
    tau = np.ascontiguousarray(np.broadcast_to(case.tau, (n, 9)), dtype=float)
    thd = np.ascontiguousarray(np.broadcast_to(case.rates, (n, 9)), dtype=float)
    mass = np.ascontiguousarray(np.broadcast_to(case.mass, (n,)), dtype=float)
    stiffness = np.ascontiguousarray(np.broadcast_to(case.stiffness, (n,)), dtype=float)
    cap = np.ascontiguousarray(case.cap, dtype=float).reshape(9)
    ok = (np.isfinite(Minv).all(axis=(1, 2)) & np.isfinite(ju).all(axis=1)
          & np.isfinite(tau).all(axis=1) & np.isfinite(thd).all(axis=1))
    speed = np.where(ok, speed, np.inf)
    Minv, ju = np.where(ok[:, None, None], Minv, 0.0), np.where(ok[:, None], ju, 0.0)
    tau, thd = np.where(ok[:, None], tau, 0.0), np.where(ok[:, None], thd, 0.0)
    gains = np.array([loop.kp, loop.kd, rate, stop], dtype=float)
    return np.asarray(_peaks(Minv, ju, np.abs(speed), tau, cap, mass, stiffness, gains,
                             np.asarray(phases, dtype=float), thd))


def drive_ratio(Jp: np.ndarray, M: np.ndarray, thd: np.ndarray, tau: np.ndarray,
                cap: np.ndarray, region: BodyRegion, loop: PositionLoop, rate: float,
                normals: list[np.ndarray], stop: float = math.inf) -> np.ndarray:
    """(n,) the largest (F / F_max)^2 over the unit ``normals`` (each (n, 3)) of contacts
    with ``region`` at points moving at J_p theta_dot (J_p (n, 3, 9), the actuated rates
    ``thd`` (n, 9)), the reduced inertia M (n, 9, 9), the planned torques ``tau`` (n, 9),
    the drives' limit ``cap`` (9,), with the site's position ``loop`` at ``rate`` in the
    contact and the reference standing from ``stop`` on (:func:`contact_peaks`).  A
    normal the point moves away from, or none (a point at rest), meets nothing (0); a
    state that is not finite is judged unsafe (inf)."""
    n = len(thd)
    v = np.einsum("nij,nj->ni", Jp, thd)
    bad = ~(np.isfinite(v).all(axis=1) & np.isfinite(Jp).all(axis=(1, 2))
            & np.isfinite(M).all(axis=(1, 2)) & np.isfinite(tau).all(axis=1))
    M = np.where(bad[:, None, None], np.eye(9), M)
    with np.errstate(all="ignore"):
        Minv = np.linalg.inv(M)
    out = np.zeros(n)
    for u in normals:
        speed = np.einsum("ni,ni->n", u, v)
        ju = np.einsum("nij,ni->nj", Jp, u)
        hit = (speed > 0.0) & ~bad
        if not hit.any():
            continue
        k = int(hit.sum())
        case = DriveCase(Minv[hit], ju[hit], speed[hit], tau[hit], cap,
                         np.full(k, region.mass), np.full(k, region.stiffness), thd[hit])
        f = contact_peaks(case, loop, rate, stop=stop) / region.transient_force
        out[hit] = np.maximum(out[hit], f * f)
    out[bad] = np.inf
    return out


__all__ = ["AFTER_STOP", "HORIZON", "MAX_STEP", "PHASES", "DriveCase", "contact_peaks",
           "drive_cap", "drive_ratio", "reference_stop"]
