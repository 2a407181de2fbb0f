"""Packaging: one namespace, nothing else at the top of site-packages, works from anywhere.

The wheel is built from this checkout (no network: --no-build-isolation with the test
extra's setuptools), installed into a private folder and imported from a user project
that has its own ``planner.py``, ``kinematics.py`` and ``design/`` package on the path.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

USER_CODE = r"""
import sys
import planner, kinematics, design              # the user's own modules
assert planner.MINE == "planner" and kinematics.MINE == "kinematics"
assert design.MINE == "design"
import sixplus3
assert sixplus3.__file__.startswith(sys.argv[1]), sixplus3.__file__
assert "pinocchio" not in sys.modules            # the flat API is lazy
from sixplus3.planner.task import task_from_dict
robot = sixplus3.Robot.default()
home = list(robot.home_position)
task = task_from_dict({"waypoints": [{"position": home},
                                     {"position": [home[0] + 0.02, home[1], home[2]]}],
                       "nodes_per_segment": 4})
sol = sixplus3.plan(task, robot, sixplus3.PlannerOptions(lock_redundancy=True))
assert sol.is_feasible()
assert planner.MINE == "planner"                 # still the user's after planning
from sixplus3 import examples
assert "tilt60_x" in examples.names() and len(examples.load("tilt60_x").waypoints) == 2
print("planned", round(sol.final_time, 4))
"""


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built from a clean copy of the working tree (no stale build/ folder)."""
    src = tmp_path_factory.mktemp("src") / "sixplus3"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".git", ".venv", "build", "out", "*.egg-info", "__pycache__", ".*_cache"))
    out = tmp_path_factory.mktemp("wheel")
    run = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps",
                          "--no-build-isolation", "-v", "-w", str(out), str(src)],
                         check=True, capture_output=True, text=True)
    # the build says nothing a new user would read as a broken install (session 34: a
    # 30-line "Package would be ignored" for the URDF folder on every install)
    said = [ln for ln in (run.stdout + run.stderr).splitlines()
            if "BuildBackendWarning" in ln or "would be ignored" in ln
            or "SetuptoolsDeprecationWarning" in ln]
    assert not said, said
    (whl,) = out.glob("sixplus3-*.whl")
    return whl


def test_the_wheel_installs_only_the_sixplus3_namespace(wheel) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    top = {n.split("/")[0] for n in names}
    assert top == {"sixplus3", wheel.name.split("-")[0] + "-" + wheel.name.split("-")[1]
                   + ".dist-info"}, top
    # every package pyproject's package-dir maps, and every module of its folder
    table = (ROOT / "pyproject.toml").read_text().split("[tool.setuptools.package-dir]")[1]
    dirs = dict(re.findall(r'^"([\w.]+)"\s*=\s*"([\w/]+)"', table.split("\n[")[0],
                           flags=re.M))
    assert {"sixplus3.identification", "sixplus3.interaction", "sixplus3.cli"} <= set(dirs)
    missing = []
    for pkg, folder in dirs.items():
        base = pkg.replace(".", "/")
        missing += [f"{base}/__init__.py"] if f"{base}/__init__.py" not in names else []
        for py in (ROOT / folder).rglob("*.py"):
            rel = py.relative_to(ROOT / folder).as_posix()
            if "__pycache__" not in rel and f"{base}/{rel}" not in names:
                missing.append(f"{base}/{rel}")
    assert not missing, missing
    assert "sixplus3/robot_description/urdf/sixplus3.urdf" in names
    assert "sixplus3/examples/tilt60_x.yaml" in names
    assert any(n.endswith("dist-info/licenses/LICENSE") for n in names)


def test_a_user_project_with_clashing_names_plans_from_any_directory(wheel, tmp_path) -> None:
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "--quiet",
                    "--target", str(site), str(wheel)], check=True, capture_output=True)
    installed = {p.name for p in site.iterdir() if not p.name.endswith(".dist-info")}
    assert installed - {"bin"} == {"sixplus3"}, installed  # bin/: the console script
    user = tmp_path / "project"
    (user / "design").mkdir(parents=True)
    (user / "planner.py").write_text('MINE = "planner"\n')
    (user / "kinematics.py").write_text('MINE = "kinematics"\n')
    (user / "design" / "__init__.py").write_text('MINE = "design"\n')
    (user / "run.py").write_text(USER_CODE)
    env = {**os.environ, "PYTHONPATH": f"{user}{os.pathsep}{site}"}
    r = subprocess.run([sys.executable, "run.py", str(site)], cwd=user, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.startswith("planned")


def test_the_layers_contract_holds_and_catches_an_upward_import(tmp_path) -> None:
    """`make lint`'s import-linter contracts (pyproject.toml) hold on the tree, and fail,
    naming the import, when a lower layer imports a higher one (a lazy import inside a
    function, as the old upward imports were) or two modules of a package import each
    other."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "importlint", Path(__file__).resolve().parents[1] / "scripts" / "importlint.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    tree = mod.build_tree(tmp_path / "tree")
    ok = mod.run(tree, capture_output=True, text=True)
    assert ok.returncode == 0, ok.stdout[-2000:]
    (tree / "sixplus3" / "kinematics" / "_upward.py").write_text(
        "def f():\n    from sixplus3.planner import ocp\n    return ocp\n")
    bad = mod.run(tree, capture_output=True, text=True)
    assert bad.returncode != 0
    assert "sixplus3.kinematics._upward -> sixplus3.planner.ocp" in bad.stdout
    # a cycle between two modules of one package, which the layers cannot see: the
    # acyclic-packages contract names it
    (tree / "sixplus3" / "kinematics" / "_upward.py").unlink()
    (tree / "sixplus3" / "control" / "_cycle.py").write_text(
        "from sixplus3.control.gate import validation\n")
    with open(tree / "sixplus3" / "control" / "report.py", "a") as f:
        f.write("\ndef _back():\n    from sixplus3.control import _cycle\n    return _cycle\n")
    cyc = mod.run(tree, capture_output=True, text=True)
    assert cyc.returncode != 0 and "acyclic packages BROKEN" in cyc.stdout
    assert "No cycles are allowed in sixplus3.control" in cyc.stdout


def test_the_curated_api_is_written_once_and_typed() -> None:
    """The three spellings of the curated API agree: ``__all__`` (a literal, which ruff
    needs to see the TYPE_CHECKING imports used), the lazy map ``_API``, and the
    TYPE_CHECKING imports for type checkers; every name resolves to its module's."""
    import ast
    import importlib

    import sixplus3

    api = sixplus3._API
    assert sorted(sixplus3.__all__) == sorted([*api, "__version__"])
    for name, module in api.items():
        assert getattr(sixplus3, name) is getattr(importlib.import_module(module), name)
    tree = ast.parse(Path(sixplus3.__file__).read_text())
    typed = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom)
                typed.update({a.name: imp.module for a in imp.names})
    assert typed == api


def test_the_package_docstring_example_runs(tmp_path, monkeypatch) -> None:
    """The example in ``sixplus3.__doc__`` (what ``help(sixplus3)`` shows a new user)
    runs as written (session 34: it named a task file a user does not have and an old
    signature)."""
    import textwrap

    import sixplus3

    doc = sixplus3.__doc__
    assert doc is not None and "::\n" in doc
    code = []  # the indented block after "::" (blank lines inside it kept)
    for ln in doc.split("::\n", 1)[1].splitlines():
        if ln and not ln.startswith("    "):
            break
        code.append(ln)
    assert len(code) > 5
    monkeypatch.chdir(tmp_path)
    exec(compile(textwrap.dedent("\n".join(code)), "sixplus3.__doc__", "exec"), {})
