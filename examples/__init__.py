"""The example planning tasks, installed with the package and loadable by name::

    from sixplus3 import examples
    examples.names()                   # ['combined', 'tilt30_x', ...]
    task = examples.load("tilt60_x")   # a validated Task
"""

from __future__ import annotations

from importlib import resources
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from sixplus3.planner.task import Task


def names() -> list[str]:
    """The names of the example tasks."""
    return sorted(p.name[:-5] for p in resources.files(__name__).iterdir()
                  if p.name.endswith(".yaml"))


def load(name: str) -> Task:
    """The example task ``name`` (see :func:`names`); raises TaskError if unknown."""
    # deferred: the planner's task (numpy) loads only when a task is; names() stays light
    from sixplus3.errors import TaskError
    from sixplus3.fileio import parse_yaml
    from sixplus3.planner.task import task_from_dict

    if name not in names():
        raise TaskError(f"unknown example {name!r}: one of {', '.join(names())}",
                        value=name, valid=", ".join(names()))
    text = resources.files(__name__).joinpath(f"{name}.yaml").read_text(encoding="utf-8")
    return task_from_dict(parse_yaml(text, f"example {name}"), name=name)
