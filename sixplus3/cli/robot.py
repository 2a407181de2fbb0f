"""The ``sixplus3`` commands of one leg and the whole robot: ``leg``, and ``robot check |
ik | list | show | export``."""

from __future__ import annotations

import json
import math
import sys
from typing import Any

import click

from sixplus3.cli.app import (
    FLOAT,
    NUMERIC_ARGS,
    current_robot,
    emit,
    fail,
    finite_json,
    json_default,
    main,
)


@main.command(context_settings=NUMERIC_ARGS)
@click.argument("x", type=FLOAT)
@click.argument("y", type=FLOAT)
@click.argument("z", type=FLOAT)
@click.option("--force", nargs=3, type=FLOAT, default=None, metavar="FX FY FZ",
              help="Force at P in the leg frame [N].")
@click.option("--mode", default=None,
              help="Assembly mode: four of +/- for (th1, th_s3, th2, th3), or 'default'. "
              "Default: the robot's.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def leg(x: float, y: float, z: float, force: tuple[float, float, float] | None,
        mode: str | None, as_json: bool) -> None:
    """Leg report at P = (X, Y, Z) [m] in the leg frame (paper §III-IV).

    Prints the actuated and passive angles, det J, det K, the singularity margins and
    type, the static torques for --force, and tau_ext (the largest torque needed for a
    2 g acceleration of 0.5 kg at P against gravity in any direction).
    """
    import numpy as np

    from sixplus3.kinematics.leg import SINGULAR_TOL, leg_ik_point
    from sixplus3.robot_description.assembly import AssemblyMode

    if not all(math.isfinite(v) for v in (x, y, z)):
        fail(f"the point must be three finite numbers [m], got {[x, y, z]}")
    robot = current_robot()
    m = robot.mode if mode is None else AssemblyMode.parse(mode)
    state = leg_ik_point([x, y, z], robot.leg, mode=m)
    theta = state.theta[0]
    theta_s = state.theta_s[0]
    sing = str(state.singularity()[0])
    tau = None
    if force is not None:
        if not all(math.isfinite(v) for v in force):
            fail(f"--force must be finite, got {list(force)}")
        if not math.isfinite(state.tau_ext[0]):
            fail("type II singularity at this point: no finite torques balance a general force")
        tau = state.torques(np.array(force))[0]
    if as_json:
        out: dict[str, Any] = {
            "p": [x, y, z], "mode": m.name,
            "theta": theta, "theta_s": theta_s,
            "det_J": float(state.det_J[0]), "det_K": float(state.det_K[0]),
            "margin_I": float(state.margin_I[0]), "margin_II": float(state.margin_II[0]),
            "singularity": sing, "tau_ext": finite_json(float(state.tau_ext[0])),
        }
        if tau is not None:
            out["tau"] = tau
        click.echo(json.dumps(out, default=json_default))
        return
    deg = np.degrees
    click.echo(f"leg at p = ({x:.4f}, {y:.4f}, {z:.4f}) m, assembly mode {m.name}")
    click.echo("  theta   [rad]  " + "  ".join(f"{v:+.6f}" for v in theta))
    click.echo("  theta   [deg]  " + "  ".join(f"{v:+.3f}" for v in deg(theta)))
    click.echo("  theta_s [deg]  " + "  ".join(f"{v:+.3f}" for v in deg(theta_s))
               + "   (th_s2, th_s3)")
    click.echo(f"  det J = {state.det_J[0]:+.6e} m^3   det K = {state.det_K[0]:+.6e} m^6")
    click.echo(f"  margins: type I {state.margin_I[0]:.4f}   type II {state.margin_II[0]:.4f}"
               f"   (0 singular .. 1 best; singular below {SINGULAR_TOL:g})")
    click.echo(f"  singularity: {sing}")
    if tau is not None:
        click.echo("  tau [N m] for f = (" + ", ".join(f"{v:g}" for v in force)  # type: ignore[union-attr]
                   + ") N:  " + "  ".join(f"{v:+.4f}" for v in tau))
    over = state.tau_ext[0] > robot.limits.torque
    click.echo(f"  tau_ext = {state.tau_ext[0]:.4f} N m  (F = F_g + 2 m g B^3, m = 0.5 kg)"
               + (f"  OVER the robot's {robot.limits.torque:g} N m torque limit: this point "
                  "is outside the 2 g COW" if over else ""))


@main.group()
def robot() -> None:
    """The whole robot: URDF + closures, inverse kinematics, statics."""


@robot.command("check")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def robot_check(as_json: bool) -> None:
    """Build the robot's URDF + closures model and check its home pose (exit 1 if home
    is outside the robot's constant-orientation workspace)."""
    from sixplus3.design.report import robot_check as check

    rep = check(current_robot())
    if as_json:
        click.echo(json.dumps(rep.doc, default=json_default))
        sys.exit(0 if rep.inside else 1)
    for line in rep.lines:
        click.echo(line)
    if not rep.inside:
        click.echo("FAILED    home is outside the robot's constant-orientation workspace "
                   f"({rep.cow_line})", err=True)
        sys.exit(1)


@robot.command("ik", context_settings=NUMERIC_ARGS)
@click.argument("x", type=FLOAT)
@click.argument("y", type=FLOAT)
@click.argument("z", type=FLOAT)
@click.argument("roll", type=FLOAT)
@click.argument("pitch", type=FLOAT)
@click.argument("yaw", type=FLOAT)
@click.option("--redundancy", nargs=3, type=FLOAT, default=(90.0, 90.0, 90.0),
              show_default=True, metavar="A1 A2 A3", help="Crank angles psi_i [deg].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
def robot_ik_cmd(x: float, y: float, z: float, roll: float, pitch: float, yaw: float,
                 redundancy: tuple[float, float, float], as_json: bool) -> None:
    """Inverse kinematics of the platform pose X Y Z [m], ROLL PITCH YAW [deg].

    Prints the 9 actuated angles (legs 0..2, each A, B, C), the closure residual, the
    singularity margins and the static gravity torques.
    """
    import numpy as np

    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.kinematics.robot import robot_ik_pose
    from sixplus3.kinematics.spherical import spherical_tilts

    values = (x, y, z, roll, pitch, yaw, *redundancy)
    if not all(math.isfinite(v) for v in values):
        fail(f"pose and redundancy must be finite numbers, got {list(values)}")
    robot = current_robot()
    lim = robot.limits
    cfg = robot_ik_pose((x, y, z), np.radians([roll, pitch, yaw]), np.radians(redundancy),
                        robot=robot)
    dyn = ClosedLoopDynamics(robot)
    q = cfg.q[0]
    residual = float(np.abs(dyn.clm.residual(q)).max())
    tau = dyn.gravity_torques(q)
    tilt = float(spherical_tilts(cfg).max())
    out = {
        "theta": cfg.theta[0], "residual": residual, "margins": cfg.margins.as_dict(),
        "tau_gravity": tau, "max_spherical_tilt_deg": math.degrees(tilt),
        "spherical_ok": tilt <= lim.spherical,
        "actuated_range_ok": bool(np.all((cfg.theta[0] >= lim.theta_min)
                                         & (cfg.theta[0] <= lim.theta_max))),
    }
    if as_json:
        click.echo(json.dumps(out, default=json_default))
        return
    th = np.degrees(cfg.theta[0]).reshape(3, 3)
    for i in range(3):
        click.echo(f"leg {i}  theta A B C = " + "  ".join(f"{v:8.3f}" for v in th[i]) + " deg")
    click.echo(f"closure residual {residual:.2e} m")
    m = out["margins"]
    click.echo("margins  leg type I " + " ".join(f"{v:.3f}" for v in m["leg_type1"])
               + " | leg type II " + " ".join(f"{v:.3f}" for v in m["leg_type2"])
               + f" | platform {m['platform']:.3f}")
    click.echo("tau_g    " + " ".join(f"{v:+.3f}" for v in tau) + "  N m")
    click.echo(f"spherical joints: max tilt {out['max_spherical_tilt_deg']:.1f} deg "
               f"({'ok' if out['spherical_ok'] else 'OVER THE LIMIT'}); actuated range "
               f"{'ok' if out['actuated_range_ok'] else 'OUTSIDE THE RANGE'}")


@robot.command("list")
def robot_list() -> None:
    """The named robots ('--robot NAME')."""
    from sixplus3.robot_description.robot import NAMED_ROBOTS

    for name, (_, text) in NAMED_ROBOTS.items():
        click.echo(f"{name:13s} {text}")


@robot.command("show")
@click.option("--json", "as_json", is_flag=True, help="Print the parameters as JSON.")
def robot_show(as_json: bool) -> None:
    """Every parameter of the robot and its hash (the input format of --robot)."""
    robot = current_robot()
    doc = robot.as_dict()
    if as_json:
        click.echo(json.dumps({**doc, "hash": robot.hash}, indent=1))
        return
    from sixplus3.robot_description.hardware import effective_limits, envelope_record

    env = envelope_record()
    lim = effective_limits(robot)
    click.echo(robot.summary())
    click.echo(f"in force: torque {lim.torque:g} N m, rate {lim.velocity:g} rad/s, "
               f"acceleration {lim.acceleration:g} rad/s^2 (the robot's limits tightened "
               f"by the envelope: {env['drive_train']}, {env['origin']})")
    click.echo(json.dumps({**doc, "hash": robot.hash}, indent=1))


@robot.command("export")
@click.argument("fmt", type=click.Choice(["urdf", "mjcf", "yaml"]))
@click.option("-o", "--out", "out_file", default=None, type=click.Path(dir_okay=False),
              help="Write to this file (atomically) instead of stdout.")
@click.option("--contacts", is_flag=True,
              help="MJCF: contacts between the links of different legs (off by default).")
@click.option("--ros2-control", "ros2_control", is_flag=True,
              help="URDF: add a <ros2_control> block (effort interfaces, 72/34 "
                   "transmissions, rotor inertia and friction as parameters; every "
                   "joint's initial_value at the robot's home, or at --start).")
@click.option("--start", "start_file", default=None,
              type=click.Path(exists=True, dir_okay=False),
              help="With --ros2-control: the initial values are this trajectory file's "
                   "first sample (a file of this robot, read through the gate's reader).")
def robot_export(fmt: str, out_file: str | None, contacts: bool, ros2_control: bool,
                 start_file: str | None) -> None:
    """Write the robot as URDF (tree; with -o the closures file it names,
    sixplus3_closures.yaml, beside it), MJCF (MuJoCo, closures included; a 'home'
    keyframe, assembled and held by its ctrl; actuator and joint limits) or YAML (its
    parameters: the input of --robot)."""
    robot = current_robot()
    if (contacts and fmt != "mjcf") or (ros2_control and fmt != "urdf"):
        fail("--contacts goes with mjcf and --ros2-control with urdf")
    if start_file is not None and not ros2_control:
        fail("--start goes with --ros2-control")
    if fmt == "urdf":
        from sixplus3.robot_description.urdf import (
            CLOSURES_PATH,
            build_closures_yaml,
            robot_urdf,
        )

        if ros2_control:
            from sixplus3.robot_description.ros2_control import with_ros2_control

            if start_file is not None:
                from sixplus3.control.file.trajectory_read import read_trajectory

                initial = read_trajectory(start_file, robot).joints("pos")[0]
            else:
                from sixplus3.kinematics.robot import home

                initial = home(robot).theta[0]
            text = with_ros2_control(robot, initial=initial)
        else:
            text = robot_urdf(robot)
        if out_file is not None:
            from pathlib import Path

            from sixplus3.fileio import atomic_write

            closures = Path(out_file).with_name(CLOSURES_PATH.name)
            if closures.resolve() == Path(out_file).resolve():
                fail(f"-o must not be named {CLOSURES_PATH.name}: the closures go there")
            atomic_write(closures, build_closures_yaml().encode())
            click.echo(f"wrote {closures} (the loop closures the URDF names)", err=True)
        else:
            click.echo(f"note: the URDF names {CLOSURES_PATH.name}; -o FILE writes it "
                       "beside FILE", err=True)
    elif fmt == "mjcf":
        from sixplus3.control.drive.simulation import export_mjcf

        text = export_mjcf(robot, contacts=contacts)
    else:
        import yaml

        text = yaml.safe_dump(robot.as_dict(), sort_keys=False)
    emit(text, out_file)
