"""Which readings of the paper's conventions reproduce its optimum? (docs/design.md)

    .venv/bin/python benchmarks/design_readings.py [--ws-step 0.005] > table.md

Runs the paper's two-stage search (1 cm, then 1 mm around the single best coarse
design: seed_tolerance=0) for each reading and prints a Markdown
table: the optimum, its area and the area of the paper's design under the same reading.
"""

from __future__ import annotations

import argparse
import itertools
import math

from sixplus3.design.search import PAPER_DESIGN, Reading, optimize

ZEROS = {"+y": 0.0, "-z": -math.pi / 2, "+z": math.pi / 2}


def readings():
    for mode, ey in itertools.product(("++++", "+-++", "++--", "-+++", "--++"),
                                      (0.0, 0.01, 0.02)):
        yield Reading(name=f"{mode} ey={ey:g} theta from +y (SPEC), <= 135", mode=mode, ey=ey)
        yield Reading(name=f"{mode} ey={ey:g} no theta limit", mode=mode, ey=ey,
                      theta_max=2 * math.pi)
        yield Reading(name=f"{mode} ey={ey:g} theta from +z towards +y, <= 135", mode=mode,
                      ey=ey, theta_zero=-math.pi / 2, theta_direction=-1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ws-step", type=float, default=0.005)
    args = ap.parse_args()
    print("| reading | l2 | l4 | ex | area [m^2] | paper design area [m^2] |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    print(f"| *paper* | {PAPER_DESIGN[0]:.3f} | {PAPER_DESIGN[1]:.3f} | {PAPER_DESIGN[2]:.3f} "
          "| | |")
    for r in readings():
        res = optimize(ws_step=args.ws_step, reading=r, seed_tolerance=0.0)  # the paper's procedure
        if res.found:
            cells = f"{res.l2:.3f} | {res.l4:.3f} | {res.ex:.3f} | {res.area_m2:.4f}"
        else:
            cells = "- | - | - | 0"
        print(f"| {r.name} | {cells} | {max(res.paper_design_area_m2, 0):.4f} |", flush=True)


if __name__ == "__main__":
    main()
