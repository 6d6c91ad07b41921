"""SafetyLayer: wraps any hardware backend and makes sure only safe commands reach it.

What it does with each ``write`` (in this order), each counted in ``interventions`` and logged
(first occurrence per kind, then a summary on close):

- ``rejected_command``: a command that is not finite real numbers of the right shape is refused;
  the last safe command is sent again instead (damping if there is none). ``write`` does not raise,
  so a loop that produced one bad sample keeps a held robot; the counter tells. Rejected commands
  in a row for ``rejected_fault_time`` (``command_fault``): a controller that has lost its numbers
  is not held stiff on its last good one, the layer sends damping and latches FAULT.
- ``gain_clamped``: kp and kd above ``kp_max`` / ``kd_max`` (the robot config's ``max_gain_ratio``
  times the servo gains) are clamped.
- ``position_clamped``: position targets clamped into [lower, upper] (the config's limits).
- ``position_step_limited``: the target moves at most ``step_limit`` per tick from the last one sent
  (how far the joint moves in a tick at its velocity limit).
- ``velocity_clamped``: velocity targets clamped to ± the velocity limit.
- soft start: kp and τ_ff ramp linearly from 0 to the commanded values over ``soft_start`` s of
  ticks after activation and after any damping episode (kd is never ramped).
- ``torque_clamped``, last, on every command the layer sends (damping included): the servo torque
  ``kp (q − q_meas) + kd (dq − dq_meas) + τ_ff`` at the last measured state is bounded to ± effort
  (``servo_torque.bound_servo_torque``: τ_ff clipped, the target moved within the position limits,
  and where that is not enough both gains scaled down).

``report()`` gives the interventions, the mode and state, the bus statistics, and per joint the
largest servo torque the controller's commands demanded, at the measured state, before any clamp
(``demanded_peak_torque_ratio``, over the effort limit): a run's delivered peaks stop at 1.

What it watches:

- ``bad_measurement``: a state whose time, q, dq, temperature, IMU or foot force/torque reading is
  not finite real numbers of the right shape → damping from the last good state, latched as FAULT
  until ``reset()`` (never a stiff hold of the last command).
- ``watchdog``: no ``write`` for ``watchdog_periods`` control periods (checked on every read and by
  the watchdog thread), armed at ``activate`` → damping mode (kp = 0, τ_ff = 0, kd = ``kd_damping``).
  The next valid write resumes with a soft start. ``activate`` first loads the compiled kernels
  (``robot_ctrl.kernels``), so that none is compiled inside the first ticks.
- ``stale_state``: the backend's state has not advanced for ``stale_periods`` control periods →
  damping mode; writes are answered with damping until a fresh state arrives.
- ``position_beyond_limit``: a measured joint position more than ``limit_tolerance`` beyond its
  position limit (an encoder offset, a joint pushed past its stop), counted when it goes beyond;
  flagged only, as ros2_control's limits report it: the commands are already held inside.
- temperature (where the backend reports it): ``temperature_warn`` logs once per joint;
  above ``temperature_derate`` kp and the torque limit of that joint scale down linearly, to 20 % at
  ``temperature_fault``; at ``temperature_fault`` the layer latches a FAULT in damping mode until
  ``reset()``.
- ``estop``: latches first, then puts the backend's servos in damping (again on every call,
  counted once); thread-safe; every later ``write`` raises ``LifecycleError`` until ``reset()`` and ``activate()``.
- ``backend_fault``: the backend's ``configure``, ``activate``, ``read`` or ``write`` raised (a bus error, a
  silent motor) → the layer latches FAULT, sends the backend's e-stop (damping) and raises
  ``HardwareFault`` naming what failed.

``close()`` (also on Ctrl-C and SIGTERM through the command line) sends damping, then deactivates
the backend (motors disabled), then closes it: a drive that misses the disable is left soft. After an
e-stop or a fault the servos are already in damping; closing then disables them all the same.

Threads: the layer's lock guards its own bookkeeping and is never held across a call into the
backend, so ``estop()`` and the watchdog act while a write is in flight. A write that was in flight
when the layer went to damping or e-stop is followed by the safe command again, so it cannot leave
a stiff command on the servos. A backend must therefore accept ``estop()`` and ``write()`` from
another thread while a write is in flight.
"""

from __future__ import annotations

import enum
import logging
import threading
import time
from collections import Counter
from typing import Callable

import numpy as np

from robot_ctrl.hw.adapter import HardwareAdapter, HardwareFault
from robot_ctrl.hw.command_filter import FLAG_KINDS, filter_command
from robot_ctrl.hw.safety_limits import SafetyLimits
from robot_ctrl.hw.servo_torque import bound_servo_torque
from robot_ctrl.hw.types import CommandError, JointCommand, JointState, LifecycleState
from robot_ctrl.kernels import load_kernels

S = LifecycleState
logger = logging.getLogger("robot_ctrl.hw.safety")


class SafetyMode(str, enum.Enum):
    """What the layer sends: nothing yet or any more (``OFF``), the controller's commands
    (``NORMAL``), or damping (``DAMPING``: kp = 0, τ_ff = 0, kd = ``kd_damping``)."""

    OFF = "off"
    NORMAL = "normal"
    DAMPING = "damping"


#: Every kind of intervention the layer counts (``SafetyLayer.interventions``), in a fixed order.
INTERVENTIONS = ("estop", "bad_measurement", "backend_fault", "watchdog", "stale_state", "rejected_command",
                 "command_fault", "position_beyond_limit", "temperature_warn", "temperature_derate", "temperature_fault", "gain_clamped", "position_clamped",
                 "position_step_limited", "velocity_clamped", "torque_clamped")


#: A command whose torque at the measured state is this far (relative) inside the effort needs no bound.
WITHIN_EFFORT_MARGIN = 1e-9


def _compiling(done: int, total: int) -> None:
    logger.warning("compiling the control loop's numba kernels: this version's first run on this machine takes "
                   "about 20 s, once (%d of %d done)", done, total)


class SafetyLayer(HardwareAdapter):
    """Wraps any backend so that only safe commands reach it (module docstring: the checks,
    their order, damping on a fault, the watchdog); an adapter itself. The last line of defence: a
    nominal run that needs it is a controller's bug. ``SafetyLayer(backend, SafetyLimits.from_robot(robot, dt))``."""

    def __init__(self, backend: HardwareAdapter, limits: SafetyLimits,
                 clock: Callable[[], float] | None = time.monotonic):
        """``clock``: what the watchdog and staleness checks measure time with, the wall clock by
        default; None: the time of the states the backend reports (lock-step simulation, where the
        simulated robot waits for its controller)."""
        super().__init__(backend.nj)
        if len(limits.lower) != backend.nj:
            raise ValueError(f"SafetyLimits are for {len(limits.lower)} joints, the backend has {backend.nj}")
        self.backend = backend
        self.limits = limits
        self._filter_limits = tuple(np.ascontiguousarray(a, dtype=float) for a in (
            limits.lower, limits.upper, limits.kp_max, limits.kd_max, limits.step_limit, limits.velocity,
            limits.effort))
        self.clock = clock if clock is not None else self._state_time
        self._latest_t = 0.0  # time of the last good state read [s]
        self.interventions: Counter[str] = Counter()
        self.mode = SafetyMode.OFF
        self._lock = threading.RLock()  # the layer's bookkeeping; never held across a backend call
        self._epoch = 0  # counts entries into damping and e-stop (a write in flight then re-sends)
        self._pending: JointCommand | None = None  # a damping command decided under the lock, to send
        self._last_sent: JointCommand | None = None
        self._last_target: np.ndarray | None = None  # the last position target before the torque bound
        self._last_good: JointState | None = None  # the last measured state that passed the checks
        self._last_write = None  # clock time of the last write, or of activation (None: disarmed)
        self._fresh_at = None  # clock time of the last state that advanced
        self._ticks = 0  # writes since the soft start began
        self._rejected = 0  # commands rejected in a row
        #: (nj,) [N·m] the largest |servo torque| the controller's commands asked for, at the measured
        #: state, before any clamp of this layer (what the report's delivered peaks hide).
        self.demanded_peak = np.zeros(backend.nj)
        self._derate = np.ones(backend.nj)
        self._warned = np.zeros(backend.nj, dtype=bool)
        self._beyond = np.zeros(backend.nj, dtype=bool)  # measured beyond a position limit
        self._watchdog: threading.Thread | None = None
        self._stop_watchdog = threading.Event()

    # Lifecycle ----------------------------------------------------------------------------------
    def _on_configure(self) -> None:
        self._backend_call(self.backend.configure)

    def _on_activate(self) -> None:
        # Before the servos are on and the watchdog armed: a kernel compiled inside the first ticks
        # (a machine's first run) would miss them.
        if (seconds := load_kernels(_compiling)) > 1.0:
            logger.warning("compiled the control loop's numba kernels in %.0f s (this version's first run on this "
                           "machine; cached from now on)", seconds)
        self._backend_call(self.backend.activate)
        with self._lock:
            self._begin_soft_start()
            self._last_write = self.clock()  # armed: a controller that never writes is caught too
            self.mode = SafetyMode.NORMAL

    def _on_deactivate(self) -> None:
        self.backend.deactivate()
        self.mode = SafetyMode.OFF

    def estop(self) -> None:
        """Latch the e-stop, then send the backend's damping; never waits for a write in flight."""
        with self._lock:
            if self._closed:
                return
            if self._state is not S.ESTOP:
                self._state = S.ESTOP
                self.mode = SafetyMode.OFF
                self._epoch += 1
                self._intervene("estop", "servos in damping mode, latched until reset()")
        self._on_estop()

    def _on_estop(self) -> None:
        self.backend.estop()

    def _on_reset(self) -> None:
        if self.backend.state in (S.ESTOP, S.FAULT):
            self.backend.reset()
        elif self.backend.state is S.ACTIVE:  # a fault of this layer left the servos in damping
            self.backend.deactivate()
        self._warned[:] = False
        self._derate[:] = 1.0

    def _on_close(self) -> None:
        self.stop_watchdog()
        try:
            if self.backend.state is S.ACTIVE:  # also after a fault of this layer: the servos are in damping
                with self._lock:
                    self.mode = SafetyMode.OFF
                    damping = self._damping_command()
                self.backend.write(damping)  # soft first, in case a drive misses the disable
                self.backend.deactivate()
        except Exception:
            logger.exception("safety: damping and disable on close failed")
        finally:
            self.backend.close()  # from ESTOP or FAULT it disables the motors itself
        if self.interventions:
            logger.info("safety interventions: %s", dict(self.interventions))

    def start_watchdog(self) -> None:
        """Check the write watchdog from a background thread every control period (real buses)."""
        if self._watchdog is None:
            self._stop_watchdog.clear()
            self._watchdog = threading.Thread(target=self._watch, name="safety-watchdog", daemon=True)
            self._watchdog.start()

    def stop_watchdog(self) -> None:
        if self._watchdog is not None:
            self._stop_watchdog.set()
            self._watchdog.join()
            self._watchdog = None

    def disarm_watchdog(self) -> None:
        """The controller stopped writing on purpose (its run ended): the servos keep its last
        command, and the write watchdog waits for the next ``write`` (which arms it again) or for
        ``close``, instead of tripping on a silence that is meant."""
        with self._lock:
            self._last_write = None

    def _watch(self) -> None:
        while not self._stop_watchdog.wait(self.limits.control_dt):
            try:
                self.check_watchdog()
            except Exception:  # a backend that fails to take the damping command: nothing left to send
                logger.exception("safety watchdog: the backend refused the damping command")
                self._state = S.FAULT
                return

    # Read / write -------------------------------------------------------------------------------
    def _state_time(self) -> float:
        return self._latest_t

    def _read(self) -> JointState:
        state = self._backend_call(self.backend.read)
        problem = state.problem(self.nj)
        with self._lock:
            if problem is not None:
                self._intervene("bad_measurement", problem)
                if self.backend.state is S.ACTIVE:
                    self._enter_damping(self._last_good)
                self._state = S.FAULT
            else:
                self._check_fresh(state)
        self._send_pending()
        if problem is None:
            self.check_watchdog()
        return state

    def write(self, command: JointCommand) -> None:
        with self._lock:
            self._require("write", S.ACTIVE)
            self._last_write = self.clock()
            epoch = self._epoch
            safe = self._safe_command(command)
            self._last_sent = safe
        self._guarded(lambda: self._write(safe))
        with self._lock:
            overtaken = self._epoch != epoch
        if overtaken:  # damping or e-stop began while this command was on its way
            self._reassert_safe()

    def _write(self, command: JointCommand) -> None:
        self._backend_call(self.backend.write, command)

    def _backend_call(self, call, *args):
        """``call(*args)``; if the backend raises: FAULT latched, the backend's damping, HardwareFault."""
        try:
            return call(*args)
        except Exception as exc:
            detail = f"{type(self.backend).__name__}.{call.__name__}: {exc}"
            with self._lock:
                self._intervene("backend_fault", detail)
                self._state = S.FAULT
                self.mode = SafetyMode.OFF
                self._epoch += 1
            try:
                self.backend.estop()
            except Exception:
                logger.exception("safety: the backend's damping failed as well")
            raise HardwareFault(f"{detail}; the servos were sent damping, FAULT latched until reset()") from exc

    def check_watchdog(self) -> None:
        """Enter damping mode if no write came for ``watchdog_periods`` control periods."""
        with self._lock:
            if self._state is not S.ACTIVE or self.mode is not SafetyMode.NORMAL or self._last_write is None:
                return
            silent = self.clock() - self._last_write
            if silent <= self.limits.watchdog_periods * self.limits.control_dt:
                return
            self._intervene("watchdog", f"no write for {silent * 1e3:.1f} ms")
            self._enter_damping(self._last_good)
        self._send_pending()

    def report(self) -> dict:
        b = self.backend
        return {"interventions": dict(self.interventions), "mode": self.mode.value, "state": self.state.value,
                "demanded_peak_torque_ratio": np.round(self.demanded_peak / self.limits.effort, 3).tolist(),
                "bus": {"missing_replies": b.missing_replies, "late_replies": b.late_replies,
                        "error_frames": b.error_frames, "foreign_frames": b.foreign_frames,
                        "duplicate_replies": b.duplicate_replies}}

    # Internals (called with the lock held, except the senders) -------------------------------------
    def _intervene(self, kind: str, detail: str) -> None:
        if self.interventions[kind] == 0:
            logger.warning("safety: %s (%s)", kind, detail)
        self.interventions[kind] += 1

    def _begin_soft_start(self) -> None:
        self._ticks = 0
        self._rejected = 0
        self._last_sent = None
        self._last_target = None

    def _check_fresh(self, state: JointState) -> None:
        self._latest_t = state.t
        now = self.clock()
        previous = self._last_good
        if previous is None or state.t > previous.t:
            self._fresh_at = now
        elif self._fresh_at is not None and now - self._fresh_at > self.limits.stale_periods * self.limits.control_dt:
            if self.mode is SafetyMode.NORMAL:
                self._intervene("stale_state", f"no new state for {now - self._fresh_at:.3f} s")
                self._enter_damping(state)
        self._last_good = state
        lim = self.limits
        beyond = (state.q < lim.lower - lim.limit_tolerance) | (state.q > lim.upper + lim.limit_tolerance)
        for i in np.flatnonzero(beyond & ~self._beyond):
            self._intervene("position_beyond_limit", f"joint {i} measured at {state.q[i]:.3f} rad, limits "
                                                     f"[{lim.lower[i]:.3f}, {lim.upper[i]:.3f}]")
        self._beyond = beyond
        if state.temperature is not None:
            self._check_temperature(np.asarray(state.temperature, dtype=float), state)

    def _safe_command(self, command: JointCommand) -> JointCommand:
        try:
            command.validate(self.nj)
        except CommandError as exc:
            self._intervene("rejected_command", str(exc))
            self._rejected += 1
            if self._rejected * self.limits.control_dt >= self.limits.rejected_fault_time - 1e-12:
                self._intervene("command_fault", f"{self._rejected} commands rejected in a row; damping, FAULT "
                                                 "latched until reset()")
                self._enter_damping(self._last_good)
                self._state = S.FAULT
                return self._last_sent
            return self._bounded(self._last_sent) if self._last_sent is not None else self._damping_command()
        self._rejected = 0
        stale = (self._fresh_at is not None
                 and self._last_write - self._fresh_at > self.limits.stale_periods * self.limits.control_dt)
        if stale or self._last_good is None:
            return self._damping_command()
        if self.mode is SafetyMode.DAMPING:
            logger.info("resuming from damping mode with a soft start")
            self._begin_soft_start()
            self.mode = SafetyMode.NORMAL
        return self._filter(command)

    def _damping_command(self, state: JointState | None = None) -> JointCommand:
        """kp = 0, τ_ff = 0, kd = ``kd_damping`` at the measured posture, within the torque bound."""
        state = state or self._last_good
        q = state.q.copy() if state is not None else (self.limits.lower + self.limits.upper) / 2
        zero = np.zeros(self.nj)
        return self._bounded(JointCommand(q=np.clip(q, self.limits.lower, self.limits.upper), dq=zero,
                                          kp=zero.copy(), kd=self.limits.kd_damping.copy(), tau_ff=zero.copy()))

    def _enter_damping(self, state: JointState | None) -> None:
        self.mode = SafetyMode.DAMPING
        self._epoch += 1
        self._pending = self._last_sent = self._damping_command(state)

    def _send_pending(self) -> None:
        with self._lock:
            command, self._pending = self._pending, None
        if command is not None and self.backend.state is S.ACTIVE:
            self.backend.write(command)

    def _reassert_safe(self) -> None:
        with self._lock:
            if self._state is S.ESTOP:
                command = None
            elif self.mode is SafetyMode.DAMPING:
                command = self._damping_command()
            else:
                return
        if command is None:
            self.backend.estop()  # sends the backend's damping again
        elif self.backend.state is S.ACTIVE:
            self.backend.write(command)

    def _check_temperature(self, temperature: np.ndarray, state: JointState) -> None:
        lim = self.limits
        hot = (temperature >= lim.temperature_warn) & ~self._warned
        for i in np.flatnonzero(hot):
            self._intervene("temperature_warn", f"joint {i} at {temperature[i]:.1f} °C")
            self._warned[i] = True
        span = lim.temperature_fault - lim.temperature_derate
        self._derate = np.clip(1.0 - 0.8 * (temperature - lim.temperature_derate) / span, 0.2, 1.0)
        if np.any(temperature > lim.temperature_derate):
            self.interventions["temperature_derate"] += 1
        if np.any(temperature >= lim.temperature_fault) and self._state is S.ACTIVE:
            joints = np.flatnonzero(temperature >= lim.temperature_fault).tolist()
            self._intervene("temperature_fault", f"joints {joints} at or above {lim.temperature_fault} °C")
            self._enter_damping(state)
            self._state = S.FAULT

    def _filter(self, cmd: JointCommand) -> JointCommand:
        # Every control tick passes here: one compiled pass (the command was validated finite).
        state = self._last_good
        reference = self._last_target if self._last_target is not None else state.q
        lim = self.limits
        ramp = min(1.0, (self._ticks + 1) * lim.control_dt / lim.soft_start) if lim.soft_start > 0 else 1.0
        self._ticks += 1
        q, dq, kp, kd, tau_ff, flags, within = filter_command(
            *(np.asarray(a, dtype=float) for a in (cmd.q, cmd.dq, cmd.kp, cmd.kd, cmd.tau_ff)), state.q, state.dq,
            reference, *self._filter_limits, self._derate, ramp, WITHIN_EFFORT_MARGIN, self.demanded_peak)
        if flags.any():
            for flag, kind in FLAG_KINDS:
                joints = np.flatnonzero(flags & flag)
                if joints.size:
                    self._intervene(kind, f"joints {joints.tolist()}")
        self._last_target = q
        filtered = JointCommand(q=q, dq=dq, kp=kp, kd=kd, tau_ff=tau_ff)
        # Within the effort with a margin far above rounding: _bounded would return it unchanged.
        return filtered if within else self._bounded(filtered)

    def _bounded(self, cmd: JointCommand) -> JointCommand:
        """``cmd`` with its torque at the last good measured state within ± the (derated) effort."""
        state, lim = self._last_good, self.limits
        if state is None:  # nothing measured yet: only damping is ever sent then
            return cmd
        q, kp, kd, tau_ff, changed = bound_servo_torque(cmd.q, cmd.dq, cmd.kp, cmd.kd, cmd.tau_ff, state.q, state.dq,
                                                        lim.effort * self._derate, lim.lower, lim.upper)
        if changed.any():
            self._intervene("torque_clamped", f"joints {np.flatnonzero(changed).tolist()}")
        return JointCommand(q=q, dq=cmd.dq, kp=kp, kd=kd, tau_ff=tau_ff)
