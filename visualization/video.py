"""A video (MP4) or GIF of a playback, rendered headless: the MeshCat page of
:func:`sixplus3.visualization.meshcat_player.write_html` in headless Chromium, driven
through the DevTools protocol.

Each frame seeks MeshCat's animator to the frame's time (paused), waits for two animation
frames (the render), and takes a screenshot; the page's readout shows the motion's own
time (``t = ... s of ... s``).  The frames go to imageio (MP4 through imageio-ffmpeg's
bundled ffmpeg, or GIF).  The video plays the motion slowed down by the page's factor
(``Frames.slowdown``), at ``fps`` frames per second of video.
"""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from sixplus3.errors import InputError
from sixplus3.fileio import atomic_write
from sixplus3.visualization.meshcat_player import write_html

#: The largest number of frames one video renders (about a minute at 20 fps).
MAX_FRAMES = 1200
#: Formats by suffix.
SUFFIXES = (".mp4", ".gif")

SEEK = """<script>
window.sixplus3_seek = function (t) {
  var a = viewer.animator;
  if (a.playing) { a.pause(); }
  a.seek(t * %(slowdown)r);
  document.getElementById('sixplus3-time').textContent =
    't = ' + Math.min(t, %(duration)r).toFixed(3) + ' s of %(duration).3f s';
  return new Promise(function (done) {
    requestAnimationFrame(function () { requestAnimationFrame(function () { done(true); }); });
  });
};
window.sixplus3_ready = function () {
  return typeof viewer !== 'undefined' && viewer.animator && viewer.animator.actions.length > 0;
};
</script>"""


def chromium() -> str:
    """The Chromium binary, or an InputError saying how to install it."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        raise InputError("a video needs Chromium (headless): apt-get install chromium",
                         value=None, valid="chromium on the PATH")
    return exe


class _DevTools:
    """A minimal DevTools-protocol client of one page of a headless Chromium."""

    def __init__(self, url: str, size: tuple[int, int], timeout: float = 60.0) -> None:
        # deferred: websockets (optional) loads only when this runs
        from websockets.sync.client import connect

        self.profile = tempfile.mkdtemp(prefix="sixplus3-chromium-")
        self.proc = subprocess.Popen(
            [chromium(), "--headless", "--no-sandbox", "--disable-gpu",
             "--disable-background-networking", "--disable-component-update",
             "--no-first-run", "--disable-sync", "--remote-debugging-port=0",
             f"--user-data-dir={self.profile}", f"--window-size={size[0]},{size[1]}",
             "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            start_new_session=True)
        ws = None
        t_end = time.monotonic() + timeout
        assert self.proc.stderr is not None
        while time.monotonic() < t_end:
            line = self.proc.stderr.readline()
            if not line:
                break
            if "DevTools listening on " in line:
                ws = line.split("DevTools listening on ", 1)[1].strip()
                break
        if ws is None:
            self.close()
            raise InputError("headless Chromium did not start its DevTools endpoint",
                             value=None, valid="a working chromium")
        self.ws = connect(ws, max_size=None, open_timeout=timeout)
        self.timeout = timeout
        self.n = 0
        target = self.call("Target.createTarget", {"url": url})["targetId"]
        self.session = self.call("Target.attachToTarget",
                                 {"targetId": target, "flatten": True})["sessionId"]
        self.call("Emulation.setDeviceMetricsOverride",
                  {"width": size[0], "height": size[1], "deviceScaleFactor": 1,
                   "mobile": False}, session=True)

    def call(self, method: str, params: dict[str, Any] | None = None,
             session: bool = False) -> dict[str, Any]:
        self.n += 1
        msg: dict[str, Any] = {"id": self.n, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self.session
        self.ws.send(json.dumps(msg))
        t_end = time.monotonic() + self.timeout
        while time.monotonic() < t_end:
            reply = json.loads(self.ws.recv(timeout=self.timeout))
            if reply.get("id") == self.n:
                if "error" in reply:
                    raise InputError(f"Chromium: {method}: {reply['error'].get('message')}",
                                     value=None, valid="a page that renders")
                return dict(reply.get("result", {}))
        raise InputError(f"Chromium did not answer {method} in {self.timeout:g} s",
                         value=None, valid="a page that renders")

    def evaluate(self, expression: str) -> Any:
        res = self.call("Runtime.evaluate", {"expression": expression, "awaitPromise": True,
                                             "returnByValue": True}, session=True)
        return res.get("result", {}).get("value")

    def close(self) -> None:
        try:
            if getattr(self, "ws", None) is not None:
                self.ws.close()
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.wait(timeout=10)
            shutil.rmtree(self.profile, ignore_errors=True)


def video_times(duration: float, slowdown: float, fps: float) -> np.ndarray:
    """The motion's times [s] of the video's frames: ``fps`` frames per second of the
    slowed-down playback, the last frame at the end of the motion."""
    n = int(np.ceil(duration * slowdown * fps)) + 1
    if n > MAX_FRAMES:
        raise InputError(f"the video would have {n} frames: at most {MAX_FRAMES} (lower "
                         "--fps)", value=n, valid=f"<= {MAX_FRAMES} frames")
    return np.minimum(np.arange(n) / (slowdown * fps), duration)


def render_video(frames: Any, out: str | Path, fps: float = 20.0,
                 size: tuple[int, int] = (800, 600)) -> Path:
    """Write the playback of ``frames`` (:class:`~.meshcat_player.Frames`) as an MP4 or a
    GIF (by ``out``'s suffix), atomically; returns its path.  ``size``: pixels, each a
    multiple of 8 (the video codec's blocks)."""
    # deferred: imageio (optional) loads only when this runs
    import imageio.v3 as iio


    out = Path(out)
    if out.suffix.lower() not in SUFFIXES:
        raise InputError(f"a video is .mp4 or .gif, got {out.name}", value=out.name,
                         valid="*.mp4 or *.gif")
    if not (isinstance(fps, (int, float)) and 1.0 <= fps <= 60.0):
        raise InputError(f"--fps must be in [1, 60], got {fps!r}", value=fps,
                         valid="[1, 60]")
    times = video_times(frames.duration, frames.slowdown, fps)
    with tempfile.TemporaryDirectory(prefix="sixplus3-video-") as tmp:
        page = Path(tmp) / "page.html"
        write_html(frames, page)
        text = page.read_text()
        page.write_text(text.replace("</body>", SEEK % {
            "slowdown": float(frames.slowdown), "duration": float(frames.duration)}
            + "</body>", 1))
        tools = _DevTools(page.as_uri(), size)
        try:
            t_end = time.monotonic() + 60.0
            while not tools.evaluate("window.sixplus3_ready && window.sixplus3_ready()"):
                if time.monotonic() > t_end:
                    raise InputError("the playback page did not load its animation in 60 s",
                                     value=None, valid="a page that renders")
                time.sleep(0.1)
            images = []
            for t in times:
                tools.evaluate(f"window.sixplus3_seek({float(t)!r})")
                shot = tools.call("Page.captureScreenshot", {"format": "png"}, session=True)
                images.append(iio.imread(base64.b64decode(shot["data"]), extension=".png")
                              [:, :, :3])
        finally:
            tools.close()
    stack = np.stack(images)
    if out.suffix.lower() == ".gif":
        blob = iio.imwrite("<bytes>", stack, extension=".gif", duration=1000.0 / fps, loop=0)
    else:
        blob = iio.imwrite("<bytes>", stack, extension=".mp4", fps=fps, codec="libx264",
                           macro_block_size=8)
    atomic_write(out, blob)
    return out


__all__ = ["MAX_FRAMES", "SUFFIXES", "render_video", "video_times"]
