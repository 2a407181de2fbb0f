"""MeshCat playback of a trajectory: live in the viewer, or as a standalone HTML page.

The robot is drawn from the URDF's primitive visuals through Pinocchio's
MeshcatVisualizer; each animation frame's tree configuration comes from the file's
platform pose and crank angles by the closed-form whole-robot IK (kinematics.robot).
MeshCat python keeps one zmq server per process (its close() is not implemented,
meshcat-python #87): one visualizer per process, reused.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.kinematics.robot import robot_ik
from sixplus3.robot_description.robot import Robot


@dataclass(frozen=True)
class Frames:
    robot: Robot
    q: np.ndarray  # (F, nq)
    fps: float
    slowdown: float  # animation time / real time


def frames_from_samples(robot: Robot, t, position, quaternion, psi, fps: float = 30.0,
                        min_seconds: float = 3.0) -> Frames:
    """Tree configurations at ``fps``, slowed down so the animation lasts >= min_seconds."""
    duration = float(t[-1])
    slowdown = max(1.0, min_seconds / max(duration, 1e-9))
    n = max(2, int(round(duration * slowdown * fps)) + 1)
    ts = np.linspace(0.0, duration, n)
    idx = np.clip(np.searchsorted(t, ts), 0, len(t) - 1)
    cfg = robot_ik(position[idx], Rotation.from_quat(quaternion[idx]).as_matrix(), psi[idx],
                   robot)
    return Frames(robot, cfg.q, fps, slowdown)


@functools.lru_cache(maxsize=1)
def _server():
    """The one meshcat server of this process (meshcat-python #87)."""
    import contextlib
    import io

    import meshcat

    # meshcat prints its server's URL on creation: a dead URL when only a page is
    # written, so it is kept quiet here; the live `play` command prints viewer_url()
    with contextlib.redirect_stdout(io.StringIO()):
        vis = meshcat.Visualizer()
    # camera ~1 m from the base centre (meshcat's camera frame is y-up)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [0.75, 0.55, 0.75])
    return vis


_LOADED: dict[str, object] = {}


def _viewer(robot: Robot):
    """The server with ``robot`` loaded (its URDF visuals; reloaded for another robot)."""
    import pinocchio as pin
    from pinocchio.visualize import MeshcatVisualizer

    vis = _server()
    if _LOADED.get("hash") != robot.hash:
        model = robot.closed_loop_model().model
        visual = pin.buildGeomFromUrdfString(model, robot.urdf(), pin.GeometryType.VISUAL)
        viz = MeshcatVisualizer(model, visual, visual)
        viz.initViewer(viewer=vis)
        viz.loadViewerModel(rootNodeName="sixplus3")
        _LOADED.update(hash=robot.hash, viz=viz)
    return vis, _LOADED["viz"]


def animate(frames: Frames):
    """Load the animation into the (single) viewer; returns the meshcat Visualizer."""
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
    vis.set_animation(anim, play=True, repetitions=0)
    return vis


def write_html(frames: Frames, out: str | Path) -> Path:
    """A self-contained page (JS inlined, no network) with the animation; atomic."""
    from sixplus3.fileio import atomic_write

    vis = animate(frames)
    out = Path(out)
    atomic_write(out, vis.static_html().encode())
    return out


def viewer_url() -> str:
    return _server().url()
