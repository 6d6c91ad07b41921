"""WorldVideo: a video of a MuJoCo world, rendered offscreen as it is simulated.

Frames are rendered at ``fps`` of simulated time by MuJoCo's offscreen renderer (an OpenGL
context: ``MUJOCO_GL=egl`` on a machine without a display) from a free camera, and encoded to
H.264 MP4 by ffmpeg (``imageio-ffmpeg``, which ships the binary). The file is complete once
:meth:`close` ran. The camera (:class:`CameraView`) follows the robots' bases (the mean of their
free-floating roots): from behind and to the right of them (``follow``), or, oriented by the first
robot's start heading, from its left side a little ahead of it, where its hands reach
(``side``), from above (``top``), or close on its left hand (``hand``).
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from robot_ctrl.modes import CameraView

FPS = 30
SIZE = (640, 480)  # [px] width, height: multiples of 16 for the encoder


def check_renderer() -> None:
    """Raise ``RuntimeError`` naming ``MUJOCO_GL`` if MuJoCo cannot render offscreen here. The test
    runs in a fresh interpreter: a GL context made in this process would be inherited, broken, by
    the processes it forks (the simulated robot's)."""
    probe = ("import mujoco; m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"0.1\"/>"
             "</worldbody></mujoco>'); r = mujoco.Renderer(m, 16, 16); r.update_scene(mujoco.MjData(m)); r.render()")
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    if result.returncode != 0:
        backend = os.environ.get("MUJOCO_GL", "unset (MuJoCo tries glfw, which needs a display)")
        error = (result.stderr.strip().splitlines() or ["no error message"])[-1]
        raise RuntimeError(f"--video needs MuJoCo's offscreen renderer, which failed with MUJOCO_GL={backend} "
                           f"({error}); set MUJOCO_GL=egl (or osmesa) and install an EGL/OpenGL driver "
                           "(Debian: libegl1 libgl1-mesa-dri)")


@dataclass(frozen=True)
class Video:
    """What to record: the MP4's ``path``, the ``camera``, and for the ``hand`` view the body it
    looks at (the MuJoCo body's full name)."""

    path: Path
    camera: CameraView = CameraView.FOLLOW
    hand: str | None = None


# View -> (distance [m], azimuth [deg] from the start heading, elevation [deg], look-at ahead of the base [m]);
# the follow view's azimuth is the world's.
VIEWS = {CameraView.FOLLOW: (3.2, 135.0, -12.0, 0.0), CameraView.SIDE: (2.1, -115.0, -22.0, 0.45),
         CameraView.TOP: (2.6, -90.0, -80.0, 0.4), CameraView.HAND: (0.75, -125.0, -30.0, 0.0)}
LOOK_AT_HEIGHT = 0.8  # [m] of the follow view; the others look at 1.0 m, where the hands work


class WorldVideo:
    def __init__(self, model: mujoco.MjModel, video: Video, fps: int = FPS, size: tuple[int, int] = SIZE):
        import imageio_ffmpeg

        self.path, self.view = Path(video.path), CameraView(video.camera)
        self.hand = model.body(video.hand).id if self.view is CameraView.HAND and video.hand else None
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fps = fps
        self.renderer = mujoco.Renderer(model, size[1], size[0])
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        distance, self._azimuth, self.camera.elevation, self._ahead = VIEWS[self.view]
        free = [j for j in np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
                if model.joint(j).name.split("/")[-1] == "root"]  # the robots', not the props'
        self.bases = model.jnt_bodyid[free]
        self._heading: float | None = None  # the first robot's yaw at the first frame [rad]
        spread = 0.0
        if len(self.bases) > 1:  # frame a group: bodies spread over its initial extent
            data = mujoco.MjData(model)
            mujoco.mj_forward(model, data)
            spread = float(np.ptp(data.xpos[self.bases], axis=0).max())
        self.camera.distance = distance + spread
        self._next = 0.0
        self.frames = 0
        self._writer = imageio_ffmpeg.write_frames(str(self.path), size, fps=fps, codec="libx264",
                                                   pix_fmt_out="yuv420p", quality=7, macro_block_size=16)
        self._writer.send(None)

    def capture(self, data: mujoco.MjData) -> None:
        """Render a frame if the simulated time reached the next one."""
        if data.time + 1e-9 < self._next:
            return
        lookat = data.xpos[self.bases].mean(axis=0) if len(self.bases) else np.zeros(3)
        if self.view is CameraView.FOLLOW:
            self.camera.azimuth = self._azimuth
            self.camera.lookat[:] = [lookat[0], lookat[1], LOOK_AT_HEIGHT]
        else:
            if self._heading is None:
                x = data.xmat[self.bases[0]].reshape(3, 3)[:, 0] if len(self.bases) else np.array([1.0, 0.0, 0.0])
                self._heading = float(np.arctan2(x[1], x[0]))
            forward = np.array([np.cos(self._heading), np.sin(self._heading)])
            self.camera.azimuth = np.degrees(self._heading) + self._azimuth
            self.camera.lookat[:] = (data.xpos[self.hand] if self.hand is not None
                                     else [*(lookat[:2] + self._ahead * forward), 1.0])
        self.renderer.update_scene(data, self.camera)
        self._writer.send(np.ascontiguousarray(self.renderer.render()))
        self.frames += 1
        self._next += 1.0 / self.fps

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self.renderer.close()
            self._writer = None
