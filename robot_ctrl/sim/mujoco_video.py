"""WorldVideo: a video of a MuJoCo world, rendered offscreen as it is simulated.

Frames are rendered at ``fps`` of simulated time by MuJoCo's offscreen renderer (an OpenGL
context: ``MUJOCO_GL=egl`` on a machine without a display) from a free camera that follows the
mean position of the world's free-floating bodies (the robots' bases), and encoded to H.264 MP4 by
ffmpeg (``imageio-ffmpeg``, which ships the binary). The file is complete once :meth:`close` ran.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np

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


class WorldVideo:
    def __init__(self, model: mujoco.MjModel, path: Path, fps: int = FPS, size: tuple[int, int] = SIZE,
                 distance: float = 3.2, azimuth: float = 135.0, elevation: float = -12.0):
        import imageio_ffmpeg

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fps = fps
        self.renderer = mujoco.Renderer(model, size[1], size[0])
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.azimuth, self.camera.elevation = azimuth, elevation
        free = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
        self.bases = model.jnt_bodyid[free]
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
        self.camera.lookat[:] = [lookat[0], lookat[1], 0.8]
        self.renderer.update_scene(data, self.camera)
        self._writer.send(np.ascontiguousarray(self.renderer.render()))
        self.frames += 1
        self._next += 1.0 / self.fps

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self.renderer.close()
            self._writer = None
