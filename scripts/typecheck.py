"""Type-check the installed namespace with mypy: ``python scripts/typecheck.py``.

The repository keeps the design card's folders at its root and maps them into the
``sixplus3`` namespace with setuptools' ``package-dir`` (pyproject.toml).  mypy does not
read that mapping, so this script builds the namespace as it is installed (a tree of
symbolic links under build/typecheck, from the same ``package-dir`` table) and runs
``mypy -p sixplus3`` on it.  Exit code: mypy's.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    mapping: dict[str, str] = cfg["tool"]["setuptools"]["package-dir"]
    tree = ROOT / "build" / "typecheck"
    shutil.rmtree(tree, ignore_errors=True)
    for package, folder in sorted(mapping.items()):
        dst = tree.joinpath(*package.split("."))
        if package == "sixplus3":
            dst.mkdir(parents=True)
            for f in (ROOT / folder).glob("*.py"):
                (dst / f.name).symlink_to(f)
        else:
            dst.symlink_to(ROOT / folder, target_is_directory=True)
    cmd = [sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
           "-p", "sixplus3"]
    return subprocess.call(cmd, cwd=tree)


if __name__ == "__main__":
    raise SystemExit(main())
