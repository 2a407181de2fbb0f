"""The ``sixplus3`` commands that read a trajectory file: validate, export, feed and
play (``simulate``: :mod:`~sixplus3.cli.simulate`)."""

from __future__ import annotations

import json
import math
import os
import sys

import click

from sixplus3.cli.app import (
    FLOAT,
    check_output,
    current_robot,
    drive_gains,
    emit,
    fail,
    json_default,
    main,
    request_fast_exit,
    task_robot,
)
from sixplus3.cli.names import EXPORT_FORMATS


@main.command()
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--task", "task_file", default=None, type=click.Path(dir_okay=False),
              help="Apply this task file's setup (payload, tool, mounting) to the robot.")
@click.option("--simulate", "with_sim", is_flag=True,
              help="Also check in MuJoCo: its inverse dynamics against the file's torques, "
                   "and feed-forward + PD replay against the torque limit.")
@drive_gains
def validate(csv_file: str, as_json: bool, task_file: str | None, with_sim: bool,
             kp: float, kd: float) -> None:
    """Check a trajectory file independently of the planner (exit 0 only if all ok).

    Every check of docs/validation.md, against the robot's hardware limits, tightened by
    the limits the file records (a header can only make the gate stricter; a looser one
    is a forged file).  Exit codes: 0 a valid motion; 1 a limit is violated; 2 the file is missing,
    corrupted, made for another robot, or not a consistent motion (time grid, rest at
    the ends, jumps, platform columns, feed-forward torques).
    """
    # numba's OpenMP threads sleep between the forward kinematics' parallel loops instead
    # of spinning on the core the dynamics worker needs (0.95 -> 0.86 s, BENCHMARKS.md).
    # Read once, when numba first starts its threads: that is later, in validate_file.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    from sixplus3.control.gate.validation import validate_file, validation_record

    robot = task_robot(task_file)
    task_limits = None
    if task_file is not None:  # the task's own limits: a planning choice checked here
        from sixplus3.planner.task import load_task
        from sixplus3.robot_description.hardware import effective_limits

        task_limits = effective_limits(robot).tightened(**load_task(task_file).limits)
    rep = validate_file(csv_file, robot, limits=task_limits)
    from sixplus3.robot_description.limits import Limits

    limits = Limits(**rep.limits) if rep.limits else robot.limits
    out = validation_record(csv_file, rep)
    envelope = out["envelope"]
    code = rep.exit_code
    eng = None
    if with_sim and code != 2:
        from sixplus3.control.drive.simulation import engine_check

        eng = engine_check(robot, rep, kp, kd)
        out["mujoco"] = eng.summary()
        code = 2 if 2 in (code, eng.exit_code) else max(code, eng.exit_code)
    if as_json:
        click.echo(json.dumps(out, default=json_default))
    else:
        verdict = {0: "OK", 1: "LIMIT VIOLATED", 2: "NOT A VALID MOTION"}[rep.exit_code]
        click.echo(f"{csv_file}: {rep.samples} samples + "
                   f"{max(0, rep.checked_points - rep.samples)} midpoints checked, "
                   f"{rep.duration or 0.0:.4f} s; max |tau| "
                   f"{rep.max_torque_ratio * limits.torque:.3f} N m (limit "
                   f"{limits.torque:g}); margins {rep.min_margin_leg_type1:.3f} / "
                   f"{rep.min_margin_leg_type2:.3f} / {rep.min_margin_platform:.3f} "
                   f"(>= {limits.margin:g}); {verdict}")
        if rep.max_torque_rate is not None:
            click.echo(f"  torque rate between samples: max {rep.max_torque_rate:.0f} N m/s "
                       f"(reported, not a gate limit: the planner bounds it at "
                       f"{limits.torque_rate:g} N m/s between its own nodes)")
        from sixplus3.control.file.trajectory_file import REPORTED_ONLY
        from sixplus3.robot_description.limits import TCP_ACCELERATION_NONE, TCP_SPEED_NONE

        none = {"tcp_speed": TCP_SPEED_NONE, "tcp_acceleration": TCP_ACCELERATION_NONE}
        lim_txt = ", ".join(f"{k} {'none' if v >= none.get(k, float('inf')) else f'{v:.6g}'}"
                            for k, v in limits.as_dict().items() if k not in REPORTED_ONLY)
        click.echo(f"  judged by robot {robot.hash[:12]} at {rep.rate_hz:g} Hz, its hardware "
                   f"limits tightened by the site's and the file's: {lim_txt}")
        click.echo(f"  envelope: {envelope['drive_train']} from the {envelope['origin']}")
        if rep.pfl:  # power and force limiting (docs/safety.md)
            legs = f" and {len(rep.pfl_links)} leg links" if rep.pfl_links else ""
            click.echo(f"  power and force limiting for {', '.join(rep.pfl)} at the platform"
                       f"{legs}: worst contact energy {rep.max_pfl_ratio:.3f} of the "
                       f"ISO/TS 15066 limit (at {rep.max_pfl_where})")
        for msg in rep.messages():
            click.echo(f"  {'defect' if rep.exit_code == 2 else 'violation'}: {msg}")
        if eng is not None:
            sm = eng.simulation
            click.echo(f"  MuJoCo: inverse dynamics vs the file {eng.feedforward_error:.2e} "
                       f"N m; replay at {sm.rate_hz:g} Hz with Kp {kp:g}, Kd {kd:g}: "
                       f"tracking error max {math.degrees(sm.max_tracking_error_rad):.3f} "
                       f"deg, PD share {100 * sm.pd_share:.1f}%, peak |tau| "
                       f"{sm.peak_total_torque:.3f} N m")
            for msg in eng.messages:
                click.echo(f"  MuJoCo: {msg}")
    request_fast_exit()
    sys.exit(code)


@main.command("safety-report")
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "out_dir", default=None, type=click.Path(file_okay=False),
              help="Output directory (default: the file's own).")
@click.option("--task", "task_file", default=None, type=click.Path(dir_okay=False),
              help="Apply this task file's setup (payload, tool, mounting) to the robot.")
def safety_report_cmd(csv_file: str, out_dir: str | None, task_file: str | None) -> None:
    """Write a safety report of CSV_FILE for a risk assessment: FILE_safety.html (with
    plots) and FILE_safety.json.

    From the file's samples, recomputed by the gate (its numbers are validate --json's,
    kept whole in the JSON): the body regions and leg links covered and those not; along
    the path, each point's speed, effective mass and two-body contact force per region;
    the largest ratio and where; from each sample, the stop table's stop time and
    distance; the contact guard's settings and measured detection; the assumptions.
    Exit codes as validate's: the report is written for a file that violates a limit
    (exit 1), and says so."""
    from pathlib import Path

    from sixplus3.interaction.report.safety_page import write_report
    from sixplus3.interaction.report.safety_report import safety_report

    robot = task_robot(task_file)
    rep = safety_report(csv_file, robot)
    out = Path(out_dir) if out_dir is not None else Path(csv_file).resolve().parent
    stem = Path(csv_file).stem
    for name in (f"{stem}_safety.html", f"{stem}_safety.json"):
        check_output(str(out / name), (csv_file, task_file), force=True)
    page, js = write_report(rep, out, stem)
    v = rep["validation"]
    if "largest" in rep:
        lg = rep["largest"]
        click.echo(f"{csv_file}: largest contact {lg['force [N]']:.0f} N of {lg['limit [N]']:.0f}"
                   f" N ({lg['region']}, ratio {lg['ratio']:.3f}) at {lg['where']}, t = "
                   f"{lg['t [s]']:.4f} s; {len(rep['coverage']['points'])} points judged")
    elif "refused" in rep:
        click.echo(f"{csv_file}: {rep['refused']}")
    else:
        click.echo(f"{csv_file}: no body region judged (not a power and force limiting "
                   "plan)")
    click.echo(f"  wrote {page} and {js}")
    request_fast_exit()
    sys.exit(int(v["exit_code"]))


@main.command("export")
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("--format", "fmt", required=True,
              type=click.Choice(EXPORT_FORMATS),
              help="ROS 2 trajectory_msgs/JointTrajectory, a servo-drive table "
                   "(encoder counts, counts/s, torque in 0.1 % of rated), or a ROS 2 bag "
                   "(MCAP directory: /joint_states of every joint, /tf, the trajectory; "
                   "needs -o).")
@click.option("-o", "--out", "out_file", default=None, type=click.Path(dir_okay=False),
              help="Write to this file (atomically) instead of stdout.")
@click.option("--task", "task_file", default=None, type=click.Path(dir_okay=False),
              help="Apply this task file's setup (payload, tool, mounting) to the robot.")
@click.option("--torque-hold", type=click.Choice(["sample", "mean"]), default=None,
              help="Torque per sample: 'mean' of it and the next (for a drive that holds "
                   "it over the tick; drive-csv's default) or the 'sample''s own (the "
                   "ROS 2 forms' default).")
@click.option("--rate", "rate", default=None, type=FLOAT,
              help="ROS 2 forms: resample at this lower rate [Hz] (>= 10) on the gate's "
                   "quintic interpolant, validated again as an interpolated motion.")
@click.option("--goal", is_flag=True,
              help="ROS 2 forms: a control_msgs/action/FollowJointTrajectory goal "
                   "(for 'ros2 action send_goal').")
@click.option("--ros-distro", type=click.Choice(["humble", "jazzy"]), default="humble",
              show_default=True,
              help="rosbag2: the ROS 2 distribution whose reader the bag's metadata.yaml "
                   "is for (a humble bag also opens in later ones).")
@click.option("--start-time", "start_time", default=None, type=FLOAT,
              help="rosbag2: the first stamp [s since the epoch] (default: now).")
@click.option("--force", is_flag=True,
              help="Replace an existing trajectory file given as -o (never the input).")
def export_cmd(csv_file: str, fmt: str, out_file: str | None, task_file: str | None,
               torque_hold: str | None, rate: float | None, goal: bool, ros_distro: str,
               start_time: float | None, force: bool) -> None:
    """Export a trajectory file for the controller side, after validating it (exit 1
    for a violated limit, 2 for a bad file: nothing is written).  With --rate, the
    motion a controller interpolates through the exported points is validated as it
    will run (docs/validation.md, "Exports")."""
    from sixplus3.control.formats.exports import export_file
    from sixplus3.control.formats.registry import FORMATS

    form = FORMATS[fmt]
    if form.directory is not None:
        if out_file is None:
            fail(f"--format {fmt} writes a directory: give it with -o DIR")
            return
        if rate is not None or goal:
            fail("--rate and --goal go with the ROS 2 message forms (ros2-yaml, "
                 "ros2-json); the rosbag2 export records the file's own samples")
        start_ns = None
        if start_time is not None:
            if not 0.0 <= start_time <= 4e9:
                fail(f"--start-time must be in [0, 4e9] s since the epoch, got {start_time:g}")
            start_ns = int(round(start_time * 1e9))
        check_output(out_file, (csv_file,), force)
        bag = form.directory(csv_file, task_robot(task_file), out_file, ros_distro, start_ns)
        click.echo(f"wrote {bag} for ROS 2 {ros_distro} (ros2 launch {bag}/replay.launch.py; "
                   f"or ros2 bag play {bag} --clock --rate 0.1)", err=True)
        return
    if start_time is not None or ros_distro != "humble":
        fail("--ros-distro and --start-time go with --format rosbag2")
    check_output(out_file, (csv_file, task_file), force)  # before the work
    text = export_file(csv_file, task_robot(task_file), fmt, torque_hold, rate, goal)
    emit(text, out_file, (csv_file, task_file), force)


@main.command()
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("--udp", default="127.0.0.1:9870", show_default=True,
              help="IPv4:PORT of the controller.")
@click.option("--speed", default=1.0, show_default=True, type=FLOAT,
              help="Replay speed in [0.01, 1]: < 1 is a real retiming, validated again.")
@click.option("--dry-run", is_flag=True, help="Print the datagrams instead of sending.")
@click.option("--start-theta", nargs=9, type=FLOAT, default=None, metavar="A0 B0 C0 ... C2",
              help="The robot's current actuated angles [deg], legs 0..2 each A, B, C: the "
                   "file must start there, on the robot's assembly branch.")
@click.option("--start-counts", nargs=9, type=FLOAT, default=None, metavar="A0 B0 C0 ... C2",
              help="Or the counts the drives read back, turned into angles with the robot "
                   "file's offsets and directions (sixplus3 commission).")
@click.option("--torque-hold", type=click.Choice(["sample", "mean"]), default="mean",
              show_default=True,
              help="Feed-forward per tick: the 'mean' of the torques at both ends of the "
                   "tick the drive holds it over, or the 'sample''s own.")
def feed(csv_file: str, udp: str, speed: float, dry_run: bool,
         start_theta: tuple[float, ...] | None, start_counts: tuple[float, ...] | None,
         torque_hold: str) -> None:
    """Send a trajectory file to the controller: read once, validate, send those samples.

    Exit codes: 0 sent; 1 a limit is violated; 2 bad input, a bad file, or a file that
    does not start at --start-theta (nothing sent).
    """
    from sixplus3.control.drive.feed import (
        check_speed,
        parse_address,
        prepare_feed,
        send,
        udp_sender,
    )

    address = parse_address(udp)
    check_speed(speed)
    current = None
    if start_theta is not None and start_counts is not None:
        fail("give the robot's state as --start-theta or as --start-counts, not both")
    if start_counts is not None:
        import numpy as np

        from sixplus3.identification.commission import counts_to_theta

        current = counts_to_theta(current_robot(), np.array(start_counts))
    if start_theta is not None:
        if not all(math.isfinite(v) for v in start_theta):
            fail(f"--start-theta must be 9 finite angles [deg], got {list(start_theta)}")
        import numpy as np

        current = np.radians(start_theta)
    plan = prepare_feed(csv_file, current_robot(), speed, current_theta=current,
                        torque_hold=torque_hold)
    if current is None:
        click.echo("note: the robot's start state was not checked (--start-theta or "
                   "--start-counts)", err=True)
    emit = (lambda m: click.echo(m.decode())) if dry_run else udp_sender(address)
    n = send(plan, emit)
    verb = "printed (dry run, nothing sent)" if dry_run else "sent"
    click.echo(f"{verb} {n} samples of {plan.t[-1]:.4f} s at {plan.rate:g} Hz "
               f"(speed {plan.speed:g}, torque hold {plan.torque_hold})", err=True)


@main.command()
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("--html", "html_out", default=None, type=click.Path(dir_okay=False),
              help="Write a standalone page with the animation instead of serving it.")
@click.option("--no-wait", is_flag=True, help="Do not wait for Ctrl-C after loading.")
@click.option("--unsafe", is_flag=True,
              help="Show a file the gate refuses, under a red banner naming the failed "
                   "check (default: refuse it, exit 1 or 2).")
@click.option("--video", "video_out", default=None, type=click.Path(dir_okay=False),
              help="Render the playback headless into an .mp4 or .gif (needs chromium and "
                   "pip install 'sixplus3[video]').")
@click.option("--fps", default=20.0, show_default=True, type=FLOAT,
              help="--video: frames per second of the (slowed-down) playback, in [1, 60].")
def play(csv_file: str, html_out: str | None, no_wait: bool, unsafe: bool,
         video_out: str | None, fps: float) -> None:
    """Animate a trajectory file in MeshCat (live; the URL is printed) or as HTML.

    The file is validated first: one the gate refuses is not shown (exit 1 for a
    violated limit, 2 for a bad file) unless --unsafe, which shows it under a red banner.
    What is animated is the forward kinematics of the file's joints, never its platform
    columns."""
    from dataclasses import replace
    from pathlib import Path

    from sixplus3.control.file.trajectory_read import read_trajectory
    from sixplus3.control.gate.validation import validate_file
    from sixplus3.visualization.meshcat_player import (
        animate,
        frames_from_samples,
        viewer_url,
        write_html,
    )

    robot = current_robot()
    check_output(html_out, (csv_file,))
    check_output(video_out, (csv_file,))
    if video_out is not None:
        if html_out is not None:
            fail("give --html or --video, not both")
        if Path(video_out).suffix.lower() not in (".mp4", ".gif"):
            fail(f"--video writes .mp4 or .gif, got {Path(video_out).name}")
        if not 1.0 <= fps <= 60.0:
            fail(f"--fps must be in [1, 60], got {fps:g}")
    rep = validate_file(csv_file, robot)
    refused = None
    if rep.exit_code != 0:
        refused = "; ".join(rep.messages())[:300] or "not a valid motion"
        if not unsafe:
            click.echo(f"refused: not shown, the gate refuses {csv_file}: {refused} "
                       "(--unsafe shows it under a red banner)", err=True)
            sys.exit(rep.exit_code)
        click.echo(f"warning: the gate refuses this file ({refused}); shown under a red "
                   "banner", err=True)
    traj = read_trajectory(csv_file, robot)
    if rep.position is not None and rep.quaternion is not None and rep.psi is not None:
        position, quaternion, psi = rep.position, rep.quaternion, rep.psi  # the gate's FK
    else:
        position, quaternion, psi = (traj.platform_position, traj.platform_quaternion,
                                     traj.psi)
    frames = frames_from_samples(robot, traj.t, position, quaternion, psi,
                                 title=f"sixplus3: {Path(csv_file).stem}",
                                 theta_dot=traj.joints("vel"))
    frames = replace(frames, refused=refused)
    if video_out:
        from sixplus3.visualization.video import render_video

        path = render_video(frames, video_out, fps=fps)
        click.echo(f"wrote {path} (the motion {frames.slowdown:.0f}x slower, {fps:g} fps)")
        return
    if html_out:
        path = write_html(frames, html_out)
        click.echo(f"wrote {path} ({len(frames.q)} frames, slowed down "
                   f"{frames.slowdown:.0f}x)")
        return
    animate(frames)
    click.echo(f"MeshCat viewer: {viewer_url()}  ({len(frames.q)} frames, slowed down "
               f"{frames.slowdown:.0f}x)")
    if not no_wait:
        import time

        click.echo("Ctrl-C to stop the viewer")
        try:
            while True:
                time.sleep(1)
        except KeyboardInterrupt:
            pass
