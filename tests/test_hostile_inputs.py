"""Hostile inputs a fresh-machine audit found (issue 53.5): each gets one line and exit 2
(or a clear refusal), never an internal error (exit 3) and never a silent success."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from click.testing import CliRunner

from sixplus3.cli import main as cli
from sixplus3.errors import InputError, check_number
from sixplus3.identification.plants import perturbed_plant
from sixplus3.identification.report import robot_yaml
from sixplus3.robot_description import hardware
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()


pytestmark = pytest.mark.usefixtures("catalogue_hardware")  # tests/conftest.py


def _run(args: list[str], env: dict | None = None):
    return CliRunner().invoke(cli, args, env=env)


def _one_line_exit_2(res) -> None:
    assert res.exit_code == 2, res.output
    assert "internal error" not in res.output and "Traceback" not in res.output
    assert len(res.output.strip().splitlines()) == 1, res.output


@pytest.mark.parametrize("byte", [b"\x00", b"\x07", b"\x1b", b"\x7f", b"\x0c"])
@pytest.mark.parametrize("kind", ["robot", "task", "site"])
def test_a_raw_control_byte_in_a_yaml_file(tmp_path, byte, kind) -> None:
    path = tmp_path / "f.yaml"
    if kind == "robot":
        path.write_bytes(b"masses: {platform: 0.3}" + byte + b"\n")
        res = _run(["--robot", str(path), "robot", "show"])
    elif kind == "task":
        path.write_bytes(b"name: t" + byte + b"\nwaypoints:\n  - position: [0, 0, 0.58]\n")
        res = _run(["plan", str(path), "-o", str(tmp_path / "o"), "--no-html"])
    else:
        path.write_bytes(b"people: collaborative" + byte + b"\n")
        res = _run(["--hardware", str(path), "robot", "show"])
    _one_line_exit_2(res)
    assert f"{byte[0]:#04x}" in res.output and "line 1" in res.output
    assert not (tmp_path / "o").exists()


def test_a_name_holding_a_raw_escape_byte(tmp_path) -> None:
    path = tmp_path / "r.yaml"
    path.write_bytes(b'name: "a\x1bb"\n')
    _one_line_exit_2(_run(["--robot", str(path), "robot", "show"]))


def test_the_filter_cut_off_has_a_floor() -> None:
    from sixplus3.control.file.drive_log import DriveLog
    from sixplus3.identification.signals import LOWEST_CUTOFF, choose_cutoff

    n = 4000
    log = DriveLog(t=np.arange(n) / 1000.0, theta=np.zeros((n, 9)), tau=np.zeros((n, 9)))
    for bad in (1e-9, 0.0, -3.0, math.nan, math.inf):
        with pytest.raises(InputError, match=re.escape(f"[{LOWEST_CUTOFF:g}, inf]")):
            choose_cutoff(log, bad)
    assert choose_cutoff(log, 20.0) == 20.0


def test_the_prior_weight_is_bounded() -> None:
    """1e300 once wrote exactly the nominal robot, saying nothing: the log was ignored."""
    from sixplus3.identification.base import base_parameters
    from sixplus3.identification.estimate import MAX_PRIOR_WEIGHT, consistent

    base = base_parameters(ROBOT)
    W, tau = np.zeros((4, base.rank)), np.zeros(4)
    for bad in (1e300, 0.0, -1.0, math.nan, 10 * MAX_PRIOR_WEIGHT):
        with pytest.raises(InputError, match="the prior weight must be"):
            consistent(W, tau, np.ones(4), base, np.zeros(base.layout.size), bad)


@pytest.mark.parametrize("factor", ["0", "0.5", "-1", "11", "nan"])
def test_plant_friction_is_a_factor_of_at_least_one(tmp_path, factor) -> None:
    out = tmp_path / "p.yaml"
    res = _run(["identify", "plant", "-o", str(out), "--friction", factor])
    _one_line_exit_2(res)
    assert not out.exists()
    if factor in ("0", "0.5"):
        assert "[1, 10]" in res.output


@pytest.mark.parametrize("seed", [-1, 2 ** 40])
def test_a_seed_out_of_range(tmp_path, seed) -> None:
    from sixplus3.control.drive.plant import run_on_plant

    with pytest.raises(InputError, match="seed must be an integer"):
        run_on_plant(tmp_path / "none.csv", ROBOT, ROBOT, seed=seed)
    with pytest.raises(InputError, match="seed must be an integer"):
        perturbed_plant(ROBOT, seed)
    _one_line_exit_2(_run(["identify", "plant", "-o", str(tmp_path / "p.yaml"), "--seed",
                           str(seed)]))


def test_check_number_is_the_one_range_check() -> None:
    assert check_number("x", 2, 0, 3) == 2.0 and check_number("x", np.float32(1.5), 0, 3) == 1.5
    assert check_number("n", np.int64(4), 0, 9, integer=True) == 4
    for bad in (True, "1", None, math.nan, math.inf, -0.1, 3.1, [1.0]):
        with pytest.raises(InputError, match=re.escape("x must be a number in [0, 3]")):
            check_number("x", bad, 0, 3)
    with pytest.raises(InputError, match=re.escape("(0, 3]")):
        check_number("x", 0.0, 0, 3, lo_open=True)
    with pytest.raises(InputError, match="an integer"):
        check_number("n", 1.5, 0, 9, integer=True)


# ----------------------------------------------------------------- $SIXPLUS3_HARDWARE
@pytest.mark.parametrize("what", ["raising", "missing", "directory", "not yaml"])
@pytest.mark.parametrize("command", [["robot", "show"], ["robot", "check"]])
def test_the_environments_site_file_counts_for_every_command(tmp_path, what, command) -> None:
    path = tmp_path / "site.yaml"
    if what == "raising":
        path.write_text("limits: {torque: 12}\n")
    elif what == "directory":
        path.mkdir()
    elif what == "not yaml":
        path.write_text("limits: {torque: 8\n")
    env = {hardware.ENV: str(path)}
    _one_line_exit_2(_run(command, env=env))
    # the same file through --hardware: the same answer
    assert _run(["--hardware", str(path), *command]).exit_code == 2


def test_robot_show_prints_the_limits_in_force(tmp_path) -> None:
    site = tmp_path / "site.yaml"
    site.write_text("limits: {torque: 8}\n")
    for res in (_run(["robot", "show"], env={hardware.ENV: str(site)}),
                _run(["--hardware", str(site), "robot", "show"])):
        assert res.exit_code == 0, res.output
        assert "in force: torque 8 N m" in res.output and "site file site.yaml" in res.output
    plain = _run(["robot", "show"], env={hardware.ENV: ""})
    assert "in force: torque 10 N m" in plain.output and "catalogue" in plain.output


# ----------------------------------------------------------------- robot files
def _edit(text: str, key: str, new: str) -> str:
    out, n = re.subn(key + r": \[[^\]]*\]", f"{key}: {new}", text, count=1, flags=re.S)
    assert n == 1, key
    return out


def _identified_like() -> str:
    """A robot file as `identify estimate` writes one (every body and joint measured)."""
    return robot_yaml(perturbed_plant(ROBOT, 3), "as identification writes it")


@pytest.mark.parametrize("case", ["negative mass", "unphysical inertia", "zero rotor",
                                  "negative rotor", "nan viscous", "nan coulomb",
                                  "negative catalogue rotor"])
def test_a_hostile_identified_robot_file(tmp_path, case) -> None:
    text = _identified_like()
    path = tmp_path / "r.yaml"
    path.write_text(text)
    assert _run(["--robot", str(path), "robot", "show"]).exit_code == 0  # as written
    nines = lambda first: "[" + ", ".join([first] + ["0.02"] * 8) + "]"  # noqa: E731
    if case == "negative mass":
        text = re.sub(r"(leg0_body:\n    mass: )", r"\1-", text, count=1)
    elif case == "unphysical inertia":  # principal moments break the triangle inequality
        text = re.sub(r"(leg0_body:\n    mass: [^\n]*\n    com: [^\n]*\n    inertia: )\[",
                      r"\1[1.0, 0.001, 0.001, ", text, count=1)
        text = re.sub(r"(inertia: \[1\.0, 0\.001, 0\.001, )[^,]*, [^,]*, [^,\]]*,",
                      r"\1", text, count=1, flags=re.S)
    elif case == "zero rotor":
        text = _edit(text, "joint_armature", nines("0.0"))
    elif case == "negative rotor":
        text = _edit(text, "joint_armature", nines("-0.01"))
    elif case == "nan viscous":
        text = _edit(text, "joint_viscous", nines(".nan"))
    elif case == "nan coulomb":
        text = _edit(text, "joint_coulomb", nines(".nan"))
    else:
        text = text.replace("rotor_inertia: ", "rotor_inertia: -", 1)
    assert text != path.read_text()
    path.write_text(text)
    res = _run(["--robot", str(path), "robot", "show"])
    _one_line_exit_2(res)
    assert "invalid robot parameter" in res.output


# ----------------------------------------------------------- issue 69, item 6
@pytest.mark.parametrize("doc", [{"region": ["hand"], "at": 0.1},
                                 {"region": {"hand": 1}, "at": 0.1},
                                 {"region": "hand", "kind": ["clamp"], "at": 0.1},
                                 {"region": "hand", "point": {"a": 1}, "at": 0.1}])
def test_a_contact_file_with_a_list_or_mapping_for_a_name(tmp_path, doc) -> None:
    """Session 34: ``region: [hand]`` or ``region: {hand: 1}`` exited 3 (a list is not a
    key).  Now one line, exit 2, naming the valid regions."""
    import yaml

    from sixplus3.control.drive.person import contact_from_dict, read_contact

    with pytest.raises(InputError, match="must be one of|must be free or clamp"):
        contact_from_dict(doc)
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(InputError):
        read_contact(path)


def _log(tmp_path, step: float):
    from sixplus3.control.file.drive_log import DriveLog, write_log
    from sixplus3.kinematics.robot import home

    n = 300
    th = np.repeat(home(ROBOT).theta, n, axis=0)
    log = DriveLog(t=np.arange(n) * step, theta=th, tau=np.zeros((n, 9)))
    path = tmp_path / "log.csv"
    write_log(path, log, ROBOT)
    return path


def test_teach_on_a_log_of_an_absurd_time_step(tmp_path) -> None:
    """Session 34: a log whose time step is 1e-25 s made ``teach`` exit 3 (an overflow).
    Now one line, exit 2, with the drive log's range of steps."""
    try:
        path = _log(tmp_path, 1e-25)
    except InputError:
        return  # the log's own reader or writer refuses it: as good
    res = _run(["teach", str(path), "-o", str(tmp_path / "t.yaml")])
    _one_line_exit_2(res)
    assert "time step" in res.output or "rate" in res.output, res.output


def test_teach_with_an_empty_pfl_is_refused_as_plan_refuses_it(tmp_path) -> None:
    """Session 34: ``teach --pfl ''`` silently wrote a task without PFL, where
    ``plan --pfl ''`` refuses.  Now both refuse, and nothing is written."""
    path = _log(tmp_path, 1e-3)
    out = tmp_path / "t.yaml"
    res = _run(["teach", str(path), "-o", str(out), "--pfl", ""])
    _one_line_exit_2(res)
    assert "--pfl names no body region" in res.output and not out.exists()
    res = _run(["plan", "gentle_translate", "-o", str(tmp_path / "p"), "--pfl", ""])
    assert res.exit_code == 2 and "--pfl names no body region" in res.output


@pytest.mark.parametrize("kwargs,name", [({"speed": None}, "speed"),
                                         ({"acceleration": 2.0}, "acceleration"),
                                         ({"speed": "ab"}, "speed"),
                                         ({"model_sigma": math.nan}, "model_sigma"),
                                         ({"monitor_noise": -1.0}, "monitor_noise")])
def test_lead_through_settings_are_refused_by_name(kwargs, name) -> None:
    """Session 34: ``speed=None`` and ``acceleration=2.0`` raised raw TypeErrors;
    ``model_sigma=nan`` and ``monitor_noise=-1`` were accepted."""
    from sixplus3.interaction.lead.leadthrough import LeadThrough

    with pytest.raises(InputError, match=name):
        LeadThrough(ROBOT, 1000.0, **kwargs)


@pytest.mark.parametrize("cov", ["abc", (1, 2, 3), None, ("x", "y"), "asym", "negative"])
def test_a_bad_parameter_covariance_is_an_input_error(cov) -> None:
    """Session 34: a bad ``parameter_cov`` gave a raw ValueError.  Now an InputError
    naming what is expected: two arrays, of the robot's base, symmetric PSD."""
    from sixplus3.identification.base import base_parameters
    from sixplus3.interaction.observer.wrench import checked_covariance

    base = base_parameters(ROBOT)
    if cov in ("asym", "negative"):
        m = np.eye(base.rank)
        if cov == "asym":
            m[0, 1] = 1.0
        else:
            m[0, 0] = -1.0
        cov = (base.index, m)
    with pytest.raises(InputError, match="parameter"):
        checked_covariance(ROBOT, cov)


def test_a_hand_file_with_a_long_path_is_no_alias_bomb(tmp_path) -> None:
    """Session 34: a hand file whose path was long (written out, no alias) was refused
    as an "alias bomb".  Within the file size cap it is read; a real alias bomb is still
    refused."""
    from sixplus3.control.drive.hand import read_hand

    n = 12_000  # 12 s of a 1 kHz hand path: ~110 000 values
    lines = ["stiffness: 400", "damping: 10", "duration: 12.0", "path:"]
    lines += [f"  - {{t: {k / 1000:.3f}, offset: [{1e-5 * k:.5f}, 0, 0]}}" for k in range(n)]
    path = tmp_path / "hand.yaml"
    path.write_text("\n".join(lines) + "\n")
    hand = read_hand(path)
    assert hand.duration == 12.0
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n"
                    + "".join(f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
                              for p, c in zip("abcdef", "bcdefg", strict=True)))
    with pytest.raises(InputError, match="alias"):
        read_hand(bomb)
