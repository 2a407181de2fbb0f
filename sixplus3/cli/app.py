"""The ``sixplus3`` command line: the root group, its error handling and the helpers
every command group shares (the command groups are the other modules of this package).

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

import math
import os
import sys
from typing import TYPE_CHECKING, Any

import click

from sixplus3.cli.names import ROBOTS

if TYPE_CHECKING:
    from sixplus3.robot_description.robot import Robot

# Negative numbers are positional values here (``sixplus3 leg -0.1 0.4 0.2``): let click
# pass tokens such as ``-0.1`` through instead of treating them as unknown options.
NUMERIC_ARGS = {"ignore_unknown_options": True, "help_option_names": ["-h", "--help"]}


def fail(message: str) -> None:
    """One-line error on stderr, exit code 2."""
    click.echo(f"error: {message}", err=True)
    sys.exit(2)


def json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(type(obj))


def finite_json(value: float) -> float | None:
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
            fail(" ".join(str(exc).split())[:2000])
        except OSError as exc:  # an output path that cannot be written, a full disk
            fail(f"{exc.strerror or exc}: {exc.filename or ''}"[:2000])
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
              help=f"A named robot ({', '.join(ROBOTS)}: "
              "'sixplus3 robot list') or a file of robot parameters (YAML/JSON, keys as in "
              "'sixplus3 robot show --json'; missing keys keep the defaults). Default: the "
              "built robot ('default').")
@click.option("--hardware", "hardware_file", default=None, metavar="FILE",
              help="The site hardware file (YAML/JSON: drive_train, people, limits): the "
              "envelope no robot, task or trajectory file can raise (docs/validation.md, "
              "'The envelope'). Default: $SIXPLUS3_HARDWARE, else the built-in catalogue.")
@click.pass_context
def main(ctx: click.Context, robot_file: str | None, hardware_file: str | None) -> None:
    """sixplus3: kinematics, dynamics, design and planning for the (6+3)-DoF robot."""
    from sixplus3 import progress
    from sixplus3.robot_description import hardware

    progress.set_level(progress.NORMAL)  # before a subcommand's --quiet / --verbose
    ctx.obj = {"robot_file": robot_file}
    hardware.use(None)
    if hardware_file is None:  # $SIXPLUS3_HARDWARE, read here for every command
        hardware_file = os.environ.get(hardware.ENV) or None
    if hardware_file is not None:  # an unreadable or raising file: exit 2 (_Group)
        hardware.use(hardware.load_hardware(hardware_file))


def bars() -> bool:
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


def verbosity(f: Any) -> Any:
    """``--quiet`` / ``--verbose`` (:mod:`sixplus3.progress`) on a long-running command."""
    f = click.option("-v", "--verbose", is_flag=True, expose_value=False, is_eager=True,
                     callback=_set_level,
                     help="Also one line per IPOPT iteration (duration, violation).")(f)
    return click.option("-q", "--quiet", is_flag=True, expose_value=False, is_eager=True,
                        callback=_set_level,
                        help="No progress: no compile notice, stages or bars; only results "
                             "and errors.")(f)


def check_png(out_path: str | None, option: str) -> None:
    """Refuse (exit 2) a picture's path that does not end in .png: the command writes a
    PNG, and a PNG under another name (``--plot x.txt``) is a file its user cannot
    open."""
    if out_path is not None and not out_path.lower().endswith(".png"):
        fail(f"{option} writes a PNG: give a file name ending in .png, got {out_path!r}")


def check_output(out_path: str | None, inputs: tuple[str | None, ...] = (),
                 force: bool = False) -> None:
    """Refuse (exit 2) an output that is one of the command's inputs (the same path or
    the same file through a link), or, without ``force``, an existing trajectory file:
    no command replaces what it reads, or a validated trajectory, by another kind of
    file.  The invocation's ``--robot`` file counts as an input of every command."""
    if out_path is None:
        return
    ctx = click.get_current_context(silent=True)
    robot_file = ((ctx.find_root().obj or {}).get("robot_file") if ctx is not None
                  else None)
    for src in (*inputs, robot_file):
        if src is None or not os.path.exists(src) or not os.path.exists(out_path):
            continue
        try:
            same = os.path.samefile(src, out_path)
        except OSError:
            same = False
        if same:
            fail(f"{out_path} is this command's input {src}: write the output elsewhere")
    if force or not os.path.isfile(out_path):
        return
    from sixplus3.control.file.file_format import FORMAT

    try:
        with open(out_path, "rb") as fh:
            head = fh.read(200)
    except OSError:
        return
    if FORMAT.encode() in head:
        fail(f"{out_path} is a trajectory file ({FORMAT}); it is not replaced by another "
             "kind of file unless you add --force")


def emit(text: str, out_file: str | None, inputs: tuple[str | None, ...] = (),
         force: bool = False) -> None:
    """``text`` to stdout, or atomically to ``out_file`` (:func:`check_output` first)."""
    if out_file is None:
        click.echo(text, nl=False)
        return
    check_output(out_file, inputs, force)
    from sixplus3.fileio import atomic_write

    atomic_write(out_file, text.encode())
    click.echo(f"wrote {out_file}", err=True)


# click >= 8.2 types ParamType as a generic; the bound (click>=8.1) keeps older ones
class _StrictNumber(click.ParamType):  # type: ignore[type-arg]
    """A number on the command line in the files' one strict decimal grammar
    (:data:`sixplus3.control.file.trajectory_parse.NUMBER`: no '1_000', 'inf', 'nan', '0x10')."""

    def __init__(self, integer: bool) -> None:
        self.integer = integer
        self.name = "integer" if integer else "number"

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        import re

        from sixplus3.control.file.trajectory_parse import NUMBER

        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return int(value) if self.integer else float(value)
        text = str(value).strip()
        grammar = r"-?(?:0|[1-9][0-9]*)" if self.integer else NUMBER
        from sixplus3.errors import InputError

        where = (param.opts[0] if param is not None and param.opts else "a number")
        if param is not None and param.param_type_name == "argument":
            where = (param.name or "argument").upper()
        if not re.fullmatch(grammar, text):
            # an InputError, not click's usage text: one line, exit 2 (_Group.invoke)
            raise InputError(f"{where}: {text[:40]!r} is not "
                             f"{'an integer' if self.integer else 'a number'} (decimal "
                             "digits, an optional '-', '.' and exponent: e.g. "
                             f"{'1000' if self.integer else '-0.25 or 1e3'})",
                             value=text[:40], valid="a decimal number")
        out = int(text) if self.integer else float(text)
        if not self.integer and not math.isfinite(out):
            raise InputError(f"{where}: {text[:40]!r} is too large", value=text[:40],
                             valid="a finite number")
        return out


#: The CLI's number types (every numeric option and argument).
FLOAT = _StrictNumber(integer=False)
INT = _StrictNumber(integer=True)


def current_robot() -> Robot:
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
            fail(f"--robot {path!r} is neither a named robot (one of "
                 f"{', '.join(NAMED_ROBOTS)}) nor an existing robot file")
        else:
            from sixplus3.kinematics.collision import check_layout
            from sixplus3.robot_description.hardware import check_robot_within

            obj["robot"] = load_robot(path)
            check_layout(obj["robot"])  # a robot file must describe a buildable robot
            check_robot_within(obj["robot"])  # nor raise the site's envelope
    return obj["robot"]


#: Set by a command whose process may end without the interpreter's teardown.
def task_robot(task_file: str | None) -> Robot:
    """The invocation's robot with a task file's setup (payload, tool, mounting)."""
    robot = current_robot()
    if task_file is None:
        return robot
    from sixplus3.planner.task import load_task

    return load_task(task_file).robot_for(robot)


def _site_gain(ctx: click.Context, param: click.Parameter, value: float | None) -> float:
    """A gain not given: the site's declared position loop's (--hardware), else the
    default drive's (300 / 6)."""
    if value is not None:
        return value
    from sixplus3.control.drive.loop import KD, KP  # deferred: the CLI starts light
    from sixplus3.robot_description import hardware  # deferred: the CLI starts light

    loop = hardware.active().position_loop
    if loop is None:
        return KP if param.name == "kp" else KD
    return loop.kp if param.name == "kp" else loop.kd


_gain_options = [
    click.option("--kp", default=None, type=FLOAT, callback=_site_gain,
                 help="PD stiffness of the replay [N m/rad]. Default: the site's "
                      "position_loop (--hardware), else 300."),
    click.option("--kd", default=None, type=FLOAT, callback=_site_gain,
                 help="PD damping of the replay [N m s/rad]. Default: the site's "
                      "position_loop, else 6."),
]


def drive_gains(f: Any) -> Any:
    """The drive's PD options (--kp, --kd) of a command that replays on a drive."""
    for opt in reversed(_gain_options):
        f = opt(f)
    return f


_FAST_EXIT = False


def request_fast_exit() -> None:
    """Let :func:`run` end this process with ``os._exit`` after the command (a command
    whose files are written and closed before it returns and that leaves no child or
    thread behind: ``validate``, ``identify check``, ``wrench``, ``commission
    directions``).  The interpreter's teardown of numba, LLVM, Pinocchio and CasADi
    costs 0.2 s, a fifth of ``identify check`` on a 1 s log."""
    global _FAST_EXIT
    _FAST_EXIT = True


def run() -> None:
    """The ``sixplus3`` program (console entry point and ``python -m sixplus3.cli``).

    ``main`` with one difference: after a command that sets ``_FAST_EXIT``
    (:func:`request_fast_exit`), the output is flushed and the
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

