"""Record what the contact guard reads on the simulated prototype, for the fast tests of
its tick (tests/test_guard_tick.py: the guard replayed on these readings, no MuJoCo).

    .venv/bin/python scripts/record_tick_inputs.py   # writes tests/data/tick_*

A short move planned for a hand (its file, ``tests/data/tick_move.csv``), run in MuJoCo
on the default robot with the stiff drive (PD 3000 / 30) and the guard in the loop:
once with nobody in the way, once with a free hand met along the motion at the tool
centre point's fastest sample.  And lead-through (PD 300 / 6): a hand pulls the tool
point 4 cm along x and lets it rest.  Each run's readings, exactly as the controller
got them (the encoder's angles and the drives' torques, one row per tick), what it
commanded, and the tick of the first contact force go to
``tests/data/tick_readings.npz``.  Run it again after a change of the default robot
(the file records the robot it was planned for), or of a controller's arithmetic (the
tests replay the readings and compare the commands bit for bit).
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from sixplus3.control.drive.hand import hand_from_dict
from sixplus3.control.drive.person import contact_from_dict
from sixplus3.control.pipeline import run_plan
from sixplus3.interaction.contact.guard import ContactGuard
from sixplus3.interaction.people.hand import run_lead
from sixplus3.interaction.people.person import run_contact
from sixplus3.planner.task import task_from_dict
from sixplus3.robot_description.robot import Robot

OUT = Path(__file__).resolve().parent.parent / "tests" / "data"
DRIVE = (3000.0, 30.0)
TASK = {"name": "tick_move", "nodes_per_segment": 6, "pfl": ["hand"], "pfl_links": [],
        "waypoints": [{"position": [-0.04, 0.0, 0.58]}, {"position": [0.04, 0.0, 0.58]}]}


LEAD_DRIVE = (300.0, 6.0)
PULL = {"stiffness": 500.0, "damping": 10.0, "delay": 0.05, "duration": 0.8,
        "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 0.5, "offset": [0.04, 0, 0]}]}


def record(guard: ContactGuard, path: Path, robot: Robot, contact: object
           ) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
    """(theta (n, 9), tau (n, 9), the first tick with a contact force or -1, the
    commands' tau_ff (n, 9))."""
    seen: list[tuple[np.ndarray, np.ndarray]] = []
    sent: list[np.ndarray] = []
    step = guard.step

    def recording(theta: object, tau: object) -> object:
        seen.append((np.array(theta, dtype=float), np.array(tau, dtype=float)))
        cmd = step(theta, tau)
        sent.append(np.array(cmd.tau_ff))
        return cmd

    guard.step = recording  # type: ignore[method-assign]
    run = run_contact(path, robot, robot, contact, guard=guard, kp=DRIVE[0], kd=DRIVE[1],
                      after=0.15)
    guard.step = step  # type: ignore[method-assign]
    onset = -1 if run.onset is None else int(round(run.onset * 1000.0))
    return (np.array([s[0] for s in seen]), np.array([s[1] for s in seen]), onset,
            np.array(sent))


def main() -> None:
    robot = Robot.default()
    OUT.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as d:
        res = run_plan(task_from_dict(TASK), d, robot, html=False, plots=False)
        path = OUT / "tick_move.csv"
        shutil.copyfile(res.csv, path)
    guard = ContactGuard(robot, path, 1000.0, drive_gains=DRIVE)
    quiet = record(guard, path, robot, None)
    at = float(np.argmax(np.linalg.norm(guard.tables.theta_d, axis=1))) / 1000.0
    hand = contact_from_dict({"region": "hand", "kind": "free", "at": round(at, 3)})
    touch = record(guard, path, robot, hand)
    lead = run_lead(robot, robot, hand_from_dict(PULL), kp=LEAD_DRIVE[0], kd=LEAD_DRIVE[1])
    assert lead.log is not None
    np.savez_compressed(OUT / "tick_readings.npz", quiet_theta=quiet[0],
                        quiet_tau=quiet[1], quiet_ff=quiet[3], touch_theta=touch[0],
                        touch_tau=touch[1], touch_onset=touch[2], touch_ff=touch[3],
                        touch_at=at, kp=DRIVE[0], kd=DRIVE[1], lead_theta=lead.log.theta,
                        lead_tau=lead.log.tau, lead_ff=lead.tau_ff,
                        lead_rate=lead.rate_ref, lead_kp=LEAD_DRIVE[0],
                        lead_kd=LEAD_DRIVE[1],
                        lead_moved=float(np.linalg.norm(lead.tcp[-1] - lead.tcp[0])))
    print(f"wrote {path} and {OUT / 'tick_readings.npz'}: {len(quiet[0])} quiet ticks, "
          f"{len(touch[0])} ticks with a hand met at {at:.3f} s (force from tick "
          f"{touch[2]})")


if __name__ == "__main__":
    main()
