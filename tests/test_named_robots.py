"""Named robots: the built default and the paper's §V assembly, tied to §V and to the
COW (docs/design.md, "Which robot is the paper's")."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy import ndimage

from sixplus3.cli import main
from sixplus3.design.cow import compute_cow, home_in_cow
from sixplus3.design.search import PAPER_DESIGN, Reading, design_grid, evaluate
from sixplus3.errors import GeometryError
from sixplus3.kinematics.robot import _segment_distance, home, leg_clearance, leg_segments
from sixplus3.robot_description.robot import NAMED_ROBOTS, Robot

LINKS = ("AD", "DP", "BG", "GE", "CH", "HF")


def test_names_and_unknown_name() -> None:
    assert Robot.named("default") == Robot.default()
    assert Robot.named(" Paper ").mode.name == "++--"
    assert Robot.named("paper-mirror").mode.name == "-+++"
    with pytest.raises(GeometryError, match="one of"):
        Robot.named("nope")
    for name in NAMED_ROBOTS:
        r = Robot.named(name)
        lg = r.leg
        assert (lg.l2, lg.l4, lg.ex) == PAPER_DESIGN  # every named robot is the paper's design
        assert home(r).ok[0]


@pytest.mark.parametrize("name, theta_direction", [("paper", -1), ("paper-mirror", 1)])
def test_paper_assembly_reproduces_the_design_study(name: str, theta_direction: int) -> None:
    """Its leg, in its mode, with theta read from vertical (docs/conventions.md), gives the
    area of the paper's design under the reading that reproduces §V's optimum."""
    r = Robot.named(name)
    reading = Reading(name=name, mode=r.mode.name, ey=r.leg.ey, theta_zero=-math.pi / 2,
                      theta_direction=theta_direction)
    area = evaluate(np.array([PAPER_DESIGN]), reading, design_grid(0.005, reading))[0][0]
    assert area == pytest.approx(0.1172, abs=0.002)
    spec = Reading()  # the built robot's assembly under the same criterion: far less
    assert evaluate(np.array([PAPER_DESIGN]), spec, design_grid(0.005, spec))[0][0] < 0.01


def test_paper_home_is_the_deepest_point_of_its_2g_cow() -> None:
    r = Robot.named("paper")
    c = compute_cow(r, step=0.02, z_step=0.01, extent=0.4, z_max=0.8, margin=r.limits.margin,
                    z_min=0.0)
    depth = ndimage.distance_transform_edt(c.masks["torque"], sampling=(0.01, 0.02, 0.02))
    i = int(np.argmin(np.abs(c.xs)))
    k = int(np.argmax(depth[:, i, i]))
    assert abs(c.zs[k] - r.home_position[2]) <= 0.02
    assert c.volume("torque") > 5 * compute_cow(Robot.default(), step=0.02, z_step=0.01,
                                                 extent=0.4, z_max=0.8, margin=0.05,
                                                 z_min=0.0).volume("torque")


def _touching(cfg) -> set[tuple[str, str]]:
    seg = leg_segments(cfg)
    out = set()
    for i, j in ((0, 1), (1, 2), (0, 2)):
        for a in range(6):
            for b in range(6):
                d = _segment_distance(seg[:, i, a, 0], seg[:, i, a, 1], seg[:, j, b, 0],
                                      seg[:, j, b, 1])[0]
                if d < 1e-9:
                    out.add(tuple(sorted((LINKS[a], LINKS[b]))))
    return out


def test_the_paper_assemblies_interfere_the_built_one_does_not() -> None:
    """The finding that keeps the default robot in mode ++++ (docs/design.md)."""
    paper, mirror = home(Robot.named("paper")), home(Robot.named("paper-mirror"))
    assert leg_clearance(paper)[0] < 0 and ("GE", "HF") in _touching(paper)
    assert leg_clearance(mirror)[0] < 0 and ("AD", "AD") in _touching(mirror)
    built = home_in_cow(Robot.default(), step=0.02)
    assert built.inside and built.depth >= 0.02
    for name in ("paper", "paper-mirror"):
        r = Robot.named(name)
        c = compute_cow(r, step=0.02, z_step=0.02, extent=0.4, z_max=0.8,
                        margin=r.limits.margin, z_min=0.0)
        assert c.volume("clear") < 0.05 * c.volume("torque")
        assert not home_in_cow(r, step=0.02).inside


def test_cli_named_robot_and_bad_name() -> None:
    res = CliRunner().invoke(main, ["--robot", "paper", "robot", "check", "--json"])
    assert res.exit_code == 1, res.output  # its home is outside its (empty) COW
    doc = json.loads(res.output)
    assert doc["assembly_mode"] == "++--" and doc["home_in_cow"]["failing"] == "clear"
    res = CliRunner().invoke(main, ["robot", "list"])
    assert res.exit_code == 0 and "paper-mirror" in res.output
    res = CliRunner().invoke(main, ["--robot", "nope", "robot", "check"])
    assert res.exit_code == 2 and "named robot" in res.output and "Traceback" not in res.output
