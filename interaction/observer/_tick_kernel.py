"""The per-tick arithmetic of the wrench observer, the lead-through and the envelope,
compiled (numba; docs/leadthrough.md, "Cost per tick").

A 1 kHz loop in Python cannot afford numpy's per-call overhead on 9-vectors (about a
microsecond a call, a few hundred calls a tick): these kernels do a tick's small linear
algebra in compiled code, on preallocated arrays, with the same formulas (and the same
order of operations) as the Python they replaced.  Their callers
(:mod:`~sixplus3.interaction.observer.compiled_state`,
:class:`~sixplus3.interaction.observer.stream.WrenchStream`,
:class:`~sixplus3.interaction.lead.leadthrough.LeadThrough`,
:func:`~sixplus3.interaction.envelope.within_envelope`) keep the state and the logic.

The 9 x 9 solves are an LU factorisation with partial pivoting (LAPACK's dgetrf
convention: row i swapped with ``piv[i]``), checked against scipy's in
tests/test_tick_kernel.py.  Matrices from CasADi's buffers are column-major and flat
(``jx[i + 9 j]``)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sixplus3.dynamics._ccall import call_casadi

#: A pivot below this (relative to the matrix's largest entry) is singular.
SINGULAR = 1e-14


@njit(cache=True, error_model="numpy")
def lu_factor(a, lu, piv):
    """LU of the (9, 9) ``a`` into ``lu`` (in place, L unit below, U on and above) and
    ``piv``; returns 0, or k + 1 when the k-th pivot is singular."""
    n = a.shape[0]
    scale = 0.0
    for i in range(n):
        for j in range(n):
            lu[i, j] = a[i, j]
            scale = max(scale, abs(a[i, j]))
    tiny = SINGULAR * max(scale, 1e-300)
    for k in range(n):
        p = k
        big = abs(lu[k, k])
        for i in range(k + 1, n):
            if abs(lu[i, k]) > big:
                big, p = abs(lu[i, k]), i
        piv[k] = p
        if big <= tiny:
            return k + 1
        if p != k:
            for j in range(n):
                lu[k, j], lu[p, j] = lu[p, j], lu[k, j]
        inv = 1.0 / lu[k, k]
        for i in range(k + 1, n):
            f = lu[i, k] * inv
            lu[i, k] = f
            if f != 0.0:
                for j in range(k + 1, n):
                    lu[i, j] -= f * lu[k, j]
    return 0


@njit(cache=True, error_model="numpy")
def lu_solve(lu, piv, b, out):
    """out = A^-1 b from :func:`lu_factor`'s factors (``out`` may be ``b``)."""
    n = lu.shape[0]
    for i in range(n):
        out[i] = b[i]
    for k in range(n):
        p = piv[k]
        if p != k:
            out[k], out[p] = out[p], out[k]
    for i in range(n):
        s = out[i]
        for j in range(i):
            s -= lu[i, j] * out[j]
        out[i] = s
    for i in range(n - 1, -1, -1):
        s = out[i]
        for j in range(i + 1, n):
            s -= lu[i, j] * out[j]
        out[i] = s / lu[i, i]


@njit(cache=True, error_model="numpy")
def lu_solve_t(lu, piv, b, out):
    """out = A^-T b from :func:`lu_factor`'s factors (``out`` may be ``b``)."""
    n = lu.shape[0]
    for i in range(n):
        out[i] = b[i]
    for i in range(n):  # U^T z = b
        s = out[i]
        for j in range(i):
            s -= lu[j, i] * out[j]
        out[i] = s / lu[i, i]
    for i in range(n - 1, -1, -1):  # L^T w = z
        s = out[i]
        for j in range(i + 1, n):
            s -= lu[j, i] * out[j]
        out[i] = s
    for k in range(n - 1, -1, -1):  # y = P^T w
        p = piv[k]
        if p != k:
            out[k], out[p] = out[p], out[k]


@njit(cache=True, error_model="numpy")
def matvec(A, x, out):
    """out = A x (numba's @ calls BLAS: about a microsecond a call on these sizes)."""
    for i in range(A.shape[0]):
        s = 0.0
        for j in range(A.shape[1]):
            s += A[i, j] * x[j]
        out[i] = s


@njit(cache=True, error_model="numpy")
def skew_squared(r):
    """[r]x [r]x = r r^T - |r|^2 I."""
    t2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    k2 = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            k2[i, j] = r[i] * r[j] - (t2 if i == j else 0.0)
    return k2


@njit(cache=True, error_model="numpy")
def _wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, error_model="numpy")
def predict(x, lu, piv, theta, theta_prev, step):
    """x += A^-1 (theta - theta_prev) (the previous sample's factors: a first-order
    prediction of the next pose)."""
    for i in range(9):
        step[i] = theta[i] - theta_prev[i]
    lu_solve(lu, piv, step, step)
    for i in range(9):
        x[i] += step[i]


@njit(cache=True, error_model="numpy")
def newton(x, th, jx, theta, lu, piv, step, tol):
    """One Newton step of forward kinematics at x, given theta(x) ``th`` and d theta / d x
    ``jx`` (flat, column-major): factor J_x; (the largest angle error, info); x moved
    by J_x^-1 (theta - th) when neither converged (error < ``tol``) nor singular."""
    a = np.empty((9, 9))
    for j in range(9):
        for i in range(9):
            a[i, j] = jx[i + 9 * j]
    info = lu_factor(a, lu, piv)
    err = 0.0
    for i in range(9):
        step[i] = _wrap(theta[i] - th[i])
        err = max(err, abs(step[i]))
    if err < tol or info != 0:
        return err, info
    lu_solve(lu, piv, step, step)
    for i in range(9):
        x[i] += step[i]
    return err, info


@njit(cache=True, error_model="numpy")
def _skew(r):
    k = np.zeros((3, 3))
    k[0, 1], k[0, 2], k[1, 2] = -r[2], r[1], -r[0]
    k[1, 0], k[2, 0], k[2, 1] = r[2], -r[1], r[0]
    return k


@njit(cache=True, error_model="numpy")
def rotation_and_inverse_left_jacobian(r):
    """(exp([r]x), J_l(r)^-1) in closed form (series near r = 0; near a half turn J_l
    inverted numerically)."""
    t2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    K = _skew(r)
    K2 = skew_squared(r)
    eye = np.eye(3)
    if t2 < 1e-8:
        return eye + K + 0.5 * K2, eye - 0.5 * K + K2 / 12.0
    t = math.sqrt(t2)
    s, c = math.sin(t), math.cos(t)
    R = eye + (s / t) * K + ((1.0 - c) / t2) * K2
    if abs(s) < 1e-6:
        Jl = eye + (1.0 - c) / t2 * K + (t - s) / (t2 * t) * K2
        return R, np.linalg.inv(Jl)
    return R, eye - 0.5 * K + (1.0 / t2 - (1.0 + c) / (2.0 * t * s)) * K2


@njit(cache=True, error_model="numpy")
def friction(w, viscous, coulomb, speed, out):
    """out = viscous w + coulomb tanh(w / speed) (per joint)."""
    for i in range(9):
        out[i] = viscous[i] * w[i] + coulomb[i] * math.tanh(w[i] / speed)


@njit(cache=True, error_model="numpy")
def observer_state(lu, piv, model_out, r, thd, drive, outs):
    """The observer's state from the compiled model's outputs ``model_out`` (jx, q0, qa,
    c) at x (r = x[3:6]), with the drive's ``drive`` (armature, viscous, coulomb,
    speed): M = J_x^-T Q_a J_x^-1 + diag(I_a), h = J_x^-T (Q_0 - Q_a J_x^-1 c) +
    friction(thd), J = J_x blockdiag(I, J_l(r)^-1, I), R = exp([r]x) (into ``outs``:
    J, M, h, R)."""
    jx, q0, qa, c = model_out
    armature, viscous, coulomb, speed = drive
    J, M, h, R = outs
    Qa = np.empty((9, 9))
    for j in range(9):
        for i in range(9):
            Qa[i, j] = qa[i + 9 * j]
    B = np.empty((9, 9))  # J_x^-T Q_a, column by column
    col = np.empty(9)
    for j in range(9):
        lu_solve_t(lu, piv, Qa[:, j].copy(), col)
        B[:, j] = col
    Mt = np.empty((9, 9))  # (B J_x^-1)^T = J_x^-T B^T, column by column
    for j in range(9):
        lu_solve_t(lu, piv, B[j, :].copy(), col)
        Mt[:, j] = col
    for i in range(9):
        for j in range(9):
            M[i, j] = 0.5 * (Mt[j, i] + Mt[i, j])
        M[i, i] += armature[i]
    lu_solve_t(lu, piv, q0, h)
    cs = np.empty(9)
    lu_solve(lu, piv, c, cs)
    fr = np.empty(9)
    friction(thd, viscous, coulomb, speed, fr)
    for i in range(9):
        s = 0.0
        for j in range(9):
            s += B[i, j] * cs[j]
        h[i] = h[i] - s + fr[i]
    Rm, Jli = rotation_and_inverse_left_jacobian(r)
    R[:, :] = Rm
    for j in range(9):
        for i in range(9):
            J[i, j] = jx[i + 9 * j]
    for i in range(9):
        a0, a1, a2 = J[i, 3], J[i, 4], J[i, 5]
        for k in range(3):
            J[i, 3 + k] = a0 * Jli[0, k] + a1 * Jli[1, k] + a2 * Jli[2, k]


@njit(cache=True, error_model="numpy")
def velocity(theta, prev, have_prev, rate, b, a, z, out):
    """The encoder's difference through the biquad (b, a) (transposed direct form II,
    state z (2, 9)) into ``out``."""
    for i in range(9):
        raw = (theta[i] - prev[i]) * rate if have_prev else 0.0
        y = b[0] * raw + z[0, i]
        z[0, i] = b[1] * raw - a[1] * y + z[1, i]
        z[1, i] = b[2] * raw - a[2] * y
        out[i] = y


@njit(cache=True, error_model="numpy")
def observe(tau, thd, M, h, dt, gain, lag, state):
    """One sample of the momentum observer, the one the batch estimator, the stream,
    the contact guard and lead-through run (:class:`~sixplus3.interaction.observer.momentum.
    MomentumObserver`): p = M thd; at the first sample p0 = p and r = 0; then
    step = (tau - h + (M - M_prev) thd / dt + r) dt, the integral += step and
    r = K (p - p0 - (integral - lag step)) (``lag``: how many ticks the momentum's rate
    lags the sample: 1/2 for an encoder's difference).  ``state``: (M_prev (9, 9), p0,
    integral, r (9), started (1,) int), in place."""
    prev_M, p0, integral, r, started = state
    p = np.empty(9)
    matvec(M, thd, p)
    if not started[0]:
        p0[:] = p
    else:
        step = np.empty(9)
        for i in range(9):
            s = 0.0
            for j in range(9):
                s += (M[i, j] - prev_M[i, j]) * thd[j]
            step[i] = (tau[i] - h[i] + s / dt + r[i]) * dt
        for i in range(9):
            integral[i] += step[i]
            late = integral[i] - lag * step[i] if lag != 0.0 else integral[i]
            r[i] = gain * (p[i] - p0[i] - late)
    prev_M[:, :] = M
    started[0] = 1


@njit(cache=True, error_model="numpy")
def observe_series(t, tau, thd, M, h, gain, lag, state, out):
    """:func:`observe` over a log's n samples (t (n,), the rest (n, 9) or (n, 9, 9)),
    the residuals into ``out`` (n, 9)."""
    for k in range(len(t)):
        dt = t[k] - t[k - 1] if k > 0 else 1.0
        observe(tau[k], thd[k], M[k], h[k], dt, gain, lag, state)
        out[k, :] = state[3]


@njit(cache=True, error_model="numpy")
def momentum(tau, thd, J, M, h, prev_tau, state, gain, dt, settings, out):
    """One sample of :class:`~sixplus3.interaction.observer.stream.WrenchStream`'s observer: the
    drive's torque held over the last tick (the mean of this sample's and the last, once
    there was one), :func:`observe`, then the platform wrench J^T r (first six), its
    standard deviation and the friction band of the slow joints.  ``settings``: (var (9),
    fc (9), v_band); ``out``: (w, std, band) (6 each)."""
    var, fc, v_band = settings
    w, std, band = out
    started = state[4]
    held = np.empty(9)
    for i in range(9):
        held[i] = 0.5 * (tau[i] + prev_tau[i]) if started[0] else tau[i]
    observe(held, thd, M, h, dt, gain, 0.0, state)
    prev_tau[:] = tau
    r = state[3]
    for k in range(6):
        s = 0.0
        s2 = 0.0
        sb = 0.0
        for i in range(9):
            a = J[i, k]
            s += a * r[i]
            s2 += a * a * var[i]
            if abs(thd[i]) < v_band:
                sb += abs(a) * fc[i]
        w[k] = s
        std[k] = math.sqrt(s2)
        band[k] = sb


@njit(cache=True, error_model="numpy")
def envelope(tau_ff, ref, vref, kp, kd, theta, vel, spread, cap):
    """The drive's whole command tau_ff + Kp (ref - theta) + Kd (vref - v) kept within
    +-cap for every rate v the drive may use in [vel - spread, vel + spread]
    (:func:`~sixplus3.interaction.envelope.within_envelope`): tau_ff clipped to the
    cap, then the reference moved toward the measured angles (or, with Kp = 0, the rate
    reference toward the measured rate) where the PD, widened by Kd spread either way,
    would leave it.  Where Kd spread alone exceeds the cap, the PD cancels tau_ff (the
    least worst case: Kd spread).  In place; returns (the largest |total| asked before at
    the rate ``vel``, whether anything moved)."""
    wanted = 0.0
    moved = False
    for i in range(9):
        damp = kd[i] * (vref[i] - vel[i])
        pd = kp[i] * (ref[i] - theta[i]) + damp
        m = kd[i] * spread[i]  # what the drive's own rate may add, either way
        wanted = max(wanted, abs(tau_ff[i] + pd))
        if abs(tau_ff[i]) > cap:
            tau_ff[i] = min(max(tau_ff[i], -cap), cap)
            moved = True
        room = max(cap - m, 0.0)
        lo, hi = -room - tau_ff[i], room - tau_ff[i]
        if pd < lo or pd > hi:
            pd_c = min(max(pd, lo), hi)
            if kp[i] > 0.0:
                ref[i] = theta[i] + (pd_c - damp) / kp[i]
            elif kd[i] > 0.0:
                vref[i] = vel[i] + pd_c / kd[i]
            moved = True
    return wanted, moved


@njit(cache=True, error_model="numpy")
def native_state(model, theta, have, thd):
    """One sample of :class:`~sixplus3.interaction.observer.compiled_state.CompiledState` in one
    call, the generated C called by address (dynamics/native.py).  ``model``: the
    compiled state's buffers and settings (``CompiledState.native_args``): the pointers
    ``kin_ptrs`` on the buffers kx -> (kth, kjx), ``obs_ptrs`` on (ox, oxd) -> (., ojx,
    oq0, oqa, oc), the pose x, the LU's (lu, piv, step), the previous angles, Newton's
    (newton_max, tol), the drive's (armature, viscous, coulomb, speed) and the outputs
    (J, M, h, R).  x predicted from the previous sample (``have``), then Newton's steps
    (at most newton_max + 1 evaluations) to ``tol``, then the observer's state at (x,
    J_x^-1 thd) into J, M, h, R.  Returns (the largest angle error, the LU's info); the
    caller accepts the sample when info is 0 and the error below 1e-8."""
    (kin_ptrs, kx, kth, kjx, obs_ptrs, ox, oxd, ojx, oq0, oqa, oc, x, lu, piv, step,
     theta_prev, newton_max, tol, armature, viscous, coulomb, speed, J, M, h, R) = model
    if have:
        predict(x, lu, piv, theta, theta_prev, step)
    err, info = math.inf, 0
    for _ in range(newton_max + 1):
        kx[:] = x
        call_casadi(kin_ptrs[0], kin_ptrs[1], kin_ptrs[2], kin_ptrs[3], kin_ptrs[4])
        err, info = newton(x, kth, kjx, theta, lu, piv, step, tol)
        if err < tol or info != 0:
            break
    if info != 0 or err >= 1e-8:
        return err, info
    ox[:] = x
    lu_solve(lu, piv, thd, oxd)
    call_casadi(obs_ptrs[0], obs_ptrs[1], obs_ptrs[2], obs_ptrs[3], obs_ptrs[4])
    observer_state(lu, piv, (ojx, oq0, oqa, oc), x[3:6], thd,
                   (armature, viscous, coulomb, speed), (J, M, h, R))
    theta_prev[:] = theta
    return err, info


@njit(cache=True, error_model="numpy")
def stream_tick(theta, tau, filt, model, obs, n_sigma, out):
    """One sample of :class:`~sixplus3.interaction.observer.stream.WrenchStream` in one call,
    after its first (a previous sample and its x): the readings checked, the velocity
    filter (``filt``: prev_theta, rate, b, a, z and the rate's output thd),
    :func:`native_state` (``model``), the momentum observer (``obs``: prev_tau, the
    observer's state, gain, dt and (var, fc, v_band); ``out``: (w, std, band)).
    Returns 0 (no contact), 1 (a contact: a component of w beyond n_sigma std + band),
    -1 (a reading not finite: nothing changed), -2 (forward kinematics did not converge:
    the filter moved on, the observer did not; the caller starts again from the full
    forward kinematics)."""
    prev_theta, rate, b, a, z, thd = filt
    prev_tau, state, gain, dt, settings = obs
    w, std, band = out
    for i in range(9):
        if not (math.isfinite(theta[i]) and math.isfinite(tau[i])):
            return -1
    velocity(theta, prev_theta, True, rate, b, a, z, thd)
    err, info = native_state(model, theta, True, thd)
    if info != 0 or err >= 1e-8:
        return -2
    J, M, h = model[22], model[23], model[24]
    momentum(tau, thd, J, M, h, prev_tau, state, gain, dt, settings, out)
    prev_theta[:] = theta
    for k in range(6):
        if abs(w[k]) > n_sigma * std[k] + band[k]:
            return 1
    return 0
