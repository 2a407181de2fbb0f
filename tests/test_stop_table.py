"""The stop table's deceleration where no stop is within the torque share
(control/gate/stop.py): the one that needs the least torque, at full path speed and at
rest alike (session 32: a re-timed plan's reversal found the former rule asking
10.3 N m at rest where 8.8 N m was enough)."""

from __future__ import annotations

import numpy as np

from sixplus3.control.gate.stop import BETA_RANGE, least_torque_beta, path_deceleration


def _worst(beta: np.ndarray, a: np.ndarray, cs: tuple[np.ndarray, ...]) -> np.ndarray:
    return np.max([np.abs(c - beta[:, None] * a).max(axis=1) for c in cs], axis=0)


def test_the_least_torque_deceleration_is_the_minimax() -> None:
    """Against a brute-force search over 200,000 decelerations in [1, 1e6] /s."""
    rng = np.random.default_rng(11)
    n = 40
    a = rng.normal(0.0, 0.05, (n, 9))
    cs = (rng.normal(0.0, 12.0, (n, 9)), rng.normal(0.0, 2.0, (n, 9)))
    got = least_torque_beta(a, cs)
    assert np.all((got >= BETA_RANGE[0]) & (got <= BETA_RANGE[1]))
    grid = np.geomspace(*BETA_RANGE, 200_000)
    brute = np.min([_worst(np.full(n, b), a, cs) for b in grid], axis=0)
    mine = _worst(got, a, cs)
    assert np.all(mine <= brute + 1e-9)
    assert np.all(mine >= brute - 1e-3)  # the grid is fine enough to come this close


def test_where_no_stop_is_within_the_share_the_table_takes_the_least_torque() -> None:
    """One joint needs beta in [11.45, 28.55] at full speed and in [-28.55, -11.45] at
    rest (cap 8.55 N m): no deceleration holds both.  The former rule took the larger
    lower bound, 11.45 /s, asking 31.45 N m at rest; the least torque over both ends is
    at the table's slowest stop, 1 /s: 21 N m."""
    a = np.zeros((2, 9))
    a[:, 0] = 1.0
    g = np.zeros((2, 9))
    g[:, 0] = -20.0
    b = np.zeros((2, 9))
    b[:, 0] = 40.0  # b + g = 20 at full path speed
    b[1, 0] = 9.0  # the second: b + g = -11, within the share only for beta < 0
    theta_dot = np.full((2, 9), 0.1)
    beta = path_deceleration(a, b, g, theta_dot, torque=9.0, acceleration=200.0)
    cs = (b + g, g)
    np.testing.assert_allclose(beta, [1.0, 1.0], rtol=1e-9)
    np.testing.assert_allclose(_worst(beta, a, cs), [21.0, 21.0], rtol=1e-9)
    # a sample with decelerations within the share keeps the fastest of them: b + g = 5
    # allows [-3.55, 13.55], g = 0 at rest [-8.55, 8.55]
    ok_b = np.zeros((1, 9))
    ok_b[0, 0] = 5.0
    beta_ok = path_deceleration(a[:1], ok_b, np.zeros((1, 9)), theta_dot[:1], torque=9.0,
                                acceleration=200.0)
    np.testing.assert_allclose(beta_ok, [0.95 * 9.0], rtol=1e-12)
