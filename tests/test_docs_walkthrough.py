"""The documented commands, run as a lab's first day runs them (issue 53): the short
form of scripts/docs_walkthrough.py (a shorter excitation and a coarser resolution map;
everything else with the documented defaults) ends with the exit code the docs give
every command."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def test_every_documented_command_runs(tmp_path) -> None:
    pytest.importorskip("mujoco")
    script = Path(__file__).parents[1] / "scripts" / "docs_walkthrough.py"
    out = subprocess.run([sys.executable, str(script), "--short", "--json", "-o",
                          str(tmp_path / "walk")], capture_output=True, text=True,
                         check=False, timeout=1800)
    rows = json.loads(out.stdout)
    bad = [(r["command"], r["exit"], r["last_line"]) for r in rows
           if r["exit"] not in r["expected"]]
    assert not bad and out.returncode == 0, bad
    assert [r["command"] for r in rows][:4] == ["robot check", "plan gentle_translate",
                                                "validate", "identify excite"]
    assert len(rows) == 19
    # what the lab gets: the identified robot file, the wrench, the zeroed robot
    # (check, wrench and commission directions end with os._exit: their output and files
    # must be whole)
    for name in ("identified.yaml", "wrench.csv", "wrench.png", "zeroed.yaml",
                 "ident/report/summary.json", "taught.yaml", "taught/taught.csv"):
        assert (tmp_path / "walk" / name).exists(), name
    lines = [ln for ln in (tmp_path / "walk" / "wrench.csv").read_text().splitlines()
             if ln and not ln.startswith("#")]
    assert len(lines) > 1000 and lines[-1].count(",") == lines[0].count(","), lines[-1]
    check = next(r for r in rows if r["command"] == "identify check")
    assert "n/a" in check["last_line"] or "per joint" in check["last_line"], check
