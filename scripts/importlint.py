"""Check the layers contract with import-linter: ``python scripts/importlint.py``.

import-linter walks the root package's folder, so it does not see setuptools'
``package-dir`` mapping (pyproject.toml) in an editable install.  This script copies the
namespace as it is installed (the same ``package-dir`` table) to build/importlint and
runs ``lint-imports`` (the ``[tool.importlinter]`` contract of pyproject.toml) on it.
Lazy imports inside functions count.  Exit code: lint-imports'.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]


def build_tree(tree: Path) -> Path:
    """Copy the installed namespace to ``tree`` (replaced); returns ``tree``."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    mapping: dict[str, str] = cfg["tool"]["setuptools"]["package-dir"]
    shutil.rmtree(tree, ignore_errors=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for package, folder in sorted(mapping.items()):  # "sixplus3" first
        dst = tree.joinpath(*package.split("."))
        if package == "sixplus3":
            dst.mkdir(parents=True)
            for f in (ROOT / folder).glob("*.py"):
                shutil.copy2(f, dst / f.name)
        else:
            shutil.copytree(ROOT / folder, dst, ignore=ignore)
    return tree


def run(tree: Path, **kw: object) -> subprocess.CompletedProcess:
    """``lint-imports`` with pyproject.toml's contract over the namespace in ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    exe = Path(sys.executable).with_name("lint-imports")
    return subprocess.run([str(exe), str(ROOT / "pyproject.toml"),
                           "--no-cache"], env=env, cwd=tree, check=False, **kw)


def main() -> int:
    return run(build_tree(ROOT / "build" / "importlint")).returncode


if __name__ == "__main__":
    sys.exit(main())
