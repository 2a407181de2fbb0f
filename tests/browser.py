"""Headless Chromium for the tests that open a page (the playback page, the safety
report): Debian's chromium, which ``make test`` installs."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path


def chromium(page: Path, work: Path, *flags: str, stdout: Path | None = None) -> None:
    """Run headless Chromium on ``page`` with ``flags`` (``--screenshot=...``,
    ``--dump-dom``), its standard output to the file ``stdout``.

    No pipes (Chromium's helper processes would inherit them and keep the wait going
    after the work is done) and its own process group, killed on timeout.  Headless
    Chromium 156 occasionally never finishes a --virtual-time-budget run (seen 3 times
    in ~10 full runs here, never twice in a row once restarted): each attempt gets a
    fresh profile and 60 s, up to 3 attempts, until its output exists."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "Debian's chromium is needed (make test installs it)"
    target = stdout or next(Path(f.split("=", 1)[1]) for f in flags
                            if f.startswith("--screenshot="))
    for attempt in range(3):
        with open(stdout or os.devnull, "wb") as out:
            proc = subprocess.Popen(
                [exe, "--headless", "--no-sandbox", "--disable-gpu",
                 "--disable-background-networking", "--disable-component-update",
                 "--no-first-run", "--disable-sync",
                 f"--user-data-dir={work / f'prof{attempt}'}", *flags, page.as_uri()],
                stdout=out, stderr=subprocess.DEVNULL, start_new_session=True)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                pass
            finally:
                if proc.poll() is None:
                    os.killpg(proc.pid, 9)
        if target.exists() and target.stat().st_size > 0:
            return
    raise AssertionError(f"chromium wrote no {target.name} in 3 attempts")
