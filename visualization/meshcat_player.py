"""MeshCat playback of a trajectory: live in the viewer, or as a standalone HTML page.

The robot is drawn from the URDF's primitive visuals through Pinocchio's
MeshcatVisualizer; each animation frame's tree configuration comes from the file's
platform pose and crank angles by the closed-form whole-robot IK (kinematics.robot).
MeshCat python keeps one zmq server per process (its close() is not implemented,
meshcat-python #87): one visualizer per process, reused.
"""

from __future__ import annotations

import contextlib
import functools
import html
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.fileio import atomic_write
from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.model import closed_loop_model
from sixplus3.robot_description.robot import Robot
from sixplus3.robot_description.urdf import robot_urdf


@dataclass(frozen=True)
class Frames:
    robot: Robot
    q: np.ndarray  # (F, nq)
    fps: float
    slowdown: float  # animation time / real time
    path: np.ndarray | None = None  # (M, 3) platform centre along the motion [m]
    duration: float = 0.0  # real duration of the motion [s]
    title: str = "sixplus3"
    #: (K, 3) points to mark (e.g. where the motion stops or its waypoints) [m]
    marks: np.ndarray | None = None
    #: (W, 3) the task's waypoints (platform centre) [m], drawn apart from the rests
    waypoints: np.ndarray | None = None
    #: the gate's refusal of the file shown (``play --unsafe``): a red banner says it
    refused: str | None = None

#: Times the page and the live viewer replay the animation (MeshCat has no endless loop
#: through its Python API; at a few seconds per play this is hours).
REPETITIONS = 10_000
#: The camera orbits a point this fraction of the home height up the robot, from a
#: distance proportional to it (set for each robot loaded, :func:`_frame_camera`).
FOCUS_FRACTION = 0.55
#: The floor: a plate under the base, 1 m square, its top this far below z = 0 [m].
FLOOR_Z = -0.05


def frames_from_samples(robot: Robot, t: Any, position: Any, quaternion: Any, psi: Any,
                        fps: float = 30.0, min_seconds: float = 3.0,
                        title: str = "sixplus3", theta_dot: Any = None,
                        waypoints: Any = None) -> Frames:
    """Tree configurations at ``fps``, slowed down so the animation lasts >= min_seconds.

    The platform path is kept for a trace; with ``theta_dot`` the samples at rest inside
    the motion (stops, dwells) and at both ends are marked; ``waypoints`` (W, 3), the
    task's platform positions, are drawn as their own markers."""
    duration = float(t[-1])
    slowdown = max(1.0, min_seconds / max(duration, 1e-9))
    n = max(2, int(round(duration * slowdown * fps)) + 1)
    ts = np.linspace(0.0, duration, n)
    idx = np.clip(np.searchsorted(t, ts), 0, len(t) - 1)
    cfg = robot_ik(position[idx], Rotation.from_quat(quaternion[idx]).as_matrix(), psi[idx],
                   robot)
    marks = np.asarray(position)[[0, -1]]
    if theta_dot is not None:
        rest = np.flatnonzero(~np.asarray(theta_dot).any(axis=1))
        marks = np.asarray(position)[rest]
    wps = None if waypoints is None else np.asarray(waypoints, dtype=float).reshape(-1, 3)
    return Frames(robot, cfg.q, fps, slowdown, np.asarray(position, dtype=float),
                  duration, title, marks, wps)


@functools.lru_cache(maxsize=1)
def _server() -> Any:
    """The one meshcat server of this process (meshcat-python #87)."""

    # deferred: meshcat loads only when this runs
    import meshcat

    # meshcat prints its server's URL on creation: a dead URL when only a page is
    # written, so it is kept quiet here; the live `play` command prints viewer_url()
    with contextlib.redirect_stdout(io.StringIO()):
        vis = meshcat.Visualizer()
    return vis


def _frame_camera(vis: Any, robot: Robot) -> None:
    """The camera orbits a point about halfway up the robot (base at z = 0, platform at
    its home height h), 1.9 h away, a little above it (meshcat's camera frame is y-up)."""
    # deferred: meshcat loads only when this runs
    import meshcat.transformations as tf

    h = max(float(robot.home_position[2]), 0.1)
    vis["/Cameras/default"].set_transform(
        tf.translation_matrix([0.0, 0.0, FOCUS_FRACTION * h]))
    vis["/Cameras/default/rotated/<object>"].set_property(
        "position", [1.3 * h, 0.45 * h, 1.3 * h])


_LOADED: dict[str, object] = {}


def _viewer(robot: Robot) -> tuple[Any, Any]:
    """The server with ``robot`` loaded (its URDF visuals; reloaded for another robot)."""
    # deferred: Pinocchio loads only when this runs
    import pinocchio as pin
    from pinocchio.visualize import MeshcatVisualizer

    vis = _server()
    if _LOADED.get("hash") != robot.hash:
        model = closed_loop_model(robot).model
        visual = pin.buildGeomFromUrdfString(model, robot_urdf(robot), pin.GeometryType.VISUAL)
        viz = MeshcatVisualizer(model, visual, visual)
        viz.initViewer(viewer=vis)
        viz.loadViewerModel(rootNodeName="sixplus3")
        _frame_camera(vis, robot)
        _LOADED.update(hash=robot.hash, viz=viz)
    return vis, _LOADED["viz"]


def animate(frames: Frames) -> Any:
    """Load the animation into the (single) viewer; returns the meshcat Visualizer."""
    # deferred: meshcat loads only when this runs
    import meshcat.animation

    vis, viz = _viewer(frames.robot)
    anim = meshcat.animation.Animation(default_framerate=frames.fps)
    try:
        for i, q in enumerate(frames.q):
            with anim.at_frame(vis, i) as frame:
                viz.viewer = frame
                viz.display(q)
    finally:
        viz.viewer = vis
    viz.display(frames.q[0])
    _overlay(vis, frames)
    vis.set_animation(anim, play=True, repetitions=REPETITIONS)
    return vis


def _overlay(vis: Any, frames: Frames) -> None:
    """The floor, the platform centre's path as a line, a small sphere at each marked
    point (magenta: at rest) and at each waypoint (green)."""
    # deferred: meshcat loads only when this runs
    import meshcat.geometry as g
    import meshcat.transformations as tf

    vis["sixplus3_floor"].set_object(g.Box([1.0, 1.0, 0.004]), g.MeshLambertMaterial(
        color=0xB0B0A8, opacity=0.85, transparent=True))
    vis["sixplus3_floor"].set_transform(tf.translation_matrix([0.0, 0.0, FLOOR_Z - 0.002]))
    vis["sixplus3_path"].delete()
    if frames.path is not None and len(frames.path) > 1:
        step = max(1, len(frames.path) // 2000)
        pts = frames.path[::step].T.astype(np.float32)
        vis["sixplus3_path/line"].set_object(g.Line(
            g.PointsGeometry(pts), g.LineBasicMaterial(color=0xC020C0, linewidth=2)))
    if frames.marks is not None:
        for k, p in enumerate(_distinct(frames.marks)):
            node = vis[f"sixplus3_path/mark{k}"]
            node.set_object(g.Sphere(0.006), g.MeshLambertMaterial(color=0xC020C0))
            node.set_transform(tf.translation_matrix(p))
    if frames.waypoints is not None:
        for k, p in enumerate(_distinct(frames.waypoints)):
            node = vis[f"sixplus3_path/waypoint{k}"]
            node.set_object(g.Sphere(0.012), g.MeshLambertMaterial(color=0x20B040))
            node.set_transform(tf.translation_matrix(p))


def _distinct(points: np.ndarray, tol: float = 1e-4) -> list[np.ndarray]:
    out: list[np.ndarray] = []
    for p in np.asarray(points, dtype=float):
        if all(np.linalg.norm(p - q) > tol for q in out):
            out.append(p)
    return out[:50]


def write_html(frames: Frames, out: str | Path) -> Path:
    """A self-contained page (JS inlined, no network) with the animation; atomic."""


    vis = animate(frames)
    out = Path(out)
    page = vis.static_html()
    title = html.escape(frames.title)
    info = (f"{title}: {frames.duration:.3f} s motion, shown {frames.slowdown:.0f}x "
            f"slower, looping; magenta: the platform centre's path and where it rests"
            + ("; green: the task's waypoints" if frames.waypoints is not None else ""))
    page = page.replace("<title>MeshCat</title>", f"<title>{title}</title>", 1)
    box = "padding:4px 8px;background:rgba(255,255,255,0.85);border-radius:4px"
    banner = ('<div style="position:fixed;top:8px;left:8px;right:240px;z-index:10;'
              'font:14px sans-serif;display:flex;flex-direction:column;'
              'align-items:flex-start;gap:4px">'
              + (f'<div id="sixplus3-refused" style="padding:6px 10px;background:#c00;'
                 f'color:#fff;font-weight:bold;border-radius:4px">NOT A VALID MOTION: the '
                 f'gate refuses this file ({html.escape(frames.refused)}). Never feed it '
                 f'to the robot.</div>' if frames.refused else "")
              + f'<div style="{box}">{info}</div>'
              f'<div id="sixplus3-time" style="{box};font-family:monospace">'
              f't = 0.000 s of {frames.duration:.3f} s</div></div>')
    # the time of the motion shown, read from the animation's clip time
    clock = ("<script>setInterval(function () {"
             " var a = (typeof viewer !== 'undefined' && viewer.animator) ?"
             " viewer.animator.actions : [];"
             " if (!a.length) { return; }"
             f" var t = Math.min(a[0].time / {frames.slowdown!r}, {frames.duration!r});"
             " document.getElementById('sixplus3-time').textContent ="
             f" 't = ' + t.toFixed(3) + ' s of {frames.duration:.3f} s';"
             " }, 50);</script>")
    page = page.replace("<body>", "<body>" + banner, 1)
    page = page.replace("</body>", clock + "</body>", 1)
    atomic_write(out, page.encode())
    return out


def viewer_url() -> str:
    return _server().url()
