"""The per-tick kernels (interaction/_tick_kernel.py) against independent derivations:
the 9 x 9 LU against LAPACK's (scipy) and the envelope against its closed form.  The
observer's state built on them is checked against Pinocchio's in
tests/test_leadthrough.py."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import lu_factor as scipy_lu_factor
from scipy.linalg import lu_solve as scipy_lu_solve

from sixplus3.interaction._tick_kernel import envelope, lu_factor, lu_solve, lu_solve_t


@pytest.mark.parametrize("seed", range(5))
def test_lu_solves_agree_with_lapack(seed: int) -> None:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(9, 9)) * np.logspace(0, 3, 9)  # badly scaled columns
    b = rng.normal(size=9)
    lu, piv = np.empty((9, 9)), np.empty(9, dtype=np.int64)
    assert lu_factor(A, lu, piv) == 0
    ref = scipy_lu_factor(A)
    out = np.empty(9)
    lu_solve(lu, piv, b, out)
    np.testing.assert_allclose(out, scipy_lu_solve(ref, b), rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(A @ out, b, atol=1e-10)
    lu_solve_t(lu, piv, b, out)
    np.testing.assert_allclose(out, scipy_lu_solve(ref, b, trans=1), rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(A.T @ out, b, atol=1e-10)


def test_a_singular_matrix_is_reported() -> None:
    A = np.eye(9)
    A[4] = A[2]
    lu, piv = np.empty((9, 9)), np.empty(9, dtype=np.int64)
    assert lu_factor(A, lu, piv) != 0


def test_the_envelope_is_the_closed_form() -> None:
    """Each joint's total tau_ff + PD within +-cap after the move, unchanged where it
    was, and the reference moved exactly to the cap's edge where it was not (Kp > 0:
    the angle; Kp = 0 < Kd: the rate)."""
    rng = np.random.default_rng(3)
    cap = 9.7
    for _ in range(200):
        ff = rng.uniform(-12, 12, 9)
        ref, vref = rng.normal(0, 0.02, 9), rng.normal(0, 1.0, 9)
        theta, vel = rng.normal(0, 0.02, 9), rng.normal(0, 1.0, 9)
        kp = np.where(rng.random(9) < 0.3, 0.0, rng.uniform(100, 3000, 9))
        kd = rng.uniform(1, 30, 9)
        f2, r2, v2 = ff.copy(), ref.copy(), vref.copy()
        wanted, moved = envelope(f2, r2, v2, kp, kd, theta, vel, cap)
        pd0 = kp * (ref - theta) + kd * (vref - vel)
        assert wanted == pytest.approx(np.abs(ff + pd0).max())
        np.testing.assert_array_equal(f2, np.clip(ff, -cap, cap))
        total = f2 + kp * (r2 - theta) + kd * (v2 - vel)
        assert np.all(np.abs(total) <= cap + 1e-9)
        inside = np.abs(f2 + pd0) <= cap
        np.testing.assert_array_equal(r2[inside], ref[inside])
        np.testing.assert_array_equal(v2[inside], vref[inside])
        out = ~inside
        np.testing.assert_allclose(np.abs(total[out]), cap, rtol=1e-9)
        assert moved == bool(out.any() or np.any(np.abs(ff) > cap))
