"""The sixplus3 command line: arguments, JSON contract, exit codes, lazy imports."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from sixplus3.cli import main


def run(*args: str):
    return CliRunner().invoke(main, list(args))


def test_help_does_not_import_the_heavy_libraries() -> None:
    code = ("import sys; from sixplus3.cli import main\n"
            "heavy = [m for m in ('numpy', 'numba', 'pinocchio', 'casadi', 'meshcat', "
            "'matplotlib') if m in sys.modules]\n"
            "print(','.join(heavy))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == ""
    res = subprocess.run([sys.executable, "-m", "sixplus3.cli", "--help"],
                         capture_output=True, text=True, check=True)
    assert "leg" in res.stdout


def test_leg_accepts_negative_numbers_and_prints_a_report() -> None:
    """The printed report carries the numbers of the JSON form (the library's), and the
    torques add up to the moment of f about the actuated axis."""
    import re

    args = ["leg", "-0.1", "0.4", "0.2", "--force", "0", "-5", "0"]
    res = run(*args)
    assert res.exit_code == 0, res.output
    out = json.loads(run(*args, "--json").output)
    text = res.output

    def numbers(label: str) -> list[float]:
        line = next(ln for ln in text.splitlines() if ln.strip().startswith(label))
        return [float(x) for x in re.findall(r"[-+]\d+\.\d+(?:e[-+]\d+)?", line)]

    np.testing.assert_allclose(numbers("theta   [rad]"), out["theta"], atol=5e-7)
    np.testing.assert_allclose(numbers("theta   [deg]"), np.degrees(out["theta"]), atol=5e-4)
    tau = numbers("tau [N m]")
    np.testing.assert_allclose(tau, out["tau"], atol=5e-5)
    assert abs(sum(tau) - np.cross([-0.1, 0.4, 0.2], [0, -5, 0])[0]) < 2e-4
    tau_ext = float(re.search(r"tau_ext = ([0-9.]+) N m", text).group(1))
    assert tau_ext == pytest.approx(out["tau_ext"], abs=5e-5)
    # over the 10 N m limit, and said so
    assert tau_ext > 10.0 and "OVER the robot's 10 N m torque limit" in text
    assert f"singularity: {out['singularity']}" in text


def test_leg_json_contract_and_physics() -> None:
    p = np.array([-0.1, 0.4, 0.2])
    f = np.array([1.5, -5.0, 2.0])
    res = run("leg", *map(str, p), "--force", *map(str, f), "--json", "--mode", "++++")
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert {"theta", "theta_s", "det_J", "det_K", "singularity", "tau", "tau_ext"} <= set(out)
    assert len(out["theta"]) == 3 and len(out["theta_s"]) == 2 and len(out["tau"]) == 3
    assert out["singularity"] in ("none", "type1", "type2")
    # Collinear motors: the torques add up to the moment of f about the actuated axis.
    assert abs(sum(out["tau"]) - np.cross(p, f)[0]) < 1e-9
    assert isinstance(out["tau_ext"], float) and out["tau_ext"] > 0
    no_force = json.loads(run("leg", *map(str, p), "--json", "--mode", "++++").output)
    assert "tau" not in no_force and no_force["theta"] == out["theta"]


def test_leg_unreachable_exits_2_with_one_line() -> None:
    res = run("leg", "0", "1.5", "0")
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "RU chain" in lines[0]
    bad_mode = run("leg", "0", "0.4", "0.1", "--mode", "++x+")
    assert bad_mode.exit_code == 2 and "assembly mode" in bad_mode.output


def test_report_prints_the_leg_report() -> None:
    """The report's areas are the library's (design.workspace.usable_area in the robot's
    own reading) on the same grid, and each is a subset of the one before."""
    import re

    from sixplus3.design.report import reading_of
    from sixplus3.design.workspace import usable_area
    from sixplus3.robot_description.geometry import LegLoad
    from sixplus3.robot_description.robot import Robot

    res = run("report", "--ws-step", "0.02")
    assert res.exit_code == 0, res.output
    areas = [float(a) for a in re.findall(r"([0-9.]+) m\^2", res.output)]
    robot = Robot.default()
    rd = reading_of(robot.mode.name)
    want = usable_area(robot.leg, 0.02, robot.mode, LegLoad(torque_limit=10.0),
                       rd.theta_max, rd.theta_zero, rd.theta_direction)
    assert areas[:4] == pytest.approx([want.disk_area, want.reachable_area,
                                       want.theta_ok_area, want.usable_area], abs=6e-6)
    assert areas[0] >= areas[1] >= areas[2] >= areas[3] > 0.0


def test_robot_check_reports_the_model() -> None:
    res = run("robot", "check", "--json")
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert (out["nq"], out["nv"], out["actuated"], out["closures"]) == (37, 36, 9, 9)
    assert out["constraint_rank_home"] == 27 and out["mobility"] == 9
    assert out["home_residual_m"] < 1e-10 and out["committed_urdf_fresh"]
    assert out["margins"]["minimum"] > 0.1 and 1.0 < out["total_mass_kg"] < 3.0
    text = run("robot", "check")
    assert text.exit_code == 0 and "mobility 9" in text.output


def test_robot_ik_with_negative_numbers_and_json() -> None:
    res = run("robot", "ik", "0.05", "-0.02", "0.58", "-30", "0", "10", "--json")
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert len(out["theta"]) == 9 and len(out["tau_gravity"]) == 9
    assert out["residual"] < 1e-10
    assert set(out["margins"]) >= {"leg_type1", "leg_type2", "platform", "minimum"}
    red = json.loads(run("robot", "ik", "0.05", "-0.02", "0.58", "-30", "0", "10",
                         "--redundancy", "60", "100", "120", "--json").output)
    assert red["theta"] != out["theta"]  # the redundancy changes the actuated angles
    assert red["margins"]["platform"] != out["margins"]["platform"]


def test_robot_ik_unreachable_exits_2_naming_the_leg() -> None:
    res = run("robot", "ik", "0", "0", "1.2", "0", "0", "0")
    assert res.exit_code == 2
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "leg 0" in lines[0] and "RU chain" in lines[0]


def test_the_name_table_is_the_registries() -> None:
    """The CLI's light name table (issue 54, item 3) is each registry's keys, in order,
    and the help offers them."""
    from sixplus3.cli import names
    from sixplus3.control.formats.registry import FORMATS
    from sixplus3.design.readings import READINGS
    from sixplus3.robot_description.robot import NAMED_ROBOTS

    assert names.EXPORT_FORMATS == tuple(FORMATS)
    assert names.ROBOTS == tuple(NAMED_ROBOTS)
    assert names.READINGS == tuple(READINGS)
    import re

    def help_text(*args: str) -> str:  # unwrapped (click breaks lines at hyphens)
        out = CliRunner().invoke(main, [*args, "--help"]).output
        return re.sub(r"-\s+", "-", " ".join(out.split()))

    assert all(n in help_text("export") for n in names.EXPORT_FORMATS)
    assert all(n in help_text() for n in names.ROBOTS)
    assert all(n in help_text("design", "optimize") for n in names.READINGS)
