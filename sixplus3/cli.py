"""The ``sixplus3`` command line.

Thin wiring only: every command imports the library (numpy, numba, pinocchio, ...) inside
its body, so that ``sixplus3 --help`` answers without loading them.  Every command works
on one robot: ``Robot.default()``, a named robot (``--robot paper``, see
``Robot.named``), or the one in ``--robot FILE`` (YAML/JSON, see
``sixplus3 robot show --json``).

Exit codes: 0 ok; 1 a limit is violated (``validate``); 2 bad input, an unreachable pose,
an infeasible task, or a missing, corrupted, forged or mismatched file: one line on
stderr naming what was wrong and the valid range; 3 an internal error (a bug: one line,
the traceback only with ``SIXPLUS3_DEBUG=1``).  The root error
:class:`~sixplus3.errors.Sixplus3Error` is caught once, here.
"""

from __future__ import annotations

import json
import math
import os
import sys
from typing import TYPE_CHECKING, Any

import click

if TYPE_CHECKING:
    from sixplus3.robot_description.robot import Robot

# Negative numbers are positional values here (``sixplus3 leg -0.1 0.4 0.2``): let click
# pass tokens such as ``-0.1`` through instead of treating them as unknown options.
_NUMERIC_ARGS = {"ignore_unknown_options": True, "help_option_names": ["-h", "--help"]}


def _fail(message: str) -> None:
    """One-line error on stderr, exit code 2."""
    click.echo(f"error: {message}", err=True)
    sys.exit(2)


def _json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(type(obj))


def _finite_json(value: float) -> float | None:
    """JSON has no inf/NaN: a singular tau_ext is reported as null."""
    return value if math.isfinite(value) else None


class _Group(click.Group):
    """Catches the root error once: one line, exit 2 (and an internal error: exit 3)."""

    def invoke(self, ctx: click.Context) -> Any:
        from sixplus3.errors import Sixplus3Error, ValidationFailed

        try:
            return super().invoke(ctx)
        except ValidationFailed as exc:
            click.echo(f"refused: {' '.join(str(exc).split())[:2000]}", err=True)
            sys.exit(exc.exit_code)
        except Sixplus3Error as exc:
            _fail(" ".join(str(exc).split())[:2000])
        except OSError as exc:  # an output path that cannot be written, a full disk
            _fail(f"{exc.strerror or exc}: {exc.filename or ''}"[:2000])
        except (click.exceptions.Exit, click.ClickException, click.Abort, SystemExit):
            raise
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            sys.exit(130)
        except Exception as exc:  # noqa: BLE001 - the CLI never shows a traceback
            if os.environ.get("SIXPLUS3_DEBUG"):
                raise
            click.echo(f"internal error (a bug, please report; SIXPLUS3_DEBUG=1 shows the "
                       f"traceback): {type(exc).__name__}: {str(exc)[:300]}", err=True)
            sys.exit(3)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="sixplus3")
@click.option("--robot", "robot_file", default=None, metavar="NAME|FILE",
              help="A named robot (default, paper, paper-mirror: 'sixplus3 robot list') or a "
              "file of robot parameters (YAML/JSON, keys as in 'sixplus3 robot show --json'; "
              "missing keys keep the defaults). Default: the built robot ('default').")
@click.pass_context
def main(ctx: click.Context, robot_file: str | None) -> None:
    """sixplus3: kinematics, dynamics, design and planning for the (6+3)-DoF robot."""
    from sixplus3 import progress

    progress.set_level(progress.NORMAL)  # before a subcommand's --quiet / --verbose
    ctx.obj = {"robot_file": robot_file}


def _bars() -> bool:
    """Progress (bars, stages) unless ``--quiet``."""
    from sixplus3 import progress

    return progress.level() != progress.QUIET


def _set_level(ctx: click.Context, param: click.Parameter, value: bool) -> bool:
    from sixplus3 import progress

    if not value:
        return value
    want = progress.QUIET if param.name == "quiet" else progress.VERBOSE
    seen = ctx.meta.setdefault("sixplus3_level", want)
    if seen != want:
        raise click.UsageError("--quiet and --verbose exclude each other")
    progress.set_level(want)
    return value


def _verbosity(f):
    """``--quiet`` / ``--verbose`` (:mod:`sixplus3.progress`) on a long-running command."""
    f = click.option("-v", "--verbose", is_flag=True, expose_value=False, is_eager=True,
                     callback=_set_level,
                     help="Also one line per IPOPT iteration (duration, violation).")(f)
    return click.option("-q", "--quiet", is_flag=True, expose_value=False, is_eager=True,
                        callback=_set_level,
                        help="No progress: no compile notice, stages or bars; only results "
                             "and errors.")(f)


def _robot() -> Robot:
    """The robot of this invocation (``--robot FILE`` or the default), loaded once."""
    ctx = click.get_current_context()
    obj = ctx.find_root().obj or {}
    if "robot" not in obj:
        from sixplus3.robot_description.robot import NAMED_ROBOTS, Robot, load_robot

        path = obj.get("robot_file")
        if not path:
            obj["robot"] = Robot.default()
        elif path.strip().lower() in NAMED_ROBOTS and not os.path.exists(path):
            obj["robot"] = Robot.named(path)
        elif not os.path.exists(path):
            _fail(f"--robot {path!r} is neither a named robot (one of "
                  f"{', '.join(NAMED_ROBOTS)}) nor an existing robot file")
        else:
            from sixplus3.kinematics.collision import check_layout

            obj["robot"] = load_robot(path)
            check_layout(obj["robot"])  # a robot file must describe a buildable robot
    return obj["robot"]


@main.command(context_settings=_NUMERIC_ARGS)
@click.argument("x", type=float)
@click.argument("y", type=float)
@click.argument("z", type=float)
@click.option("--force", nargs=3, type=float, default=None, metavar="FX FY FZ",
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

    from sixplus3.kinematics.leg import SINGULAR_TOL, AssemblyMode, leg_ik_point

    if not all(math.isfinite(v) for v in (x, y, z)):
        _fail(f"the point must be three finite numbers [m], got {[x, y, z]}")
    robot = _robot()
    m = robot.mode if mode is None else AssemblyMode.parse(mode)
    state = leg_ik_point([x, y, z], robot.leg, mode=m)
    theta = state.theta[0]
    theta_s = state.theta_s[0]
    sing = str(state.singularity()[0])
    tau = None
    if force is not None:
        if not all(math.isfinite(v) for v in force):
            _fail(f"--force must be finite, got {list(force)}")
        if not math.isfinite(state.tau_ext[0]):
            _fail("type II singularity at this point: no finite torques balance a general force")
        tau = state.torques(np.array(force))[0]
    if as_json:
        out: dict[str, Any] = {
            "p": [x, y, z], "mode": m.name,
            "theta": theta, "theta_s": theta_s,
            "det_J": float(state.det_J[0]), "det_K": float(state.det_K[0]),
            "margin_I": float(state.margin_I[0]), "margin_II": float(state.margin_II[0]),
            "singularity": sing, "tau_ext": _finite_json(float(state.tau_ext[0])),
        }
        if tau is not None:
            out["tau"] = tau
        click.echo(json.dumps(out, default=_json_default))
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
    import numpy as np

    from sixplus3.design.cow import home_in_cow
    from sixplus3.dynamics.closed_loop import ClosedLoopDynamics
    from sixplus3.kinematics import collision
    from sixplus3.kinematics.robot import home
    from sixplus3.kinematics.spherical import spherical_tilts
    from sixplus3.robot_description.urdf import check as urdf_stale

    robot = _robot()
    dyn = ClosedLoopDynamics(robot)
    clm = dyn.clm
    h = home(robot)
    where = home_in_cow(robot, step=0.02)
    g = robot.geometry
    near = collision.closest(h)
    layout = {"axis_turn_deg": math.degrees(g.axis_turn),
              "platform_phase_deg": math.degrees(g.platform_phase),
              "base_radius_m": g.base_radius, "platform_radius_m": g.platform_radius,
              "platform_crank_m": g.platform_crank,
              "home_clearance_m": near[2], "home_closest_pair": list(near[:2]),
              "collision_model_m": robot.collision.as_dict()}
    q = h.q[0]
    residual = float(np.abs(clm.residual(q)).max())
    rank = int(np.linalg.matrix_rank(clm.constraint_jacobian(q), tol=1e-9))
    tau = dyn.gravity_torques(q)
    out = {
        "robot": robot.summary(), "robot_hash": robot.hash, "assembly_mode": robot.mode.name,
        "committed_urdf_fresh": not urdf_stale(),
        "nq": clm.model.nq, "nv": clm.model.nv, "actuated": len(clm.actuated_names),
        "closures": len(clm.pairs), "constraint_rows": clm.n_constraints,
        "constraint_rank_home": rank, "mobility": clm.model.nv - rank,
        "home_position_m": list(robot.home_position),
        "home_psi_deg": np.degrees(robot.home_psi), "home_residual_m": residual,
        "margins": h.margins.as_dict(),
        "max_spherical_tilt_deg": float(np.degrees(spherical_tilts(h).max())),
        "tau_gravity_home": tau, "total_mass_kg": clm.total_mass(),
        "design_m": {"l2": robot.leg.l2, "l4": robot.leg.l4, "ex": robot.leg.ex,
                     "ey": robot.leg.ey},
        "layout": layout,
        "home_in_cow": {"inside": where.inside, "failing": where.failing,
                        "depth_m": where.depth, "deepest_m": list(where.deepest),
                        "z_range_m": list(where.z_range), "volume_l": where.volume_l,
                        "grid_m": where.step},
    }
    if as_json:
        click.echo(json.dumps(out, default=_json_default))
        sys.exit(0 if where.inside else 1)
    click.echo(f"robot     {out['robot']}")
    click.echo(f"gravity   {list(robot.gravity)} m/s^2; committed URDF of the default robot "
               f"fresh: {out['committed_urdf_fresh']}")
    click.echo(f"tree DoF  nq = {out['nq']}, nv = {out['nv']}; {out['actuated']} actuated joints")
    click.echo(f"closures  {out['closures']} spherical, {out['constraint_rows']} rows, rank "
               f"{rank} at home -> mobility {out['mobility']}")
    click.echo(f"design    l2 = l3 = {robot.leg.l2:.3f}, l4 = l5 = {robot.leg.l4:.3f}, ex = fx = "
               f"{robot.leg.ex:.3f}, ey = -fy = {robot.leg.ey:.3f} m; assembly mode "
               f"{robot.mode.name}")
    click.echo(f"layout    actuated axes turned {layout['axis_turn_deg']:.1f} deg from the "
               f"tangent (|a_j - a_i| = {g.base_radius * math.sqrt(3):.3f} m), platform phase "
               f"{layout['platform_phase_deg']:.1f} deg; at home the closest bodies are "
               f"{near[0]} and {near[1]}, {near[2] * 1e3:.1f} mm apart")
    click.echo(f"home      platform at {list(robot.home_position)} m, psi = "
               f"{np.round(np.degrees(robot.home_psi), 2).tolist()} deg; closure residual "
               f"{residual:.2e} m")
    click.echo(f"COW       {where.line()} (grid {where.step * 100:g} cm)")
    m = out["margins"]
    click.echo("margins   leg type I " + " ".join(f"{v:.3f}" for v in m["leg_type1"])
               + " | leg type II " + " ".join(f"{v:.3f}" for v in m["leg_type2"])
               + f" | platform {m['platform']:.3f}")
    click.echo("tau_g     " + " ".join(f"{v:+.3f}" for v in tau) + "  N m (home)")
    click.echo(f"mass      {out['total_mass_kg']:.3f} kg")
    if not where.inside:
        click.echo("FAILED    home is outside the robot's constant-orientation workspace "
                   f"({where.line()})", err=True)
        sys.exit(1)


@robot.command("ik", context_settings=_NUMERIC_ARGS)
@click.argument("x", type=float)
@click.argument("y", type=float)
@click.argument("z", type=float)
@click.argument("roll", type=float)
@click.argument("pitch", type=float)
@click.argument("yaw", type=float)
@click.option("--redundancy", nargs=3, type=float, default=(90.0, 90.0, 90.0),
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
        _fail(f"pose and redundancy must be finite numbers, got {list(values)}")
    robot = _robot()
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
        click.echo(json.dumps(out, default=_json_default))
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
    robot = _robot()
    doc = robot.as_dict()
    if as_json:
        click.echo(json.dumps({**doc, "hash": robot.hash}, indent=1))
        return
    click.echo(robot.summary())
    click.echo(json.dumps({**doc, "hash": robot.hash}, indent=1))


@robot.command("export")
@click.argument("fmt", type=click.Choice(["urdf", "mjcf", "yaml"]))
@click.option("-o", "--out", "out_file", default=None, type=click.Path(dir_okay=False),
              help="Write to this file (atomically) instead of stdout.")
@click.option("--contacts", is_flag=True,
              help="MJCF: contacts between the links of different legs (off by default).")
@click.option("--ros2-control", "ros2_control", is_flag=True,
              help="URDF: add a <ros2_control> block (effort interfaces, 72/34 "
                   "transmissions, rotor inertia and friction as parameters).")
def robot_export(fmt: str, out_file: str | None, contacts: bool, ros2_control: bool) -> None:
    """Write the robot as URDF (tree; with -o the closures file it names,
    sixplus3_closures.yaml, beside it), MJCF (MuJoCo, closures included; a 'home'
    keyframe, assembled and held by its ctrl; actuator and joint limits) or YAML (its
    parameters: the input of --robot)."""
    robot = _robot()
    if (contacts and fmt != "mjcf") or (ros2_control and fmt != "urdf"):
        _fail("--contacts goes with mjcf and --ros2-control with urdf")
    if fmt == "urdf":
        from sixplus3.robot_description.urdf import CLOSURES_PATH, with_ros2_control

        text = with_ros2_control(robot) if ros2_control else robot.urdf()
        if out_file is not None:
            from pathlib import Path

            from sixplus3.fileio import atomic_write

            closures = Path(out_file).with_name(CLOSURES_PATH.name)
            if closures.resolve() == Path(out_file).resolve():
                _fail(f"-o must not be named {CLOSURES_PATH.name}: the closures go there")
            atomic_write(closures, robot.closures_yaml().encode())
            click.echo(f"wrote {closures} (the loop closures the URDF names)", err=True)
        else:
            click.echo(f"note: the URDF names {CLOSURES_PATH.name}; -o FILE writes it "
                       "beside FILE", err=True)
    elif fmt == "mjcf":
        from sixplus3.control.simulation import export_mjcf

        text = export_mjcf(robot, contacts=contacts)
    else:
        import yaml

        text = yaml.safe_dump(robot.as_dict(), sort_keys=False)
    _emit(text, out_file)


@main.group()
def design() -> None:
    """Optimal leg design and workspace (paper §V)."""


def _reading_option(f):
    return click.option("--reading", default="paper-mirror", show_default=True,
                        help="Reading of the paper's conventions (see docs/design.md): "
                        "one of " + ", ".join(_reading_names()))(f)


def _reading_names() -> list[str]:
    # Static so that --help does not import numba; tests check it equals READINGS.
    return ["spec", "paper-match", "paper-mirror", "spec-no-theta-limit"]


def _reading(name: str):
    from sixplus3.design.readings import READINGS

    if name not in READINGS:
        _fail(f"unknown reading {name!r}: choose one of {', '.join(sorted(READINGS))}")
    return READINGS[name]


@design.command("optimize")
@click.option("--coarse-step", default=0.01, show_default=True, type=float,
              help="Stage-1 grid of the design variables [m].")
@click.option("--fine-step", default=0.001, show_default=True, type=float,
              help="Stage-2 grid around the best coarse design [m].")
@click.option("--ws-step", "ws_steps", default=(0.01, 0.005, 0.0025), show_default=True,
              type=float, multiple=True,
              help="Workspace grid of the half-plane [m]; repeat to re-optimise on each.")
@_reading_option
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object per grid.")
@_verbosity
def design_optimize(coarse_step: float, fine_step: float, ws_steps: tuple[float, ...],
                    reading: str, as_json: bool) -> None:
    """Two-stage grid search of (l2 = l3, l4 = l5, ex = fx) maximising the usable area,
    re-run on every workspace grid, with the ridge of near-optimal designs."""
    from sixplus3.design.search import PAPER_DESIGN, check_steps, optimize

    rd = _reading(reading)
    # every grid before the first search: no partial output for a bad one (InputError)
    check_steps(coarse_step, fine_step, *ws_steps)
    if not as_json:
        click.echo(f"reading '{rd.name}': {rd.description}")
        click.echo(f"paper        l2 = {PAPER_DESIGN[0]:.3f}  l4 = {PAPER_DESIGN[1]:.3f}  "
                   f"ex = {PAPER_DESIGN[2]:.3f} m")
    for ws_step in ws_steps:
        res = optimize(coarse_step, fine_step, ws_step, rd, progress=_bars() and not as_json)
        rg = res.ridge
        if as_json:
            out = {"found": res.found, "l2": res.l2, "l4": res.l4, "ex": res.ex,
                   "area_m2": res.area_m2, "paper_design_area_m2": res.paper_design_area_m2,
                   "evaluations": res.evaluations, "point_evaluations": res.point_evaluations,
                   "seconds": res.seconds, "reading": rd.name, "ws_step": ws_step,
                   "ridge": None if rg is None else {
                       "tolerance": rg.tolerance, "count": rg.count, "l2": rg.l2,
                       "l4": rg.l4, "ex": rg.ex, "l2_over_ex": rg.l2_over_ex},
                   "local_optima": [dict(zip(("l2", "l4", "ex", "area_m2"), v, strict=True))
                                    for v in res.local_optima]}
            click.echo(json.dumps(out, default=lambda x: None))
            continue
        click.echo(f"grid {ws_step * 1000:g} mm:")
        if res.found:
            click.echo(f"  optimum    l2 = {res.l2:.3f}  l4 = {res.l4:.3f}  ex = {res.ex:.3f} m"
                       f"   area {res.area_m2:.5f} m^2")
        else:
            click.echo("  optimum    none: no feasible design has a counted point")
        click.echo(f"  paper's design: area {res.paper_design_area_m2:.5f} m^2 (our model)")
        for v in res.local_optima:
            if (v[0], v[1], v[2]) == (res.l2, res.l4, res.ex):
                continue
            click.echo(f"  also       l2 = {v[0]:.3f}  l4 = {v[1]:.3f}  ex = {v[2]:.3f} m   "
                       f"area {v[3]:.5f} m^2 (refined from another coarse seed)")
        if rg is not None:
            click.echo(f"  ridge      {rg.line()}")
        click.echo(f"  {res.evaluations} designs ({res.feasible_designs} feasible), "
                   f"{res.point_evaluations:,} point evaluations in {res.seconds:.1f} s")


@design.command("layout")
@click.option("--turns", default="0:45:2.5", show_default=True, metavar="START:STOP:STEP",
              help="Axis turns gamma to sweep [deg].")
@click.option("--phases", default="-20:20:10", show_default=True, metavar="START:STOP:STEP",
              help="Platform phase offsets to sweep [deg], from the robot's own phase.")
@click.option("--step", default=0.02, show_default=True, type=float,
              help="COW grid pitch, x, y and z [m].")
@click.option("--legs", type=click.Choice(["both", "paper", "other-basin"]), default="both",
              show_default=True, help="Which §V legs to study.")
@click.option("--out", "out_dir", default="layout", show_default=True,
              type=click.Path(file_okay=False), help="Output directory (table, figure).")
@click.option("--workers", default=2, show_default=True, type=int,
              help="LocalCluster worker processes (1-4).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="A Dask scheduler address (tcp://host:8786), or 'synchronous'.")
def design_layout(turns: str, phases: str, step: float, legs: str, out_dir: str,
                  workers: int, scheduler: str | None) -> None:
    """The whole-robot layout study: the paper's leg in its §V assembly, the
    interference-free 2 g COW against the axis turn and the platform phase (docs/design.md,
    "Layout").  The base robot is --robot's (default: the built robot) with its own
    layout replaced by each of the sweep's."""
    from pathlib import Path

    from sixplus3 import fileio
    from sixplus3.design import layout as lay
    from sixplus3.design.cluster import check_scheduler, check_workers

    st = lay.LayoutSettings(turns_deg=_sweep("--turns", turns),
                            phases_deg=_sweep("--phases", phases), step=step,
                            z_step=step).check()
    check_workers(workers)
    check_scheduler(scheduler)
    base = _robot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    which = ("paper", "other-basin") if legs == "both" else (legs,)
    n = len(st.turns_deg) * len(st.phases_deg) * len(which)
    where = f"LocalCluster of {workers} workers" if scheduler is None else scheduler
    click.echo(f"layout study: {n} layouts, COW grid {step * 100:g} cm; {where}")
    study = lay.layout_study(base, st, which, scheduler=scheduler, workers=workers,
                             progress=_bars())
    click.echo(study.report())
    table = out / "layout.json"
    fileio.atomic_write(table, json.dumps(
        {"robot": base.as_dict(), "settings": {"turns_deg": list(st.turns_deg),
                                               "phases_deg": list(st.phases_deg),
                                               "step_m": st.step},
         "points": [p.as_dict() for p in study.points]}, indent=1,
        default=lambda x: None).encode() + b"\n")
    fig = out / "layout_volume.png"
    lay.plot_study(study, fig)
    click.echo(f"wrote {table}\nwrote {fig}")


def _sweep(name: str, text: str) -> tuple[float, ...]:
    """START:STOP:STEP (inclusive) or one number [deg], as a tuple; bad text exits 2."""
    parts = str(text).split(":")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        _fail(f"{name} must be START:STOP:STEP or one number [deg], got {text[:40]!r}")
    if len(vals) == 1:
        vals = [vals[0], vals[0], 1.0]
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals) or vals[2] <= 0 \
            or vals[1] < vals[0] or (vals[1] - vals[0]) / vals[2] > 400:
        _fail(f"{name} must be START:STOP:STEP with START <= STOP, STEP > 0 and at most "
              f"400 values [deg], got {text[:40]!r}")
    n = int(math.floor((vals[1] - vals[0]) / vals[2] + 1e-9)) + 1
    return tuple(round(vals[0] + k * vals[2], 9) for k in range(n))


@design.command("figures")
@click.option("--out", "out_dir", default="figures", show_default=True,
              type=click.Path(file_okay=False), help="Output directory.")
@_reading_option
@click.option("--ws-step", default=0.0025, show_default=True, type=float,
              help="Half-plane grid of the leg figures [m].")
def design_figures(out_dir: str, reading: str, ws_step: float) -> None:
    """Write the §V figures (det J/K, tau_ext, COW, encoder resolution) as PNG."""
    from sixplus3.design.figures import make_figures

    if not (math.isfinite(ws_step) and 0.0005 <= ws_step <= 0.05):
        _fail(f"--ws-step must be in [0.0005, 0.05] m, got {ws_step!r}")
    rd = _reading(reading)
    s = make_figures(out_dir, rd, ws_step=ws_step)
    for f in s.files:
        click.echo(f"wrote {f}")
    click.echo(f"counted area {s.counted_area_m2:.4f} m^2; COW projected area / footprint: "
               + ", ".join(f"{k} {v:.2f}" for k, v in s.cow_ratios.items())
               + f" (paper {s.paper_cow_ratio}); worst encoder resolution "
               f"{s.worst_resolution_m:.2e} m (paper {s.paper_resolution_m:.1e} m)")


@main.command()
@click.option("--ws-step", default=0.005, show_default=True, type=float,
              help="Workspace grid step of the usable-area report [m].")
def report(ws_step: float) -> None:
    """A report of the robot's leg design (sample configurations, usable area)."""
    from sixplus3.design.report import leg_report

    click.echo(leg_report(_robot(), ws_step=ws_step))


@main.command()
@click.option("-o", "--out", "out_dir", default="out/atlas", show_default=True,
              type=click.Path(file_okay=False), help="Output directory (atlas.nc, PNGs).")
@click.option("--step", default=0.02, show_default=True, type=float,
              help="Position grid step [m].")
@click.option("--azimuth-step", default=15.0, show_default=True, type=float,
              help="Tilt-direction step [deg] (tilt-axis azimuths 0..360).")
@click.option("--torsion", "torsions", multiple=True, type=float,
              help="Torsion angle [deg] (repeat for several; default 0).")
@click.option("--max-tilt", default=180.0, show_default=True, type=float,
              help="Largest tilt searched [deg].")
@click.option("--resolution", default=1.0, show_default=True, type=float,
              help="Bisection resolution of the tilt [deg].")
@click.option("--z", "z_range", nargs=2, type=float, default=None,
              help="Only heights in [ZMIN, ZMAX] [m] (default: the reachable region).")
@click.option("--workers", default=2, show_default=True, type=int,
              help="Dask LocalCluster worker processes (one thread each).")
@click.option("--scheduler", default=None,
              help="A Dask scheduler address (tcp://host:8786) instead of a LocalCluster; "
              "'synchronous' runs in this process.")
@click.option("--chunk", default=48, show_default=True, type=int,
              help="Positions per Dask task.")
@click.option("--accel-g", default=0.0, show_default=True, type=float,
              help="Dynamic criterion: the platform must also accelerate at this many g "
              "in every direction from rest within the torque limit (0: static only).")
@click.option("--no-figures", is_flag=True, help="Write only the data file.")
@_verbosity
def atlas(out_dir: str, step: float, azimuth_step: float, torsions: tuple[float, ...],
          max_tilt: float, resolution: float, z_range: tuple[float, float] | None,
          workers: int, scheduler: str | None, chunk: int, accel_g: float,
          no_figures: bool) -> None:
    """The orientation-workspace atlas: the largest tilt in every direction at every
    position, cranks free vs locked (NetCDF + maps; docs/atlas.md)."""
    import time
    from pathlib import Path

    import numpy as np

    from sixplus3.design import atlas as at

    try:
        import dask.distributed  # noqa: F401
        import h5netcdf  # noqa: F401
        import xarray  # noqa: F401
    except ImportError as exc:
        _fail(f"the atlas needs the 'atlas' extra ({exc.name} is missing): "
              "pip install 'sixplus3[atlas]' (make install includes it)")
    st = at.AtlasSettings(step=step, azimuth_step_deg=azimuth_step,
                          torsions_deg=tuple(torsions) or (0.0,), max_tilt_deg=max_tilt,
                          resolution_deg=resolution, accel_g=accel_g).check()
    at.check_run(workers, chunk)
    at.check_scheduler(scheduler)
    if z_range is not None and not (all(math.isfinite(v) for v in z_range)
                                    and 0 < z_range[0] <= z_range[1] <= 3):
        _fail(f"--z must be 0 < ZMIN <= ZMAX <= 3 m, got {z_range[0]!r} {z_range[1]!r}")
    robot = _robot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    xs, ys, zs = at.position_grid(robot, st.step)
    if z_range is not None:
        lo, hi = z_range
        inside = (zs >= lo - 1e-9) & (zs <= hi + 1e-9)
        if not inside.any():
            _fail(f"--z [{lo}, {hi}] m holds no grid height (the grid has "
                  f"{zs[[0, -1]].round(3).tolist()} m)")
        zs = zs[inside]
    npos = len(xs) * len(ys) * len(zs)
    where = f"LocalCluster of {workers} workers" if scheduler is None else scheduler
    click.echo(f"atlas of {robot.name}: {npos} positions ({len(xs)} x {len(ys)} x {len(zs)},"
               f" {st.step * 100:g} cm) x {len(st.azimuths_deg)} directions x "
               f"{len(st.torsions_deg)} torsion(s), cranks free and locked; {where}")
    t0 = time.perf_counter()
    ds = at.compute_atlas(robot, st, scheduler=scheduler, workers=workers, chunk=chunk,
                          grid=(xs, ys, zs), progress=_bars())
    path = at.save(ds, out / "atlas.nc")
    click.echo(f"wrote {path} ({time.perf_counter() - t0:.1f} s)")
    if not no_figures:
        polar = at.home_polar(robot, st)
        for f in at.figures(ds, out, robot, polar):
            click.echo(f"wrote {f}")
        click.echo("at home, largest tilt over directions: free "
                   f"{np.nanmin(polar['free']):.1f} deg (min) .. {np.nanmax(polar['free']):.1f}"
                   f" (max); locked {np.nanmin(polar['locked']):.1f} .. "
                   f"{np.nanmax(polar['locked']):.1f} deg")
    vol = at.volumes(ds)
    t = next(iter(vol["free"]))
    click.echo("volume where every direction tilts at least [L]: "
               + "; ".join(f"{k:g} deg: free {vol['free'][t][k]:.2f}, locked "
                           f"{vol['locked'][t][k]:.2f}" for k in at.THRESHOLDS_DEG)
               + f" (zero-tilt workspace: free {vol['free'][t]['zero tilt']:.2f}, locked "
               f"{vol['locked'][t]['zero tilt']:.2f})")
    click.echo(at.headline(ds))


def _check_rate(rate: float) -> None:
    from sixplus3.control.validation import RATE_RANGE

    lo, hi = RATE_RANGE
    if not (math.isfinite(rate) and lo <= rate <= hi):
        _fail(f"--rate must be in [{lo:g}, {hi:g}] Hz, got {rate!r}")


def _load_task_or_example(task_file: str):
    """A task file, or the name of an installed example (when no such file exists)."""
    from pathlib import Path

    from sixplus3 import examples
    from sixplus3.planner.task import load_task

    if not Path(task_file).exists() and task_file in examples.names():
        return examples.load(task_file)
    return load_task(task_file)


def _run_plan(task, out_dir: str, rate: float, html: bool, locked: bool) -> None:
    from sixplus3.control.pipeline import run_plan
    from sixplus3.planner.ocp import PlannerOptions
    from sixplus3.progress import ConsoleProgress

    # quiet: no reporter at all, so the planner computes nothing for one
    reporter = ConsoleProgress() if _bars() else None
    try:
        res = run_plan(task, out_dir, _robot(), rate=rate, html=html,
                       options=PlannerOptions(lock_redundancy=locked), progress=reporter)
    finally:
        if reporter is not None:
            reporter.close()
    click.echo(f"done in {res.seconds['total']:.1f} s: {res.csv}")


@main.command()
@click.argument("task_file", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "out_dir", default="out", show_default=True,
              type=click.Path(file_okay=False), help="Output directory.")
@click.option("--rate", default=1000.0, show_default=True, help="Controller rate [Hz].")
@click.option("--no-html", is_flag=True, help="Skip the MeshCat page.")
@click.option("--locked", is_flag=True, help="Lock the crank angles at their home angles.")
@_verbosity
def plan(task_file: str, out_dir: str, rate: float, no_html: bool, locked: bool) -> None:
    """Plan TASK_FILE (YAML, or the name of an installed example such as tilt60_x):
    plan -> smooth -> validate -> the trajectory file, its MeshCat page and plots."""

    _check_rate(rate)
    task = _load_task_or_example(task_file)
    task.limits_for(_robot())  # a looser limit than the robot's: refused before solving
    _run_plan(task, out_dir, rate, not no_html, locked)


@main.command("move-to-start", context_settings=_NUMERIC_ARGS)
@click.argument("task_file", type=click.Path(dir_okay=False))
@click.option("--theta", nargs=9, type=float, required=True, metavar="A0 B0 C0 ... C2",
              help="The robot's current actuated angles [deg], legs 0..2 each A, B, C.")
@click.option("-o", "--out", "out_dir", default="out", show_default=True,
              help="Output directory.")
@click.option("--rate", default=1000.0, show_default=True, help="Controller rate [Hz].")
@_verbosity
def move_to_start_cmd(task_file: str, theta: tuple[float, ...], out_dir: str,
                      rate: float) -> None:
    """Plan from the robot's current state to a task's start state (at rest)."""
    import numpy as np

    from sixplus3.planner.task import move_to_start

    _check_rate(rate)
    if not all(math.isfinite(v) for v in theta):
        _fail(f"--theta must be 9 finite angles [deg], got {list(theta)}")
    task = move_to_start(_load_task_or_example(task_file), np.radians(theta), _robot())
    _run_plan(task, out_dir, rate, False, False)


@main.command()
@click.option("-o", "--out", "out_dir", default="out", show_default=True,
              type=click.Path(file_okay=False), help="Output directory.")
@_verbosity
def demo(out_dir: str) -> None:
    """Main job on built-in defaults: plan, smooth, validate and show a 30 deg tilt."""
    from sixplus3.control.pipeline import demo_task
    from sixplus3.planner.task import task_from_dict

    _run_plan(task_from_dict(demo_task(_robot())), out_dir, 1000.0, True, False)


def _emit(text: str, out_file: str | None) -> None:
    """``text`` to stdout, or atomically to ``out_file``."""
    if out_file is None:
        click.echo(text, nl=False)
        return
    from sixplus3.fileio import atomic_write

    atomic_write(out_file, text.encode())
    click.echo(f"wrote {out_file}", err=True)


def _task_robot(task_file: str | None) -> Robot:
    """The invocation's robot with a task file's setup (payload, tool, mounting)."""
    robot = _robot()
    if task_file is None:
        return robot
    from sixplus3.planner.task import load_task

    return load_task(task_file).robot_for(robot)


_gain_options = [
    click.option("--kp", default=300.0, show_default=True, type=float,
                 help="PD stiffness of the replay [N m/rad]."),
    click.option("--kd", default=6.0, show_default=True, type=float,
                 help="PD damping of the replay [N m s/rad]."),
]


def _gains(f):
    for opt in reversed(_gain_options):
        f = opt(f)
    return f


@main.command()
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--task", "task_file", default=None, type=click.Path(dir_okay=False),
              help="Apply this task file's setup (payload, tool, mounting) to the robot.")
@click.option("--simulate", "with_sim", is_flag=True,
              help="Also check in MuJoCo: its inverse dynamics against the file's torques, "
                   "and feed-forward + PD replay against the torque limit.")
@_gains
def validate(csv_file: str, as_json: bool, task_file: str | None, with_sim: bool,
             kp: float, kd: float) -> None:
    """Check a trajectory file independently of the planner (exit 0 only if all ok).

    Every check of docs/validation.md, against the robot's hardware limits, tightened by
    the limits the file records (a header can only make the gate stricter; a looser one
    is a forged file).  Exit codes: 0 a valid motion; 1 a limit is violated; 2 the file is missing,
    corrupted, made for another robot, or not a consistent motion (time grid, rest at
    the ends, jumps, platform columns, feed-forward torques).
    """
    global _FAST_EXIT
    # numba's OpenMP threads sleep between the forward kinematics' parallel loops instead
    # of spinning on the core the dynamics worker needs (0.95 -> 0.86 s, BENCHMARKS.md).
    # Read once, when numba first starts its threads: that is later, in validate_file.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    from sixplus3.control.validation import validate_file

    robot = _task_robot(task_file)
    rep = validate_file(csv_file, robot)
    from sixplus3.robot_description.limits import Limits

    limits = Limits(**rep.limits) if rep.limits else robot.limits
    out = {"file": csv_file, "duration_s": rep.duration, **rep.summary(),
           "feedforward_max_error": rep.feedforward_error}
    code = rep.exit_code
    eng = None
    if with_sim and code != 2:
        from sixplus3.control.simulation import engine_check

        eng = engine_check(robot, rep, kp, kd)
        out["mujoco"] = eng.summary()
        code = 2 if 2 in (code, eng.exit_code) else max(code, eng.exit_code)
    if as_json:
        click.echo(json.dumps(out, default=_json_default))
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
        lim_txt = ", ".join(f"{k} {v:.6g}" for k, v in limits.as_dict().items())
        click.echo(f"  judged by robot {robot.hash[:12]} at {rep.rate_hz:g} Hz, its hardware "
                   f"limits tightened by the file's: {lim_txt}")
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
    _FAST_EXIT = True
    sys.exit(code)


@main.command()
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("--task", "task_file", default=None, type=click.Path(dir_okay=False),
              help="Apply this task file's setup (payload, tool, mounting) to the robot.")
@click.option("--ff-scale", default=1.0, show_default=True, type=float,
              help="Scale the feed-forward torques by this factor, in [0, 2].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.option("--torque-hold", type=click.Choice(["sample", "mean"]), default="mean",
              show_default=True,
              help="Feed-forward held over each tick: the 'mean' of both ends' torques, "
                   "or the 'sample''s own.")
@_gains
def simulate(csv_file: str, task_file: str | None, ff_scale: float, as_json: bool,
             torque_hold: str, kp: float, kd: float) -> None:
    """Replay a trajectory file in MuJoCo at its rate: feed-forward + PD.

    The file is validated first (a defective file is not simulated: exit 2).  Reports
    the tracking error, the PD share of the torque and the peak total torque; exit 1 if
    that peak is over the hardware limit.
    """
    from sixplus3.control.simulation import simulate_file

    robot = _task_robot(task_file)
    rep, sim = simulate_file(csv_file, robot, kp, kd, ff_scale, torque_hold)
    if sim is None:
        what = "is not a valid motion" if rep.exit_code == 2 else "violates a limit"
        click.echo(f"refused: {csv_file} {what} (the gate's verdict; nothing simulated): "
                   + "; ".join(rep.messages())[:1500], err=True)
        sys.exit(rep.exit_code or 2)
    assert sim is not None
    if as_json:
        click.echo(json.dumps(sim.summary()))
    else:
        click.echo(f"{csv_file}: {sim.samples} ticks at {sim.rate_hz:g} Hz, Kp {kp:g}, "
                   f"Kd {kd:g}, feed-forward x{ff_scale:g} held per tick as "
                   f"'{sim.torque_hold}'; MuJoCo step {sim.timestep_s * 1e3:g} ms "
                   "(implicitfast)")
        click.echo(f"  tracking error: max {math.degrees(sim.max_tracking_error_rad):.4f} "
                   f"deg, rms {math.degrees(sim.rms_tracking_error_rad):.4f} deg, final "
                   f"{math.degrees(sim.final_tracking_error_rad):.4f} deg")
        click.echo(f"  PD share {100 * sim.pd_share:.2f}% (max |tau_PD| "
                   f"{sim.max_pd_torque:.3f} N m); peak |tau| commanded at the ticks "
                   f"{sim.peak_total_torque:.3f} N m "
                   f"(limit {sim.torque_limit:g}); closure residual "
                   f"{sim.max_closure_residual_m:.1e} m")
    sys.exit(0 if sim.within_torque_limit else 1)


@main.command("export")
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("--format", "fmt", required=True,
              type=click.Choice(["ros2-yaml", "ros2-json", "drive-csv", "rosbag2"]),
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
@click.option("--rate", "rate", default=None, type=float,
              help="ROS 2 forms: resample at this lower rate [Hz] (>= 10) on the gate's "
                   "quintic interpolant, validated again as an interpolated motion.")
@click.option("--goal", is_flag=True,
              help="ROS 2 forms: a control_msgs/action/FollowJointTrajectory goal "
                   "(for 'ros2 action send_goal').")
def export_cmd(csv_file: str, fmt: str, out_file: str | None, task_file: str | None,
               torque_hold: str | None, rate: float | None, goal: bool) -> None:
    """Export a trajectory file for the controller side, after validating it (exit 1
    for a violated limit, 2 for a bad file: nothing is written)."""
    from sixplus3.control.exports import export_file

    if fmt == "rosbag2":
        from sixplus3.control.rosbag import write_rosbag2

        if out_file is None:
            _fail("--format rosbag2 writes a directory: give it with -o DIR")
            return
        bag = write_rosbag2(csv_file, _task_robot(task_file), out_file)
        click.echo(f"wrote {bag} (ros2 bag play {bag})", err=True)
        return
    text = export_file(csv_file, _task_robot(task_file), fmt, torque_hold, rate, goal)
    _emit(text, out_file)


@main.command()
@click.argument("csv_file", type=click.Path(dir_okay=False))
@click.option("--udp", default="127.0.0.1:9870", show_default=True,
              help="IPv4:PORT of the controller.")
@click.option("--speed", default=1.0, show_default=True, type=float,
              help="Replay speed in [0.01, 1]: < 1 is a real retiming, validated again.")
@click.option("--dry-run", is_flag=True, help="Print the datagrams instead of sending.")
@click.option("--start-theta", nargs=9, type=float, default=None, metavar="A0 B0 C0 ... C2",
              help="The robot's current actuated angles [deg], legs 0..2 each A, B, C: the "
                   "file must start there, on the robot's assembly branch.")
@click.option("--torque-hold", type=click.Choice(["sample", "mean"]), default="mean",
              show_default=True,
              help="Feed-forward per tick: the 'mean' of the torques at both ends of the "
                   "tick the drive holds it over, or the 'sample''s own.")
def feed(csv_file: str, udp: str, speed: float, dry_run: bool,
         start_theta: tuple[float, ...] | None, torque_hold: str) -> None:
    """Send a trajectory file to the controller: read once, validate, send those samples.

    Exit codes: 0 sent; 1 a limit is violated; 2 bad input, a bad file, or a file that
    does not start at --start-theta (nothing sent).
    """
    from sixplus3.control.feed import check_speed, parse_address, prepare_feed, send, udp_sender

    address = parse_address(udp)
    check_speed(speed)
    current = None
    if start_theta is not None:
        if not all(math.isfinite(v) for v in start_theta):
            _fail(f"--start-theta must be 9 finite angles [deg], got {list(start_theta)}")
        import numpy as np

        current = np.radians(start_theta)
    plan = prepare_feed(csv_file, _robot(), speed, current_theta=current,
                        torque_hold=torque_hold)
    if current is None:
        click.echo("note: the robot's start state was not checked (--start-theta)", err=True)
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
def play(csv_file: str, html_out: str | None, no_wait: bool) -> None:
    """Animate a trajectory file in MeshCat (live; the URL is printed) or as HTML."""
    from pathlib import Path

    from sixplus3.control.trajectory_file import columns, read_trajectory
    from sixplus3.visualization.meshcat_player import (
        animate,
        frames_from_samples,
        viewer_url,
        write_html,
    )

    robot = _robot()
    _, data = read_trajectory(csv_file, robot)
    frames = frames_from_samples(robot, data[:, 0], data[:, 37:40], data[:, 40:44],
                                 data[:, 44:47], title=f"sixplus3: {Path(csv_file).stem}",
                                 theta_dot=columns(data, "vel"))
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


#: Set by a command whose process may end without the interpreter's teardown.
_FAST_EXIT = False


def run() -> None:
    """The ``sixplus3`` program (console entry point and ``python -m sixplus3.cli``).

    ``main`` with one difference: after a command that sets ``_FAST_EXIT`` (``validate``:
    it writes nothing and leaves no child or thread behind), the output is flushed and the
    process ends with ``os._exit``.  The interpreter's teardown of numba and LLVM would
    otherwise add ~0.08 s to every validation (measured in BENCHMARKS.md, "The gate").
    Tests that drive ``main`` in-process (click's CliRunner) never get here.
    """
    try:
        main()
    except SystemExit as exc:
        if not _FAST_EXIT:
            raise
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    run()
