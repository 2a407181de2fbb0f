"""Where every plan's torque goes, and how the durations change with each limit
(BENCHMARKS.md, "Where the torque goes"; docs/planner.md, "Platform-space limits").

    python benchmarks/bench_tcp_limits.py [--examples translate combined ...]

For every example on the default robot: the minimum-time duration with the robot's
limits, then with the joint acceleration limit halved (100 rad/s^2), with a tool centre
point speed of 0.25 m/s, with a TCP acceleration of 2 g, and with both TCP limits; and,
on the default plan, the torque at its peak sample split into the rotors' share
(armature x theta_ddot) and the rest (links, gravity, friction).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from sixplus3 import examples
from sixplus3.planner.problem import Problem
from sixplus3.planner.solution import actuated_profile
from sixplus3.planner.strategy import solve
from sixplus3.robot_description.robot import Robot

CASES = (("robot's limits", {}), ("acceleration 100 rad/s^2", {"acceleration": 100.0}),
         ("tcp 0.25 m/s", {"tcp_speed": 0.25}), ("tcp 2 g", {"tcp_acceleration": 19.62}),
         ("tcp 0.25 m/s and 2 g", {"tcp_speed": 0.25, "tcp_acceleration": 19.62}))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--examples", nargs="*", default=None)
    names = ap.parse_args().examples or examples.names()
    robot = Robot.default()
    print("| example | " + " | ".join(c for c, _ in CASES)
          + " | peak |tau| [N m] | rotors' share at that sample |")
    print("| --- |" + " ---: |" * (len(CASES) + 2))
    for name in names:
        base = examples.load(name)
        row, first = [], None
        for _, lim in CASES:
            task = dataclasses.replace(base, limits={**base.limits, **lim})
            sol = solve(Problem(task, robot))
            ok = sol.check is not None and sol.check.ok
            row.append(f"{sol.final_time:.4f}" + ("" if ok else " (check failed)"))
            first = first or sol
        r = first.robot
        times = np.linspace(0.0, first.t[-1], (len(first.t) - 1) * 10 + 1)
        x, xd, xdd = first.sample(times)
        thd, thdd, tau, _ = (v.T for v in actuated_profile(r, x, xd, xdd))
        k, j = np.unravel_index(np.argmax(np.abs(tau)), tau.shape)
        rotor = r.motors.armature * thdd[k, j]
        print(f"| {name} | " + " | ".join(row)
              + f" | {abs(tau[k, j]):.2f} | {abs(rotor):.2f} N m "
                f"({100 * abs(rotor) / abs(tau[k, j]):.0f} %) |", flush=True)


if __name__ == "__main__":
    main()
