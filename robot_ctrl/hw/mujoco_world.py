"""MujocoWorld: one MuJoCo model and data shared by every simulated robot in a scene.

The world owns the physics (``MjModel``/``MjData``), the control period and the optional viewer.
Each robot in it is driven through its own :class:`~robot_ctrl.hw.mujoco_backend.MujocoBackend`
(lifecycle, read/write); the backends only touch their robot's slice of the data. A world with a
single robot is stepped by that robot's ``write()``; a world shared by several robots is stepped
by :meth:`step` once every controller has written its command for the tick (lock-step).

A control period is one ``mujoco.rollout`` call over its physics steps: the same steps as
``mj_step`` in a loop (same warm start, bit for bit), with the state after each step kept for
the backends (their servos' demand) and without the Python interpreter lock held. That lets
:meth:`start_step` run the period on a background thread, as a real robot moves while its
controller computes: the caller can do other work until :meth:`finish_step`.
"""

from __future__ import annotations

import sys
import threading
import time
import weakref
from pathlib import Path

import mujoco
import mujoco.rollout
import numpy as np

#: Interpreter switch interval while a background period runs [s]. The default (5 ms) lets the
#: controller's Python hold the lock for a whole period before the physics thread may start.
SWITCH_INTERVAL = 5e-6


class MujocoWorld:
    #: What a physics state holds (``mj_getState``): time, qpos, qvel, act, mocap, user data.
    STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS

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
        m, n = self.m, self.n_substeps
        nstate = mujoco.mj_stateSize(m, self.STATE)
        #: Physics state at the start of each step of the last period (n_substeps × nstate): the
        #: state the step's forward dynamics (and so each servo's force) was computed from.
        self.step_states = np.zeros((n, nstate))
        self._after = np.zeros((1, n, nstate))  # rollout's output: the state after each step
        self._start = np.zeros((1, nstate))
        self._warmstart = np.zeros((1, m.nv))
        self._ctrl = np.zeros((1, n, m.nu))
        self._sensordata = np.zeros((1, n, m.nsensordata))
        self._rollout = mujoco.rollout.Rollout(nthread=0)  # runs on the calling thread
        self._thread: _PeriodThread | None = None
        self._running = False  # a period started by start_step has not been finished

    def open_viewer(self) -> None:
        if self._want_viewer and self._viewer is None:
            import mujoco.viewer

            self._viewer = mujoco.viewer.launch_passive(self.m, self.d)
        self._wall0 = time.perf_counter() - self.d.time

    def step(self) -> None:
        """Advance the physics by one control period, on the calling thread (see
        :meth:`finish_step` for what it leaves)."""
        self._begin()
        self._run_period()
        self._end_period()

    def start_step(self) -> None:
        """Start the next control period on the physics thread and return at once. Nothing may
        touch ``m`` or ``d`` until :meth:`finish_step`."""
        self._begin()
        if self._thread is None:
            self._thread = _PeriodThread()
            self._close_thread = weakref.finalize(self, self._thread.close)
        self._running = True
        self._thread.run(self._run_period)

    def finish_step(self) -> None:
        """Wait for the period started last (if any), then compute the bodies' contact wrenches
        (``cfrc_ext``, which ``mj_step`` leaves out) for the backends' force/torque readings.
        ``d`` then holds what a loop of ``mj_step`` leaves: the state at the end of the period,
        its forward quantities from the start of the last step."""
        if not self._running:
            return
        self._running = False
        self._thread.wait()
        self._end_period()

    def _end_period(self) -> None:
        self.step_states[0] = self._start[0]
        self.step_states[1:] = self._after[0, :-1]
        mujoco.mj_rnePostConstraint(self.m, self.d)
        if self._viewer is not None:
            self._viewer.sync()
            lag = self.d.time - (time.perf_counter() - self._wall0)
            if lag > 0:  # pace the viewer at real time
                time.sleep(lag)

    def _begin(self) -> None:
        if self._running:
            raise RuntimeError("MujocoWorld: a control period is still running (call finish_step first)")
        mujoco.mj_getState(self.m, self.d, self._start[0], self.STATE)
        self._warmstart[0] = self.d.qacc_warmstart
        self._ctrl[0] = self.d.ctrl

    def _run_period(self) -> None:
        self._rollout.rollout_.rollout([self.m], [self.d], self.n_substeps, mujoco.mjtState.mjSTATE_CTRL,
                                       self._start, self._warmstart, self._ctrl, self._after, self._sensordata,
                                       None)

    def close(self) -> None:
        self.finish_step()
        if self._thread is not None:
            self._close_thread()
            self._thread = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None


class _PeriodThread:
    """A daemon thread that runs one job per :meth:`run`; :meth:`wait` blocks until it is done and
    re-raises what it raised. Raw locks, not Events: each wake-up of the thread costs one handover
    of the interpreter lock, not several. The thread holds a job only while running it, so a world
    it serves can be collected (its finalizer closes the thread)."""

    _open = 0  # threads alive: the switch interval is shortened while any is
    _saved_interval = 0.0

    def __init__(self):
        self._go = threading.Lock()
        self._go.acquire()
        self._done = threading.Lock()
        self._done.acquire()
        self._job = None
        self._error: BaseException | None = None
        self._closed = False
        if _PeriodThread._open == 0:
            _PeriodThread._saved_interval = sys.getswitchinterval()
            sys.setswitchinterval(min(_PeriodThread._saved_interval, SWITCH_INTERVAL))
        _PeriodThread._open += 1
        self._thread = threading.Thread(target=self._loop, name="mujoco-physics", daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while True:
            self._go.acquire()
            job, self._job = self._job, None
            if job is None:  # close()
                return
            try:
                job()
            except BaseException as exc:  # handed to the waiting caller
                self._error = exc
            del job
            self._done.release()

    def run(self, job) -> None:
        self._job = job
        self._go.release()

    def wait(self) -> None:
        self._done.acquire()
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._go.release()  # with no job: the loop ends
        self._thread.join()
        _PeriodThread._open -= 1
        if _PeriodThread._open == 0:
            sys.setswitchinterval(_PeriodThread._saved_interval)
