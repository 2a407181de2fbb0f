"""The full two-stage design search (1 cm, then 1 mm, 5 mm workspace grid): time, memory;
then the optimum re-optimised on every workspace grid, with the paper's one-seed
procedure and with every near-best coarse seed refined (docs/design.md).

    .venv/bin/python benchmarks/bench_design.py [--reading paper-match] [--ws-step 0.005]
"""

from __future__ import annotations

import argparse
import resource

import numba
import numpy as np

from sixplus3.design.readings import READINGS
from sixplus3.design.search import design_grid, evaluate, optimize


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reading", default="paper-match", choices=sorted(READINGS))
    ap.add_argument("--ws-step", type=float, default=0.005)
    args = ap.parse_args()
    reading = READINGS[args.reading]
    optimize(coarse_step=0.05, fine_step=0.01, ws_step=0.02, reading=reading)  # JIT warm-up
    res = optimize(ws_step=args.ws_step, reading=reading)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"reading {reading.name}, ws_step {args.ws_step * 1000:g} mm, "
          f"{numba.get_num_threads()} threads")
    print(f"optimum l2={res.l2:.3f} l4={res.l4:.3f} ex={res.ex:.3f} m, area "
          f"{res.area_m2:.4f} m^2; paper design {res.paper_design_area_m2:.4f} m^2")
    print(f"{res.evaluations} designs ({res.feasible_designs} feasible), "
          f"{res.point_evaluations:,} point evaluations in {res.seconds:.2f} s: "
          f"{res.evaluations / res.seconds:,.0f} designs/s, "
          f"{res.point_evaluations / res.seconds / 1e6:.1f} M points/s; max RSS {rss:.0f} MB")
    if res.ridge is not None:
        print(f"ridge: {res.ridge.line()}")
    print("| grid | one seed (paper's procedure) | area [m^2] | every seed within 3 % | "
          "area [m^2] | ridge within 1 % |")
    print("| --- | --- | ---: | --- | ---: | --- |")
    for step in (0.01, 0.005, 0.0025):
        one = optimize(ws_step=step, reading=reading, seed_tolerance=0.0)
        many = optimize(ws_step=step, reading=reading)
        rg = many.ridge.line() if many.ridge is not None else "-"
        print(f"| {step * 1000:g} mm | ({one.l2:.3f}, {one.l4:.3f}, {one.ex:.3f}) | "
              f"{one.area_m2:.5f} | ({many.l2:.3f}, {many.l4:.3f}, {many.ex:.3f}) | "
              f"{many.area_m2:.5f} | {rg} |")
    paper = np.array([[0.139, 0.350, 0.097]])
    print("the paper's design re-scored: " + ", ".join(
        f"{step * 1000:g} mm {evaluate(paper, reading, design_grid(step, reading))[0][0]:.5f}"
        for step in (0.01, 0.005, 0.0025, 0.00125)))

if __name__ == "__main__":
    main()
