"""What the long-running parts report while they work, and how much.

Three levels, set once per command (``sixplus3 plan TASK --quiet`` / ``--verbose``, on
the commands that plan or search):

``QUIET``
    Nothing but results and errors: no compile notice, no planning stages, no bars.
``NORMAL`` (the default)
    The compile notice (with its elapsed time), one line per planning stage and per
    finished NLP solve, and on a terminal a live status line of the running IPOPT solve
    (iteration, the plan's duration, the constraint violation) and the atlas's bar.
``VERBOSE``
    As ``NORMAL``, plus one line per IPOPT iteration, also when not on a terminal.

The planner reports through a :class:`PlanProgress` (``plan(..., progress=...)``); the
IPOPT iterations reach it through CasADi's ``iteration_callback`` (see
:mod:`sixplus3.planner.solvers`).  :class:`ConsoleProgress` is the command line's reporter.
"""

from __future__ import annotations

import shutil
import sys
from typing import Any, Protocol, TextIO, runtime_checkable

from sixplus3.errors import InputError

QUIET, NORMAL, VERBOSE = 0, 1, 2
_level = NORMAL


def level() -> int:
    """The current reporting level (QUIET, NORMAL or VERBOSE)."""
    return _level


def set_level(value: int) -> None:
    global _level
    if value not in (QUIET, NORMAL, VERBOSE):
        raise InputError(f"reporting level must be 0, 1 or 2, got {value!r}", value=value,
                         valid="0, 1 or 2")
    _level = value


@runtime_checkable
class PlanProgress(Protocol):
    """What :func:`sixplus3.planner.ocp.plan` tells its caller while it works."""

    def stage(self, text: str) -> None:
        """A planning stage starts or ends (the baseline, a start of the NLP, a re-solve,
        the re-timing); ``text`` is one line."""

    def iteration(self, k: int, duration: float, violation: float) -> None:
        """IPOPT finished iteration ``k`` of the running solve: the iterate's motion
        lasts ``duration`` [s] and violates its constraints by at most ``violation``
        (the largest row's distance outside its bounds, in the rows' own units)."""


class ConsoleProgress:
    """The command line's :class:`PlanProgress`: stage lines on ``stream`` (default
    standard output), and the iterations as a live tqdm status line on a terminal
    (NORMAL) or one line each (VERBOSE).  Nothing at all when the level is QUIET."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stdout
        self._bar: Any = None

    def _close_bar(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def stage(self, text: str) -> None:
        if _level == QUIET:
            return
        self._close_bar()
        print(text, file=self.stream, flush=True)

    def iteration(self, k: int, duration: float, violation: float) -> None:
        verbose = _level == VERBOSE
        if not (verbose or (_level == NORMAL and self.stream.isatty())):
            return
        line = f"IPOPT iteration {k:4d}: duration {duration:8.4f} s, violation {violation:.1e}"
        if verbose:
            print(f"    {line}", file=self.stream, flush=True)
        else:
            if self._bar is None:
                # deferred: the progress lines load tqdm only when drawn (--help)
                from tqdm import tqdm

                # a terminal that reports a 0 x 0 size (a bare pty) would hide the line
                size = shutil.get_terminal_size((100, 24))
                self._bar = tqdm(total=None, bar_format="    {desc} [{elapsed}]",
                                 file=self.stream, leave=False, ncols=size.columns,
                                 nrows=size.lines, miniters=1)
            self._bar.set_description_str(line, refresh=False)
            self._bar.update(1)

    def close(self) -> None:
        self._close_bar()
