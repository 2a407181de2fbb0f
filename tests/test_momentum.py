"""Issue 68, item 2: one momentum observer (interaction/observer/momentum.py) for the batch
estimator, the stream, the contact guard and lead-through, checked on the same log."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from sixplus3.errors import InputError
from sixplus3.interaction.observer._tick_kernel import momentum
from sixplus3.interaction.observer.momentum import MomentumObserver, momentum_observer

ROOT = Path(__file__).resolve().parents[1]
GAIN = 150.0


def _log(n: int = 60, seed: int = 0) -> tuple[np.ndarray, ...]:
    """A log's (t, tau, theta_dot, M, h): uneven ticks, SPD inertias that change."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.8e-3, 1.2e-3, n))
    a = rng.normal(size=(n, 9, 9)) * 0.05
    M = np.einsum("nij,nkj->nik", a, a) + 0.03 * np.eye(9)
    return t, rng.normal(size=(n, 9)), rng.normal(size=(n, 9)), M, rng.normal(size=(n, 9))


def test_the_batch_is_the_observer_stepped_sample_by_sample() -> None:
    t, tau, thd, M, h = _log()
    for lag in (0.0, 0.5):
        batch = momentum_observer(t, tau, thd, M, h, GAIN, lag)
        obs = MomentumObserver(GAIN, lag)
        stepped = np.array([obs.step(tau[k], thd[k], M[k], h[k],
                                     t[k] - t[k - 1] if k else 1.0).copy()
                            for k in range(len(t))])
        np.testing.assert_array_equal(batch, stepped)
        np.testing.assert_array_equal(batch[0], np.zeros(9))  # nothing integrated yet
        obs.reset()
        assert not obs.started and not obs.r.any()


def test_the_stream_runs_the_same_observer_on_its_held_torque() -> None:
    """The stream's kernel (interaction/observer/stream.py) holds the torque over a tick as the
    mean of its two readings, then observes: the batch fed those torques gives its
    residuals bit for bit."""
    t, tau, thd, M, h = _log(seed=1)
    dt = 2.0 ** -10  # ticks whose differences are exact: the batch's dt is the stream's
    t = np.arange(len(t)) * dt
    obs = MomentumObserver(GAIN)
    prev_tau = np.zeros(9)
    J = np.eye(9)
    settings = (np.full(9, 1e-4), np.zeros(9), 0.0)
    out = (np.empty(6), np.empty(6), np.empty(6))
    rs = []
    for k in range(len(t)):
        momentum(tau[k], thd[k], J, M[k], h[k], prev_tau, obs.state, GAIN, dt, settings, out)
        rs.append(obs.r.copy())
        np.testing.assert_array_equal(out[0], obs.r[:6])  # J = I: the wrench is r
    held = np.vstack([tau[:1], 0.5 * (tau[1:] + tau[:-1])])
    np.testing.assert_array_equal(np.array(rs), momentum_observer(t, held, thd, M, h, GAIN))


def test_the_guard_runs_the_same_observer() -> None:
    """The contact guard's residuals, tick by tick on a recorded run, are the batch
    observer's on the guard's own inputs (the encoder's difference, lag 1/2)."""
    from sixplus3.interaction.contact.guard import ContactGuard
    from sixplus3.robot_description.robot import Robot

    data = np.load(ROOT / "tests" / "data" / "tick_readings.npz")
    g = ContactGuard(Robot.default(), ROOT / "tests" / "data" / "tick_move.csv", 1000.0,
                     drive_gains=(3000.0, 30.0))
    fed: list[tuple[np.ndarray, ...]] = []
    got: list[np.ndarray] = []
    for th, ta in zip(data["touch_theta"], data["touch_tau"], strict=True):
        obs = g.st.observer
        real = obs.step

        def spy(*a: object, real: object = real) -> np.ndarray:
            fed.append(tuple(np.array(x, dtype=float) for x in a))
            r = real(*a)  # type: ignore[operator]
            got.append(r.copy())
            return r

        obs.step = spy  # type: ignore[method-assign]
        g.step(th, ta)
        obs.step = real  # type: ignore[method-assign]
    assert len(fed) > 50 and any(np.abs(r).max() > 1.0 for r in got)  # it saw the touch
    tau, thd, M, h, dt = (np.array([f[i] for f in fed]) for i in range(5))
    t = np.concatenate([[0.0], np.cumsum(dt[1:])])
    np.testing.assert_allclose(t[1:] - t[:-1], dt[1:], rtol=1e-9)
    batch = momentum_observer(t, tau, thd, M, h, g.gain, 0.5)
    np.testing.assert_allclose(np.array(got), batch, rtol=1e-9, atol=1e-9)


def test_lead_through_reads_the_stream_s_observer() -> None:
    from sixplus3.interaction.lead.leadthrough import LeadThrough
    from sixplus3.robot_description.robot import Robot

    lt = LeadThrough(Robot.default(), 1000.0)
    assert isinstance(lt.stream.observer, MomentumObserver)


def test_the_observer_s_settings_are_checked() -> None:
    with pytest.raises(InputError, match="gain"):
        MomentumObserver(float("nan"))
    with pytest.raises(InputError, match="lag"):
        MomentumObserver(10.0, lag=2.0)


def test_there_is_one_observer() -> None:
    """A second observer fails here: the integral of the momentum's balance is taken in
    one kernel (interaction/observer/_tick_kernel.observe) and nowhere else in the library."""
    folders = ["sixplus3", "robot_description", "kinematics", "dynamics", "planner",
               "control", "design", "visualization", "identification", "interaction"]
    found = set()
    for folder in folders:
        for path in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.AugAssign) and "integral" in ast.unparse(node.target):
                    found.add(str(path.relative_to(ROOT)))
    assert found == {"interaction/observer/_tick_kernel.py"}
    kernel = ast.parse((ROOT / "interaction" / "observer" / "_tick_kernel.py").read_text())
    owners = {f.name for f in ast.walk(kernel) if isinstance(f, ast.FunctionDef)
              and any(isinstance(n, ast.AugAssign) and "integral" in ast.unparse(n.target)
                      for n in ast.walk(f))}
    assert owners == {"observe"}
