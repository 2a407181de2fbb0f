"""Run every command README.md, docs/identification.md, docs/interaction.md and
docs/commissioning.md show, in the order a lab's first day takes them, with their
defaults, on the virtual prototype; print each command's exit code, wall and CPU time,
and the length of the log it read (issue 53: "a lab's first day would stop at the first
step of identification").

    .venv/bin/python scripts/docs_walkthrough.py [-o out/walkthrough] [--short] [--json]

``--short`` (what CI runs, tests/test_docs_walkthrough.py): the excitation at
``--duration 3 --candidates 4`` and the slow map of ``wrench-resolution`` at
``--step 0.03``; everything else as documented.  Exit 0 when every command ended with
the exit code the docs give it, 1 otherwise.
"""

from __future__ import annotations

import argparse
import csv
import json
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

#: Whether a row's figure is "the log's length" (a command that reads a log).
LOG_OF = {"identify estimate": "exc.csv", "identify check": "val.csv",
          "wrench": "push.csv", "commission directions": "jog.csv"}


def _seconds_of(path: Path) -> float | None:
    """The duration of a drive log or trajectory file [s] (its last t)."""
    try:
        last = None
        with open(path) as fh:
            for line in fh:
                if line[:1].isdigit() or line[:1] == "-":
                    last = line
        return float(last.split(",", 1)[0]) if last else None
    except (OSError, ValueError):
        return None


def _first_counts(path: Path) -> list[str]:
    rows = [ln for ln in open(path) if not ln.startswith("#")]
    head = next(csv.reader([rows[0]]))
    first = next(csv.reader([rows[1]]))
    return [v for k, v in zip(head, first, strict=True) if k.endswith("_counts")]


def steps(out: Path, short: bool) -> list[tuple[str, list[str], tuple[int, ...]]]:
    """(label, arguments of `sixplus3`, the exit codes the docs give) in order."""
    ex = ["--duration", "3", "--candidates", "4"] if short else []
    res = ["--step", "0.03"] if short else []
    o = str(out)
    return [
        ("robot check", ["robot", "check"], (0,)),
        ("plan gentle_translate", ["plan", "gentle_translate", "-o", o, "--no-html"], (0,)),
        ("validate", ["validate", f"{o}/gentle_translate.csv"], (0,)),
        ("identify excite", ["identify", "excite", "-o", f"{o}/ident", *ex], (0,)),
        ("identify plant", ["identify", "plant", "-o", f"{o}/plant.yaml", "--seed", "3"],
         (0,)),
        ("simulate (excitation)", ["simulate", f"{o}/ident/excitation.csv", "--plant",
                                   f"{o}/plant.yaml", "--log", f"{o}/exc.csv"], (0,)),
        ("simulate (validation)", ["simulate", f"{o}/gentle_translate.csv", "--plant",
                                   f"{o}/plant.yaml", "--log", f"{o}/val.csv", "--hold",
                                   "1"], (0,)),
        ("identify estimate", ["identify", "estimate", f"{o}/exc.csv", "-o",
                               f"{o}/identified.yaml", "--report", f"{o}/ident/report",
                               "--validation", f"{o}/val.csv"], (0,)),
        ("identify check", ["--robot", f"{o}/identified.yaml", "identify", "check",
                            f"{o}/val.csv"], (0,)),
        ("plan tilt60_x (identified)", ["--robot", f"{o}/identified.yaml", "plan", "tilt60_x",
                                        "-o", f"{o}/identified_plans", "--no-html"], (0,)),
        ("simulate (push)", ["simulate", f"{o}/gentle_translate.csv", "--plant",
                             f"{o}/plant.yaml", "--log", f"{o}/push.csv", "--hold", "1.5",
                             "--wrench", f"{o}/push_profile.csv"], (0,)),
        ("wrench", ["--robot", f"{o}/identified.yaml", "wrench", f"{o}/push.csv", "-o",
                    f"{o}/wrench.csv", "--plot", f"{o}/wrench.png"], (0,)),
        ("wrench-resolution", ["wrench-resolution", "-o", f"{o}/resolution.png", *res], (0,)),
        ("commission jog", ["commission", "jog", "--plant", f"{o}/plant.yaml", "-o",
                            f"{o}/jog.csv"], (0,)),
        ("commission zero", ["commission", "zero", "--counts", "@jog", "-o",
                             f"{o}/zeroed.yaml"], (0,)),
        ("commission directions", ["--robot", f"{o}/zeroed.yaml", "commission", "directions",
                                   f"{o}/jog.csv", "-o", f"{o}/robot.yaml"], (0, 1)),
        ("simulate (lead)", ["simulate", "--plant", f"{o}/plant.yaml", "--lead",
                             f"{o}/hand.yaml", "--log", f"{o}/lead.csv"], (0,)),
        ("teach", ["teach", f"{o}/lead.csv", "-o", f"{o}/taught.yaml", "--pfl", "hand"], (0,)),
        ("plan (taught)", ["plan", f"{o}/taught.yaml", "-o", f"{o}/taught", "--no-html"],
         (0,)),
    ]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--out", default="out/walkthrough")
    ap.add_argument("--short", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    # the push of docs/interaction.md: 10 N along x from 1.2 s to 2.0 s
    (out / "push_profile.csv").write_text("t,fx,fy,fz,mx,my,mz\n0,0,0,0,0,0,0\n"
                                          "1.2,10,0,0,0,0,0\n2.0,0,0,0,0,0,0\n")
    # the hand of docs/leadthrough.md
    (out / "hand.yaml").write_text(
        "stiffness: 400\ndamping: 10\ndelay: 0.15\nmax_force: 30\nstiffness_rot: 2\n"
        "damping_rot: 0.1\nduration: 5.0\npath:\n  - {t: 0.0, offset: [0, 0, 0]}\n"
        "  - {t: 1.5, offset: [0.06, 0, 0]}\n  - {t: 2.5, offset: [0.06, 0, 0]}\n"
        "  - {t: 4.0, offset: [0.06, 0.04, 0], rotation: [0, 0, 0.3]}\n")
    exe = shutil.which("sixplus3", path=str(Path(sys.executable).parent)) or "sixplus3"
    rows, ok = [], True
    for label, cmd, want in steps(out, args.short):
        if "@jog" in cmd:
            i = cmd.index("@jog")
            cmd = cmd[:i] + _first_counts(out / "jog.csv") + cmd[i + 1:]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run([exe, *cmd], capture_output=True, text=True, check=False,
                              stdin=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        log = LOG_OF.get(label)
        seconds = _seconds_of(out / log) if log else None
        good = proc.returncode in want
        ok &= good
        rows.append({"command": label, "argv": cmd, "exit": proc.returncode,
                     "expected": list(want), "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
                     "log_s": seconds,
                     "last_line": (proc.stdout.strip().splitlines() or [""])[-1][:160]
                     if good else (proc.stdout + proc.stderr)[-600:]})
        if not args.json:
            extra = f", log {seconds:.2f} s" if seconds is not None else ""
            print(f"{'ok ' if good else 'BAD'} {label:28s} exit {proc.returncode}  "
                  f"wall {wall:6.1f} s  cpu {cpu:6.1f} s{extra}", flush=True)
            if not good:
                print("    " + rows[-1]["last_line"].replace("\n", "\n    "))
    if args.json:
        print(json.dumps(rows, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
