"""Named robots: the built default (the layout study's winner), the paper's assembly on
its stated layout, its mirror and the compact robot built before the study; tied to §V,
to the COW and to an independent distance function (docs/design.md, "Layout")."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from sixplus3.cli import main
from sixplus3.design.cow import compute_cow, deepest_point, home_in_cow
from sixplus3.design.readings import READINGS
from sixplus3.design.search import PAPER_DESIGN, Reading, design_grid, evaluate
from sixplus3.errors import GeometryError
from sixplus3.kinematics import collision
from sixplus3.kinematics.robot import home, robot_ik
from sixplus3.robot_description.robot import NAMED_ROBOTS, Robot

LINKS = ("AD", "DP", "BG", "GE", "CH", "HF")


def test_names_and_unknown_name() -> None:
    assert Robot.named("default") == Robot.default() == Robot()
    assert Robot.named(" Paper-as-stated ").mode.name == "++--"
    assert Robot.named("paper-as-stated").geometry.axis_turn == 0.0
    assert Robot.named("paper-mirror").mode.name == "-+++"
    assert Robot.named("compact").mode.name == "++++"
    d = Robot.default()
    assert d.mode.name == "++--" and math.degrees(d.geometry.axis_turn) == pytest.approx(28)
    with pytest.raises(GeometryError, match="one of"):
        Robot.named("nope")
    for name in NAMED_ROBOTS:
        r = Robot.named(name)
        lg = r.leg
        assert (lg.l2, lg.l4, lg.ex) == PAPER_DESIGN  # every named robot is the paper's design
        assert home(r).ok[0]


@pytest.mark.parametrize("name, theta_direction", [("paper-as-stated", -1), ("default", -1),
                                                   ("paper-mirror", 1)])
def test_the_leg_reproduces_the_design_study(name: str, theta_direction: int) -> None:
    """The leg, in its mode, with theta read from vertical (docs/conventions.md) and the
    paper's E = F (ey = 0, §IV), gives the area of the paper's design under the reading
    that reproduces §V's optimum; the layout does not enter the leg study."""
    r = Robot.named(name)
    reading = Reading(name=name, mode=r.mode.name, ey=0.0, theta_zero=-math.pi / 2,
                      theta_direction=theta_direction)
    area = evaluate(np.array([PAPER_DESIGN]), reading, design_grid(0.005, reading))[0][0]
    # the design study's "paper-match" reading (design.readings) is that reading: the
    # robot's leg and mode, read its way, give the same area to the grid's last bit
    match = READINGS["paper-match"]
    want = evaluate(np.array([PAPER_DESIGN]), match, design_grid(0.005, match))[0][0]
    assert area == pytest.approx(want, abs=1e-12) and area > 0.1
    spec = Reading()  # the compact robot's assembly under the same criterion: far less
    assert evaluate(np.array([PAPER_DESIGN]), spec, design_grid(0.005, spec))[0][0] < 0.01


def test_default_home_is_the_deepest_point_of_its_cow_of_at_least_15_litres() -> None:
    r = Robot.default()
    point, depth, volume = deepest_point(r, step=0.01)
    # the grid's cells straddle the central axis (centres at +-5 mm): home is on the axis
    assert abs(point[0]) <= 0.005 + 1e-9 and abs(point[1]) <= 0.005 + 1e-9
    assert abs(point[2] - r.home_position[2]) <= 0.01 + 1e-9
    assert depth >= 0.10 and volume >= 15.0
    compact = Robot.named("compact")
    assert volume > 5 * compute_cow(compact, step=0.01, z_step=0.01, extent=0.4, z_max=0.8,
                                    margin=0.05, z_min=0.0).volume("clear") * 1e3


def _sampled_clearance(caps: np.ndarray, radii: np.ndarray, n: int = 100) -> np.ndarray:
    """An independent distance function: each capsule's segment sampled at n points, the
    exact point-to-segment distance to the other body of every pair, minus the radii.  It
    over-estimates the pairs' clearance by at most half the sampling pitch."""
    s = np.linspace(0.0, 1.0, n)
    pa, pb = collision.PAIRS[:, 0], collision.PAIRS[:, 1]
    p0, p1 = caps[:, pa, 0][:, :, None], caps[:, pa, 1][:, :, None]  # (m, P, 1, 3)
    pts = p0 + s[None, None, :, None] * (p1 - p0)  # (m, P, n, 3)
    a0, a1 = caps[:, pb, 0][:, :, None], caps[:, pb, 1][:, :, None]
    d = a1 - a0
    t = np.clip(np.sum((pts - a0) * d, axis=-1) / np.maximum(np.sum(d * d, axis=-1), 1e-300),
                0.0, 1.0)
    dist = np.linalg.norm(pts - (a0 + t[..., None] * d), axis=-1).min(axis=2)
    return (dist - radii[pa] - radii[pb]).min(axis=1)


def test_no_contact_over_the_default_cow_by_an_independent_distance() -> None:
    """Over the default's whole interference-free 2 g COW (2 cm grid), the compiled
    clearance is >= 0, and dense point sampling of the capsules agrees with it: never
    below it (it is the exact minimum), at most half a sampling pitch above."""
    r = Robot.default()
    c = compute_cow(r, step=0.02, z_step=0.02, extent=0.4, z_max=0.8, margin=r.limits.margin,
                    z_min=0.02)
    Z, X, Y = np.nonzero(c.masks["clear"])
    pos = np.c_[c.xs[X], c.ys[Y], c.zs[Z]]
    assert len(pos) > 1000
    cfg = robot_ik(pos, np.eye(3), r.home_psi, r)
    exact = collision.clearance(cfg)
    assert exact.min() >= 0.0
    caps = collision.capsules(cfg)
    radii = collision.radii(r)
    longest = np.linalg.norm(caps[:, :, 1] - caps[:, :, 0], axis=-1).max()
    pairs_exact = collision._geometry_kernel.pair_distances(np.ascontiguousarray(caps), radii,
                                                            collision.PAIRS).min(axis=1)
    sampled = np.concatenate([_sampled_clearance(caps[k:k + 200], radii)
                              for k in range(0, len(caps), 200)])
    assert np.all(pairs_exact <= sampled + 1e-12)
    assert np.all(sampled - pairs_exact <= longest / 99 / 2 + 1e-12)
    # the platform is far above the base plate here: the pairs alone set the clearance
    np.testing.assert_allclose(exact, pairs_exact, rtol=0, atol=1e-12)


def _touching(cfg) -> set[tuple[str, str]]:
    caps = collision.capsules(cfg)
    out = set()
    for i, j in ((0, 1), (1, 2), (0, 2)):
        for a in range(6):
            for b in range(6):
                d = collision._geometry_kernel.segment_distance(
                    caps[0, 6 * i + a, 0], caps[0, 6 * i + a, 1], caps[0, 6 * j + b, 0],
                    caps[0, 6 * j + b, 1])
                if d < 1e-9:
                    out.add(tuple(sorted((LINKS[a], LINKS[b]))))
    return out


def test_the_paper_assemblies_interfere_the_built_one_does_not() -> None:
    """The finding that the layout study answers (docs/design.md)."""
    paper, mirror = home(Robot.named("paper-as-stated")), home(Robot.named("paper-mirror"))
    assert collision.clearance(paper)[0] < 0 and ("GE", "HF") in _touching(paper)
    assert collision.clearance(mirror)[0] < 0 and ("AD", "AD") in _touching(mirror)
    built = home_in_cow(Robot.default(), step=0.02)
    assert built.inside and built.depth >= 0.08
    for name in ("paper-as-stated", "paper-mirror"):
        r = Robot.named(name)
        c = compute_cow(r, step=0.02, z_step=0.02, extent=0.4, z_max=0.8,
                        margin=r.limits.margin, z_min=0.0)
        assert c.volume("clear") < 0.05 * c.volume("torque")
        assert not home_in_cow(r, step=0.02).inside


def test_cli_named_robot_and_bad_name() -> None:
    res = CliRunner().invoke(main, ["--robot", "paper-as-stated", "robot", "check", "--json"])
    assert res.exit_code == 1, res.output  # its home is outside its (empty) COW
    doc = json.loads(res.output)
    assert doc["assembly_mode"] == "++--" and doc["home_in_cow"]["failing"] == "clear"
    res = CliRunner().invoke(main, ["robot", "list"])
    assert res.exit_code == 0 and "paper-mirror" in res.output and "compact" in res.output
    res = CliRunner().invoke(main, ["--robot", "nope", "robot", "check"])
    assert res.exit_code == 2 and "named robot" in res.output and "Traceback" not in res.output


@pytest.mark.parametrize("doc, words", [
    ({"geometry": {"axis_turn": 0.0}}, ["overlap", "leg"]),  # the §V assembly, stated layout
    ({"geometry": {"axis_turn": float("nan")}}, ["axis_turn", "finite"]),
    ({"geometry": {"axis_turn": 1e9}}, ["axis_turn", "[-2 pi, 2 pi]"]),
    ({"collision": {"link_radius": 0.0}}, ["link_radius", "(0, 0.2]"]),
    ({"collision": {"hub_width": -0.01}}, ["hub_width", "(0, 0.2]"]),
    ({"collision": {"base_top": 0.1}}, ["base_top", "[-0.5, 0)"]),
])
def test_bad_layout_values_are_refused_in_one_line(doc, words, tmp_path) -> None:
    f = tmp_path / "robot.json"
    f.write_text(json.dumps(doc).replace("NaN", ".nan"))
    if "nan" in f.read_text():
        f = tmp_path / "robot.yaml"
        f.write_text("geometry:\n  axis_turn: .nan\n")
    res = CliRunner().invoke(main, ["--robot", str(f), "robot", "check"])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in res.output
    assert all(w in lines[0] for w in words), lines[0]


def test_a_robot_file_keeps_the_default_robots_values_and_round_trips(tmp_path) -> None:
    """`robot show --json` is the robot file format: read back, it is the same robot
    (its hash checked); a partial geometry keeps the default robot's leg and layout; an
    edited parameter under the old hash is refused, naming the key."""
    res = CliRunner().invoke(main, ["robot", "show", "--json"])
    f = tmp_path / "r.json"
    f.write_text(res.output)
    assert Robot.from_dict(json.loads(res.output)) == Robot.default()
    part = Robot.from_dict({"geometry": {"axis_turn": math.radians(25.0)}})
    assert part.leg == Robot.default().leg
    assert part.geometry.platform_phase == Robot.default().geometry.platform_phase
    doc = json.loads(res.output)
    doc["limits"]["torque"] = 9.5
    f.write_text(json.dumps(doc))
    bad = CliRunner().invoke(main, ["--robot", str(f), "robot", "show"])
    assert bad.exit_code == 2 and "hash" in bad.output and "Traceback" not in bad.output
