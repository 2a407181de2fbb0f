"""Compile ahead of first use (issue 67): numba compiles each kernel into its cache the
first time it runs, and the observer's CasADi model is compiled to C once.  Before this,
the first ``wrench`` of a new install used 2.4x its log's length in CPU time, the first
``identify check`` 3.1x and the first ``LeadThrough`` took 121 s to build; the second
runs 0.85x, 0.67x and 0.3 s.  :func:`warm` runs each of those paths once on a small
log it makes (the robot at home, a few degrees of motion on every joint), so that
what a user runs next starts warm.  ``sixplus3 demo`` ends with it, and ``sixplus3
warmup`` runs it alone.  Nothing here is measured or kept: the numbers are not used."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

#: [m] and [rad] the small log's motion (its rates pass the identification's row filter)
AMP = 0.01


def _log(robot: Any, seconds: float = 1.2, rate: float = 1000.0) -> Any:
    """A small drive log: the platform moving by AMP [m] about home along each axis and
    the cranks by AMP [rad], the model's torques as the measured ones (nothing here is
    judged)."""
    from sixplus3.control.file.drive_log import DriveLog
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.kinematics.robot import robot_ik

    n = int(round(seconds * rate))
    t = np.arange(n) / rate
    wave = np.sin(2.0 * math.pi * np.outer(t, np.linspace(1.0, 3.0, 6)))
    pos = np.asarray(robot.home_position) + AMP * wave[:, 0:3]
    psi = np.asarray(robot.home_psi) + AMP * wave[:, 3:6]
    cfg = robot_ik(pos, np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), psi, robot,
                   platform_margins=False)
    theta = np.asarray(cfg.theta, dtype=float)
    thd = np.gradient(theta, 1.0 / rate, axis=0)
    thdd = np.gradient(thd, 1.0 / rate, axis=0)
    tau, _ = ClosedLoopDynamics(robot).actuated_inverse_dynamics_batch(cfg.q, thd, thdd)
    return DriveLog(t=t, theta=theta, tau=np.asarray(tau), name="warmup")


def warm(robot: Any, trajectory: str | Path | None = None,
         say: Callable[[str], None] = print) -> dict[str, float]:
    """Run once each path whose kernels compile on first use: the wrench estimator, the
    identification's check, the commissioning's directions, the streaming observer
    (compiled), lead-through, the drive's contact model (the gate's, for a site that
    declares its position loop), and with a ``trajectory`` file the contact guard.  Returns
    the seconds each took (a warm cache: well under a second each)."""
    from sixplus3.identification.commission import check_directions
    from sixplus3.identification.identify import check
    from sixplus3.interaction.lead.leadthrough import LeadThrough
    from sixplus3.interaction.observer.wrench import estimate

    secs: dict[str, float] = {}

    def step(name: str, fn: Callable[[], object]) -> None:
        say(f"  compiling for first use: {name} ...")
        t0 = time.perf_counter()
        fn()
        secs[name] = time.perf_counter() - t0

    log = _log(robot)
    step("the wrench estimator (sixplus3 wrench)", lambda: estimate(log, robot))
    step("the identification's check (identify check)", lambda: check(log, robot))
    step("the motors' directions (commission directions)",
         lambda: check_directions(robot, log))

    def lead() -> None:
        lt = LeadThrough(robot, 1000.0, drive_gains=(300.0, 6.0))
        for k in range(30):
            lt.step(log.theta[k], log.tau[k])

    step("lead-through and the streaming observer", lead)

    def drive_contact() -> None:
        from sixplus3.dynamics.drive_contact import DriveCase, contact_peaks
        from sixplus3.robot_description.hardware import PositionLoop

        one = np.ones((1, 9))
        case = DriveCase(np.eye(9)[None], 0.1 * one, np.ones(1), 0.0 * one,
                         np.full(9, 10.0), np.full(1, 0.6), np.full(1, 75e3), 0.0 * one)
        contact_peaks(case, PositionLoop(3000.0, 30.0), 1000.0, stop=0.01)

    step("the drive's contact model (a site's position_loop)", drive_contact)
    if trajectory is not None and Path(trajectory).is_file():
        from sixplus3.interaction.contact.guard import ContactGuard

        def guard() -> None:
            g = ContactGuard(robot, trajectory, drive_gains=(3000.0, 30.0))
            for k in range(30):
                k_ = min(k, g.n - 1)
                g.step(g.tables.theta[k_], g.tables.b[k_] + g.tables.g[k_])

        step("the contact guard", guard)
    return secs


__all__ = ["warm"]
