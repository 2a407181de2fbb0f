"""Lead-through on the virtual prototype (docs/leadthrough.md): a simulated hand guides the
platform through the drives, LeadThrough in the loop, on the nominal plant and on
perturbed plants the model was not tuned on.

Measured per plant (the model is the nominal robot; the plants' masses, rotors and
friction differ):

- rest: nobody touches the platform for ``--rest`` seconds: the drift [mm];
- breakaway: a soft hand's force ramps (its anchor moves at 1 cm/s): the force when the
  tool point has left its start by 0.5 mm [N];
- drag: the hand drags the platform at 0.1 m/s: the force [N] (the virtual damper's
  D v = 2 N plus the deadband);
- follow: a 3-segment path with pauses: the rms distance tool point - hand [mm];
- wall: a 25 N pull toward the workspace's edge along x: the reference's smallest slack
  (> -0.2: the gate's limits hold), the tool point's largest travel [mm], and the
  largest commanded joint acceleration and rate of change of the feed-forward (a wall
  met without a jerk);
- twist: a grip turns the platform 120 deg about x, cranks deciding and locked: the
  smallest singularity margin of the reference, the largest angle reached;
- cranks 60: the follow path from cranks at 60 deg (where a plan may leave them; the
  platform's margin 0.23 there, 0.34 at 90 deg), cranks deciding and locked: the
  reference's singularity margin at the end;
- stiff / soft: a stiff (3000 N/m) and a soft (150 N/m) hand move 5 cm and hold: the
  speed over the last 0.5 s (no sustained oscillation) and the least energy the hand put
  in (passivity: >= -0.5 J, the tank's initial energy);
- the peak torque asked of the drives over every run.

Tick cost: LeadThrough.step timed inside the drag run (median, p99); the drag run's drive
samples replayed through a fresh LeadThrough with the compiled observer state, then
through one with Pinocchio's (median, p99, with and without the ticks that update the
walls and cranks: the three stages of wall_update.py, ticks 0-2 of every 10); and a 1 kHz
Python loop replaying them, sleeping to each 1 ms deadline: its lateness (median, p99,
max).

    python benchmarks/bench_leadthrough.py                 # nominal + plants 41, 57
    python benchmarks/bench_leadthrough.py --plants 41 --rest 2   # quicker
    python benchmarks/bench_leadthrough.py --model identified41.yaml --plants 41 --no-nominal \
        --no-walls
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from sixplus3.control.drive.hand import hand_from_dict
from sixplus3.identification.plants import perturbed_plant
from sixplus3.interaction.lead.leadthrough import LeadThrough
from sixplus3.interaction.people.hand import run_lead
from sixplus3.kinematics.robot import robot_ik, robot_ik_pose
from sixplus3.robot_description.robot import Robot, load_robot

KP, KD = 300.0, 6.0


FOLLOW = {"stiffness": 600.0, "damping": 15.0, "delay": 0.15, "duration": 6.0,
          "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 1.5, "offset": [0.08, 0, 0]},
                   {"t": 2.3, "offset": [0.08, 0, 0]},
                   {"t": 3.8, "offset": [0.08, 0.08, 0.03]},
                   {"t": 4.6, "offset": [0.08, 0.08, 0.03]},
                   {"t": 5.5, "offset": [0, 0, 0]}]}


def hands(rest: float) -> dict[str, dict]:
    return {
        "rest": {"stiffness": 0.0, "damping": 0.0, "duration": rest},
        "breakaway": {"stiffness": 200.0, "damping": 2.0, "delay": 0.0, "duration": 1.5,
                      "path": [{"t": 0.0, "offset": [0, 0, 0]},
                               {"t": 1.5, "offset": [0.015, 0, 0]}]},
        "drag": {"stiffness": 500.0, "damping": 10.0, "delay": 0.15, "duration": 2.5,
                 "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 0.2, "offset": [0, 0, 0]},
                          {"t": 2.2, "offset": [0.2, 0, 0]}]},
        "follow": FOLLOW,
        "wall": {"stiffness": 1000.0, "damping": 20.0, "max_force": 25.0, "duration": 5.0,
                 "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 3.5, "offset": [0.4, 0, 0]}]},
        "twist": {"stiffness": 300.0, "damping": 10.0, "stiffness_rot": 5.0,
                  "damping_rot": 0.3, "max_torque": 3.0, "max_force": 25.0, "duration": 8.0,
                  "path": [{"t": 0.0, "offset": [0, 0, 0]},
                           {"t": 6.0, "offset": [0, 0, 0], "rotation": [2.094, 0, 0]}]},
        "cranks60": FOLLOW,  # the same hand, from cranks at 60 deg
        "stiff": {"stiffness": 3000.0, "damping": 40.0, "delay": 0.15, "duration": 3.0,
                  "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 1.0, "offset": [0, 0.05, 0]}]},
        "soft": {"stiffness": 150.0, "damping": 3.0, "delay": 0.15, "duration": 3.0,
                 "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": 1.0, "offset": [0, 0.05, 0]}]},
    }


WALLS = {
    "+x, 25 N over 3.5 s": [0.4, 0, 0, 3.5], "+x, 25 N over 1 s": [0.4, 0, 0, 1.0],
    "up (+z), 25 N over 1 s": [0, 0, 0.3, 1.0], "-y, 25 N over 1 s": [0, -0.4, 0, 1.0]}


def wall_table(model: Robot) -> None:
    """A hand pulls 25 N toward the workspace's edge in four ways, on the nominal plant
    with the soft drive (Kp 300) and a stiff one (Kp 3000): the reference's least slack
    (> -0.2: the gate's limits hold) and singularity margin, the tool point's travel, the
    largest commanded joint acceleration and feed-forward rate (a jerk), the peak torque
    asked, and what the lead-through said."""
    print("\n| wall hand | drive | least slack | least margin | tool travel [mm] | max ref. "
          "acc. [rad/s^2] | max dtau_ff/dt [N m/s] | peak torque asked [N m] | events |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, (x, y, z, t) in WALLS.items():
        doc = {"stiffness": 1000.0, "damping": 20.0, "max_force": 25.0, "duration": t + 2.0,
               "path": [{"t": 0.0, "offset": [0, 0, 0]}, {"t": t, "offset": [x, y, z]}]}
        for drive, (kp, kd) in (("soft", (KP, KD)), ("stiff", (3000.0, 30.0))):
            lt = LeadThrough(model, 1000.0, drive_gains=(kp, kd))
            run = run_lead(model, Robot.default(), hand_from_dict(doc), lead=lt, kp=kp, kd=kd)
            acc, dff = run.smoothness()
            travel = 1e3 * float(np.linalg.norm(run.tcp - run.tcp[0], axis=1).max())
            ev = f"{len(run.events)} held ticks" if run.events else "-"
            print(f"| {name} | {drive} | {lt.min_slack:.3f} | {lt.min_margin:.3f} | "
                  f"{travel:.0f} | {acc:.0f} | {dff:.0f} | {run.peak_command:.2f} | {ev} |",
                  flush=True)


def timed(lt: LeadThrough) -> list[float]:
    """Wrap ``lt.step`` to record each call's wall time [s]."""
    times: list[float] = []
    inner = lt.step

    def step(theta, tau):  # type: ignore[no-untyped-def]
        t0 = time.perf_counter()
        out = inner(theta, tau)
        times.append(time.perf_counter() - t0)
        return out

    lt.step = step  # type: ignore[method-assign]
    return times


def replay_cost(model: Robot, theta: np.ndarray, tau: np.ndarray) -> dict[str, np.ndarray]:
    """Per-step wall times [s] of a fresh LeadThrough replaying (theta, tau), with the
    compiled observer state and then with Pinocchio's, each alone over the whole replay
    (a loop runs one controller: stepping two in turn evicts each other's caches, which
    measured the switches more than the ticks)."""
    out = {}
    for name, compiled in (("compiled", True), ("pinocchio", False)):
        lt = LeadThrough(model, 1000.0, drive_gains=(KP, KD), compiled=compiled)
        ts = np.empty(len(theta))
        for k in range(len(theta)):
            t0 = time.perf_counter()
            lt.step(theta[k], tau[k])
            ts[k] = time.perf_counter() - t0
        out[name] = ts
    return out


def loop_jitter(model: Robot, theta: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Lateness [s] of each tick of a 1 kHz loop replaying (theta, tau) through a fresh
    LeadThrough, sleeping to each deadline."""
    lt = LeadThrough(model, 1000.0, drive_gains=(KP, KD))
    late = np.empty(len(theta))
    t_next = time.perf_counter()
    for k in range(len(theta)):
        t_next += 1e-3
        lt.step(theta[k], tau[k])
        now = time.perf_counter()
        late[k] = max(0.0, now - t_next)
        if now < t_next:
            time.sleep(max(0.0, t_next - now - 2e-4))
            while time.perf_counter() < t_next:
                pass
        else:
            t_next = now  # a missed deadline: the next one from here
    return late


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--plants", default="41,57",
                    help="perturbed plants' seeds (mass and rotors +-10 %%, friction x1.3)")
    ap.add_argument("--rest", type=float, default=10.0, help="the rest run's length [s]")
    ap.add_argument("--no-nominal", action="store_true", help="skip the nominal plant")
    ap.add_argument("--no-walls", action="store_true", help="skip the walls' table")
    ap.add_argument("--model", default=None,
                    help="the robot file LeadThrough runs on (default: the nominal robot), "
                         "e.g. one identified on a plant (sixplus3 identify estimate)")
    a = ap.parse_args()
    model = Robot.default() if a.model is None else load_robot(a.model)
    start60 = robot_ik_pose(model.home_position, (0, 0, 0), [math.radians(60)] * 3,
                            robot=model).q[0]
    nominal = Robot.default()
    plants = [] if a.no_nominal else [("nominal", nominal)]
    plants += [(f"seed {s}", perturbed_plant(nominal, int(s), mass=0.1, rotor=0.1,
                                             friction=1.3))
               for s in a.plants.split(",") if s]
    print("| plant | drift at rest [mm] | breakaway [N] | force at 0.1 m/s [N] | follow rms "
          "[mm] | wall: slack, travel [mm], max ref. acc. [rad/s^2], max dtau_ff/dt [N m/s] "
          "| twist margin cranks / locked | twist angle "
          "cranks / locked [deg] | cranks 60: end margin cranks / locked | stiff: last "
          "speed [mm/s], energy [J] | soft: last speed, energy | peak torque [N m] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    step_times: list[float] = []
    replay = None
    t_all = time.time()
    for name, plant in plants:
        res = {}
        peak = 0.0
        for case, doc in hands(a.rest).items():
            for gain in ((2.0, 0.0) if case in ("twist", "cranks60") else (2.0,)):
                lt = LeadThrough(model, 1000.0, drive_gains=(KP, KD), crank_gain=gain)
                times = timed(lt) if (case == "drag" and not step_times) else None
                start = start60 if case == "cranks60" else None
                run = run_lead(model, plant, hand_from_dict(doc), lead=lt, kp=KP, kd=KD,
                               start=start)
                if case == "cranks60":
                    end = robot_ik(lt.st.p_ref, lt.st.R_ref, lt.st.psi_ref, model)
                    lt.min_margin = float(end.margins.minimum[0])  # the end's margin
                if times is not None:
                    step_times = times[1:]
                    assert run.log is not None
                    replay = (run.log.theta, run.log.tau)
                res[(case, gain)] = (lt, run)
                peak = max(peak, run.peak_command)
        rest = res[("rest", 2.0)][1]
        br = res[("breakaway", 2.0)][1].breakaway()
        dr = res[("drag", 2.0)][1].force_at_speed(0.1)
        fo = res[("follow", 2.0)][1].summary()["rms_lag_m"]
        wl, wr = res[("wall", 2.0)]
        tc, tr = res[("twist", 2.0)], res[("twist", 0.0)]
        c6, c6l = res[("cranks60", 2.0)][0], res[("cranks60", 0.0)][0]
        st, so = res[("stiff", 2.0)][1], res[("soft", 2.0)][1]

        def last(run) -> float:  # type: ignore[no-untyped-def]
            return 1e3 * float(run.speed[run.t > run.t[-1] - 0.5].max())

        def fmt(v: float | None) -> str:
            return "-" if v is None else f"{v:.2f}"

        travel = 1e3 * float(np.abs(wr.tcp[:, 0] - wr.tcp[0, 0]).max())
        w_acc, w_dff = wr.smoothness()
        print(f"| {name} | {1e3 * rest.drift():.3f} | {fmt(br)} | {fmt(dr)} | {1e3 * fo:.1f} "
              f"| {wl.min_slack:.3f}, {travel:.0f}, {w_acc:.1f}, {w_dff:.0f} | "
              f"{tc[0].min_margin:.3f} / "
              f"{tr[0].min_margin:.3f} | {tc[1].angle.max() * 57.2958:.1f} / "
              f"{tr[1].angle.max() * 57.2958:.1f} | {c6.min_margin:.3f} / "
              f"{c6l.min_margin:.3f} | {last(st):.2f}, "
              f"{st.port_energy_min:.3f} | {last(so):.2f}, {so.port_energy_min:.3f} "
              f"| {peak:.2f} |", flush=True)
    st_us = 1e6 * np.asarray(step_times)
    print(f"\nLeadThrough.step in the drag run ({len(st_us)} ticks): median "
          f"{np.median(st_us):.0f} us, p99 {np.percentile(st_us, 99):.0f} us, max "
          f"{st_us.max():.0f} us")
    if replay is not None:
        for name, ts in replay_cost(model, *replay).items():
            us = 1e6 * ts[10:]
            # the walls' and cranks' update (interaction/lead/wall_update.py): its first stage
            # every 10th tick, the middle one the tick after, the near walls' gradients
            # (if any) the tick after that
            slow = np.arange(10, len(ts)) % 10 <= 2
            print(f"replayed, {name} observer state: median {np.median(us):.0f} us, p99 "
                  f"{np.percentile(us, 99):.0f} us; without the walls' update (3 in 10 ticks): "
                  f"median {np.median(us[~slow]):.0f} us, p99 "
                  f"{np.percentile(us[~slow], 99):.0f} us; the update ticks: median "
                  f"{np.median(us[slow]):.0f} us")
        late = 1e6 * loop_jitter(model, *replay)
        print(f"1 kHz Python loop replaying it ({len(late)} ticks): lateness median "
              f"{np.median(late):.0f} us, p99 {np.percentile(late, 99):.0f} us, max "
              f"{late.max():.0f} us; deadlines missed {int((late > 0).sum())}")
    if not a.no_walls:
        wall_table(model)
    print(f"\n{time.time() - t_all:.0f} s in all")


if __name__ == "__main__":
    main()
