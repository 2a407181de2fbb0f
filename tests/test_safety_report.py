"""The safety report per plan (issue 70): every example planned for a hand (the legs
judged, the default), its report written by the command, opened in headless Chromium,
and its numbers the gate's: ``validate --json``'s record kept whole, the largest ratio
and where equal to it, the per-point forces the two-body model's of the gate's ratio,
and the stop table the one the gate recomputes."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
from browser import chromium
from click.testing import CliRunner

from sixplus3 import examples
from sixplus3.cli import main
from sixplus3.control.pipeline import run_plan
from sixplus3.robot_description.body_regions import REGIONS
from sixplus3.robot_description.robot import Robot

ROBOT = Robot.default()


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """Each example planned with ``pfl: [hand]`` and its safety report: (name, the
    file, the task file, the report's page and JSON, the command's exit code)."""
    out = tmp_path_factory.mktemp("reports")
    done = []
    for name in examples.names():
        task = dataclasses.replace(examples.load(name), pfl=("hand",))
        res = run_plan(task, out / "plans", ROBOT, html=False, plots=False)
        task_file = Path(examples.__file__).parent / f"{name}.yaml"
        r = CliRunner().invoke(main, ["safety-report", str(res.csv), "-o", str(out / name),
                                      "--task", str(task_file)])
        done.append((name, res.csv, task_file, out / name / f"{res.csv.stem}_safety.html",
                     out / name / f"{res.csv.stem}_safety.json", r))
    return done


def test_every_examples_report_is_written_and_its_numbers_are_the_gates(reports) -> None:
    assert len(reports) == len(examples.names()) >= 10
    for name, csv, task_file, page, js, r in reports:
        assert r.exit_code == 0, (name, r.output)
        assert page.exists() and js.exists(), name
        rep = json.loads(js.read_text())
        v = CliRunner().invoke(main, ["validate", str(csv), "--json", "--task", str(task_file)])
        record = json.loads(v.output)
        assert rep["validation"] == json.loads(json.dumps(record)), name
        assert rep["largest"]["ratio"] == record["max_pfl_ratio"] <= 1.0, name
        assert rep["largest"]["where"] == record["max_pfl_where"], name
        assert rep["coverage"]["regions"] == record["pfl"] == ["hand"]
        assert rep["coverage"]["leg links"] == record["pfl_links"] and \
            len(record["pfl_links"]) == 18 and rep["coverage"]["leg links not covered"] == []
        # the largest force: the two-body model's of the gate's ratio, 280 N x sqrt(ratio)
        lg = rep["largest"]
        assert lg["force [N]"] == pytest.approx(280.0 * np.sqrt(lg["ratio"]), rel=1e-9)
        # and it is the largest of the per-point forces along the path (5 digits there)
        forces = [max(f for f in d["regions"]["hand"]["force [N]"] if f is not None)
                  for d in rep["path"]["points"].values()]
        assert max(forces) == pytest.approx(lg["force [N]"], rel=1e-4), name
        assert set(rep["path"]["points"]) == set(rep["coverage"]["points"])
        assert len(rep["path"]["t"]) == record["samples"]
        st = rep["stop"]
        assert len(st["stop time [s]"]) == record["samples"] and st["max stop time [s]"] > 0
        assert st["file's table"].startswith("checked")
        assert 0 < st["max tcp distance [m]"] <= st["max distance [m]"] < 0.5, name
        # the detection's distance at the tool's speed comes on top of the stop's
        tcp_speed = rep["path"]["points"]["tcp"]["speed [m/s]"]
        k = int(np.argmax([x or 0.0 for x in tcp_speed]))
        assert st["tcp distance with detection [m]"][k] == pytest.approx(
            st["tcp distance [m]"][k] + st["detection assumed [s]"] * tcp_speed[k],
            rel=1e-3, abs=1e-6)
        assert st["detection assumed [s]"] == 0.010
        assert rep["guard"]["measured"][0]["source"].startswith("BENCHMARKS.md")


def test_every_examples_report_opens_in_chromium_and_shows_the_gates_numbers(
        reports, tmp_path) -> None:
    """The page as Chromium renders it: its plots decoded (one per region, the speeds,
    the stop), and the largest ratio, its place and the verdict as the JSON has them."""
    for name, _, _, page, js, _ in reports:
        rep = json.loads(js.read_text())
        dom = tmp_path / f"{name}.html"
        chromium(page, tmp_path, "--dump-dom", stdout=dom)
        text = dom.read_text()
        assert "The file passes the gate (exit code 0)" in text, name
        imgs = re.findall(r'<img alt="[^"]+" src="data:image/png;base64,', text)
        assert len(imgs) == 3, (name, len(imgs))
        table = re.search(r'<table class="largest">(.*?)</table>', text, re.S)
        assert table is not None, name
        cells = dict(re.findall(r"<th>(.*?)</th><td>(.*?)</td>", table.group(1)))
        assert float(cells["ratio (contact energy / ISO/TS 15066 limit)"]) == \
            pytest.approx(rep["largest"]["ratio"], rel=1e-5)
        assert cells["where"] == rep["largest"]["where"]
    shot = tmp_path / "shot.png"
    chromium(reports[0][3], tmp_path, "--window-size=1000,2400", f"--screenshot={shot}")
    import matplotlib.image as mpimg

    img = (mpimg.imread(shot)[:, :, :3] * 255).astype(int)
    blue = (img[..., 2] > 150) & (img[..., 0] < 80)  # the plots' first line (matplotlib C0)
    assert blue.sum() > 500, blue.sum()


def test_a_report_says_what_a_file_without_regions_does_not_cover(tmp_path) -> None:
    task = examples.load("tilt30_x")
    res = run_plan(task, tmp_path, ROBOT, html=False, plots=False)
    r = CliRunner().invoke(main, ["safety-report", str(res.csv)])
    assert r.exit_code == 0 and "no body region judged" in r.output, r.output
    rep = json.loads(Path(str(res.csv).replace(".csv", "_safety.json")).read_text())
    assert rep["coverage"]["regions"] == [] and "largest" not in rep
    assert rep["coverage"]["regions not covered"] == list(REGIONS)
    assert len(rep["coverage"]["leg links not covered"]) == 18
    # the speeds are shown at every point all the same: the tool and the 18 vertices
    assert len(rep["path"]["points"]) == 19 and "leg2_P" in rep["path"]["points"]
    assert max(v for v in rep["path"]["points"]["leg0_D"]["speed [m/s]"]) > 0.1
    bad = CliRunner().invoke(main, ["safety-report", str(tmp_path / "missing.csv")])
    assert bad.exit_code == 2 and "Traceback" not in bad.output
