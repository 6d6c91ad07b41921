"""MujocoWorld: one MuJoCo model and data shared by every simulated robot in a scene.

The world owns the physics (``MjModel``/``MjData``), the control period, the optional viewer and
the optional video. Each robot in it is driven through its own
:class:`~robot_ctrl.sim.mujoco_backend.MujocoBackend` (lifecycle, read/write); the backends only
touch their robot's slice of the data. Each backend attaches itself; the world steps when every
attached robot has submitted its command for the tick (lock-step): a single robot's ``write()``
steps it at once.

A control period is one ``mujoco.rollout`` call over its physics steps: the same steps as
``mj_step`` in a loop (same warm start, bit for bit), with the state at the start of each step
kept for the backends (their servos' demand record) and without Python between the steps. To let
a controller compute while its robot moves, run the robot's backend in a process of its own
(:class:`~robot_ctrl.sim.robot_process.RobotProcess`).
"""

from __future__ import annotations

import time
from pathlib import Path

import mujoco
import mujoco.rollout
import numpy as np

from robot_ctrl.sim.mujoco_video import Video


class MujocoWorld:
    #: What a physics state holds (``mj_getState``): time, qpos, qvel, act, mocap, user data.
    STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS

    def __init__(self, mjcf: Path, control_dt: float = 0.005, viewer: bool = False, video: Video | Path | None = None,
                 friction_scale: float = 1.0):
        """``video``: record an MP4 of the run (:class:`~robot_ctrl.sim.mujoco_video.WorldVideo`; a path:
        the follow camera);
        ``friction_scale``: every geom's sliding friction times this (``Disturbances``)."""
        self.m = mujoco.MjModel.from_xml_path(str(mjcf))
        self.m.geom_friction[:, 0] *= friction_scale
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
        m, n = self.m, self.n_substeps
        nstate = mujoco.mj_stateSize(m, self.STATE)
        #: Physics state at the start of each step of the last period (n_substeps × nstate): the
        #: state the step's forward dynamics (and so each servo's force) was computed from.
        self.step_states = np.zeros((n, nstate))
        self._after = np.zeros((1, n, nstate))  # rollout's output: the state after each step
        self._start = np.zeros((1, nstate))
        self._warmstart = np.zeros((1, m.nv))
        self._ctrl = np.zeros((1, n, m.nu))
        self._pushes: list[tuple[int, float, float, np.ndarray]] = []  # (body, start, end [s], world force)
        # Mocap poses and equality switches (props such as the drawer cabinet) enter the rollout as inputs.
        self._props = ((mujoco.mjtState.mjSTATE_MOCAP_POS | mujoco.mjtState.mjSTATE_MOCAP_QUAT if self.m.nmocap else 0)
                       | (mujoco.mjtState.mjSTATE_EQ_ACTIVE if self.m.neq else 0))
        self._sensordata = np.zeros((1, n, m.nsensordata))
        self._rollout = mujoco.rollout.Rollout(nthread=0)  # runs on the calling thread
        self._video = video if video is None or isinstance(video, Video) else Video(Path(video))
        self.video = None
        self._robots = self._submitted = 0

    def add_push(self, body: int, start: float, duration: float, force: np.ndarray) -> None:
        """A force [N] (world frame, on ``body``'s centre of mass) over [start, start + duration) [s]."""
        self._pushes.append((body, start, start + duration, np.asarray(force, dtype=float)))

    def attach(self) -> None:
        """A robot's backend joins the world: the world steps once each attached robot submitted."""
        self._robots += 1

    def submit(self) -> None:
        """One attached robot's command for the tick is in; the last one steps the world."""
        self._submitted += 1
        if self._submitted >= self._robots:
            self._submitted = 0
            self.step()

    def open_viewer(self) -> None:
        """Open the viewer and the video, if asked for (once the robots stand in their start pose)."""
        if self._want_viewer and self._viewer is None:
            import mujoco.viewer

            self._viewer = mujoco.viewer.launch_passive(self.m, self.d)
        if self._video is not None and self.video is None:
            from robot_ctrl.sim.mujoco_video import WorldVideo

            self.video = WorldVideo(self.m, self._video)
            self.video.capture(self.d)
        self._wall0 = time.perf_counter() - self.d.time

    def step(self) -> None:
        """Advance the physics by one control period. ``d`` then holds what a loop of ``mj_step``
        leaves (the state at the end of the period, its forward quantities from the start of the
        last step) and the bodies' contact wrenches (``cfrc_ext``, which ``mj_step`` leaves out)
        for the backends' force/torque readings."""
        mujoco.mj_getState(self.m, self.d, self._start[0], self.STATE)
        self._warmstart[0] = self.d.qacc_warmstart
        self._ctrl[0] = self.d.ctrl
        control, spec = self._control()
        self._rollout.rollout([self.m], [self.d], self._start, control, skip_checks=True, nstep=self.n_substeps,
                              control_spec=spec, initial_warmstart=self._warmstart,
                              state=self._after, sensordata=self._sensordata)
        self.step_states[0] = self._start[0]
        self.step_states[1:] = self._after[0, :-1]
        mujoco.mj_rnePostConstraint(self.m, self.d)
        if self.video is not None:
            self.video.capture(self.d)
        if self._viewer is not None:
            self._viewer.sync()
            lag = self.d.time - (time.perf_counter() - self._wall0)
            if lag > 0:  # pace the viewer at real time
                time.sleep(lag)

    def _control(self) -> tuple[np.ndarray, int]:
        """The rollout's inputs over the period: the servos' controls; the body forces of each step
        while a push acts (a force written into ``xfrc_applied`` before the rollout would not be);
        in a scene with mocap bodies or equality constraints, their poses and switches as ``d`` holds
        them (the rollout resets what its inputs do not carry)."""
        m, n, dt = self.m, self.n_substeps, self.m.opt.timestep
        times = self.d.time + dt * np.arange(n)
        active = [(b, (times >= t0 - 1e-9) & (times < t1 - 1e-9), f) for b, t0, t1, f in self._pushes]
        active = [a for a in active if a[1].any()]
        if not active and not self._props:  # the usual period: nothing beyond the servos
            return self._ctrl, int(mujoco.mjtState.mjSTATE_CTRL)
        spec = mujoco.mjtState.mjSTATE_CTRL | (mujoco.mjtState.mjSTATE_XFRC_APPLIED if active else 0) | self._props
        row = np.empty(mujoco.mj_stateSize(m, spec))
        mujoco.mj_getState(m, self.d, row, spec)
        control = np.tile(row, (1, n, 1))
        for body, steps, force in active:  # the body forces follow the controls in the input vector
            control[0, steps, m.nu + 6 * body : m.nu + 6 * body + 3] = force
        return control, int(spec)

    def close(self) -> None:
        if self.video is not None:
            self.video.close()
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None
