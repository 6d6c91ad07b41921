"""MujocoWorld: one MuJoCo model and data shared by every simulated robot in a scene.

The world owns the physics (``MjModel``/``MjData``), the control period and the optional viewer.
Each robot in it is driven through its own :class:`~robot_ctrl.hw.mujoco_backend.MujocoBackend`
(lifecycle, read/write); the backends only touch their robot's slice of the data. A world with a
single robot is stepped by that robot's ``write()``; a world shared by several robots is stepped
by :meth:`step` once every controller has written its command for the tick (lock-step).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import mujoco


class MujocoWorld:
    def __init__(self, mjcf: Path, control_dt: float = 0.005, viewer: bool = False):
        self.m = mujoco.MjModel.from_xml_path(str(mjcf))
        self.d = mujoco.MjData(self.m)
        self.n_substeps = round(control_dt / self.m.opt.timestep)
        if self.n_substeps < 1 or abs(self.n_substeps * self.m.opt.timestep - control_dt) > 1e-9:
            raise ValueError(f"control_dt = {control_dt} s must be a positive multiple of the physics step "
                             f"{self.m.opt.timestep} s")
        self.control_dt = control_dt
        self.floor = self.m.geom("floor").id
        self._want_viewer = viewer
        self._viewer = None
        self._wall0 = 0.0
        self._after_substep: list[Callable[[int], None]] = []

    def on_substep(self, callback: Callable[[int], None]) -> None:
        """Call ``callback(i)`` after physics step i of each control period (a backend recording
        its servo demand)."""
        self._after_substep.append(callback)

    def open_viewer(self) -> None:
        if self._want_viewer and self._viewer is None:
            import mujoco.viewer

            self._viewer = mujoco.viewer.launch_passive(self.m, self.d)
        self._wall0 = time.perf_counter() - self.d.time

    def step(self) -> None:
        """Advance the physics by one control period, then compute the bodies' contact wrenches
        (``cfrc_ext``, which ``mj_step`` leaves out) for the backends' force/torque readings."""
        for i in range(self.n_substeps):
            mujoco.mj_step(self.m, self.d)
            for callback in self._after_substep:
                callback(i)
        mujoco.mj_rnePostConstraint(self.m, self.d)
        if self._viewer is not None:
            self._viewer.sync()
            lag = self.d.time - (time.perf_counter() - self._wall0)
            if lag > 0:  # pace the viewer at real time
                time.sleep(lag)

    def close(self) -> None:
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
