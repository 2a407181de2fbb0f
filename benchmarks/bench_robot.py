"""Whole-robot kinematics and dynamics: microseconds per call.

    .venv/bin/python benchmarks/bench_robot.py [--repeat R]

Also times a 5 s trajectory at 1 kHz (5000 samples): batched IK of the platform poses,
then the batched constrained inverse dynamics of the moving robot at every sample (the
validator's form; the command itself is timed by bench_validate.py).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
from sixplus3.kinematics.robot import home, robot_ik, robot_ik_pose
from sixplus3.kinematics.robot_fk import robot_fk
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()


def per_call(fn, n: int, repeat: int) -> tuple[float, float]:
    fn()
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        ts.append((time.perf_counter() - t) / n * 1e6)
    return min(ts), statistics.median(ts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    dyn = ClosedLoopDynamics(ROBOT)
    h = home(ROBOT)
    q = h.q[0]
    rng = np.random.default_rng(0)
    v, a = dyn.consistent_state(q, rng.normal(size=9), rng.normal(size=9))
    tau = dyn.inverse_dynamics(q, v, a)
    rows = [
        ("robot IK, one pose (robot_ik_pose)",
         lambda: robot_ik_pose((0.02, 0.01, 0.59), (0.1, 0.2, 0.3), robot=ROBOT), 200),
        ("robot FK, Newton from the previous sample",
         lambda: robot_fk(h.theta[0] + 1e-3, q_hint=q, robot=ROBOT), 50),
        ("constrained inverse dynamics", lambda: dyn.inverse_dynamics(q, v, a), 500),
        ("constrained forward dynamics (constraintDynamics)",
         lambda: dyn.forward_dynamics(q, v, tau), 500),
        ("simulation step, RK4 + projection", lambda: dyn.step(q, v, tau, 1e-3), 200),
        ("simulation step, semi-implicit Euler, no projection",
         lambda: dyn.step(q, v, tau, 1e-3, method="euler", project=False), 500),
    ]
    print(f"{'operation':52s} {'best us':>9s} {'median':>9s}")
    for name, fn, n in rows:
        best, med = per_call(fn, n, args.repeat)
        print(f"{name:52s} {best:9.1f} {med:9.1f}")

    # A 5 s trajectory at 1 kHz: circle + tilt, redundancy varying.
    n = 5000
    t = np.linspace(0, 5, n)
    pos = np.c_[0.05 * np.cos(t), 0.05 * np.sin(t), 0.30 + 0.03 * np.sin(2 * t)]
    rot = Rotation.from_euler("xyz", np.c_[0.3 * np.sin(t), 0.2 * np.cos(t), 0.4 * np.sin(t)])
    psi = np.pi / 2 + 0.3 * np.c_[np.sin(t), np.sin(t + 2), np.sin(t + 4)]
    best = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        cfg = robot_ik(pos, rot.as_matrix(), psi, robot=ROBOT)
        t1 = time.perf_counter()
        th_d = np.gradient(cfg.theta, t, axis=0)
        th_dd = np.gradient(th_d, t, axis=0)
        tau_b, _ = dyn.actuated_inverse_dynamics_batch(cfg.q, th_d, th_dd)
        t2 = time.perf_counter()
        best.append((t1 - t0, t2 - t1))
    ik_s, id_s = min(best, key=sum)
    assert cfg.ok.all() and np.isfinite(tau_b).all()
    print(f"5 s trajectory at 1 kHz: batched IK {ik_s * 1e3:.0f} ms + batched constrained "
          f"inverse dynamics, moving (the validator's) {id_s * 1e3:.0f} ms "
          f"({1e6 * id_s / n:.0f} us per state) = {(ik_s + id_s):.2f} s "
          f"(best of {args.repeat})")


if __name__ == "__main__":
    main()
