"""The committed robot files (robot_description/urdf/): the default robot's URDF, its
point-mass variant and the loop closures, generated from Robot.default(); the check
that the committed files are the generator's, numbers compared as numbers.

    python -m sixplus3.robot_description.generated          # (re)write robot_description/urdf/*
    python -m sixplus3.robot_description.generated --check  # exit 1: the files are stale
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from sixplus3.robot_description.masses import POINT_MASS
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import (
    CLOSURES_PATH,
    POINT_MASS_URDF_PATH,
    URDF_DIR,
    URDF_PATH,
    build_closures_yaml,
    robot_urdf,
)

#: Two generated files are the same robot when every number agrees to this (absolute or
#: relative): far below anything physical, far above a float's last bit.
SAME_NUMBER = 1e-12


def generated_files() -> dict[Path, str]:
    """The committed files: ``Robot.default()`` and its point-mass variant."""
    robot = Robot.default()
    return {
        URDF_PATH: robot_urdf(robot),
        POINT_MASS_URDF_PATH: robot_urdf(robot.replace(masses=POINT_MASS,
                                            name="sixplus3_pointmass")),
        CLOSURES_PATH: build_closures_yaml(),
    }


_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def same_text(a: str, b: str, tol: float = SAME_NUMBER) -> bool:
    """True when ``a`` and ``b`` are the same text once every number in them is read as a
    number and compared within ``tol`` (absolute, or relative to the larger): a generated
    file is compared with the committed one as numbers, not as the last bit of a float."""
    if a == b:
        return True
    if _NUMBER.sub("#", a) != _NUMBER.sub("#", b):
        return False
    xs = [float(m) for m in _NUMBER.findall(a)]
    ys = [float(m) for m in _NUMBER.findall(b)]
    return len(xs) == len(ys) and all(
        abs(x - y) <= tol * max(1.0, abs(x), abs(y)) for x, y in zip(xs, ys, strict=True))


def check() -> list[Path]:
    """The committed files that differ from what the generator makes now (numbers compared
    within :data:`SAME_NUMBER`, see :func:`same_text`)."""
    return [p for p, text in generated_files().items()
            if not p.exists() or not same_text(p.read_text(), text)]


def write() -> list[Path]:
    URDF_DIR.mkdir(parents=True, exist_ok=True)
    out = []
    for path, text in generated_files().items():
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(text)
        tmp.replace(path)  # atomic
        out.append(path)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Generate the sixplus3 URDF and closures.")
    ap.add_argument("--check", action="store_true",
                    help="exit 1 if the committed files differ from the generator")
    args = ap.parse_args(argv)
    if args.check:
        stale = check()
        for p in stale:
            print(f"stale: {p}", file=sys.stderr)
        return 1 if stale else 0
    for p in write():
        print(f"wrote {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
