"""HardwareAdapter: the lifecycle and read/write interface every backend implements.

Lifecycle (after ros2_control)::

    UNCONFIGURED --configure--> INACTIVE --activate--> ACTIVE --deactivate--> INACTIVE
    any state --estop--> ESTOP (latched)        a backend failure --> FAULT
    ESTOP or FAULT --reset--> INACTIVE (explicit; activate again to move)
    any state --close--> closed (no further calls; from ESTOP or FAULT the motors are damped and
                         disabled first; Ctrl-C and SIGTERM are held until it is done)

``read()`` works once configured; ``write()`` only while ACTIVE. Commands are validated here,
before a backend sees them, so a NaN or a malformed array never reaches an actuator.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod

import numpy as np

from robot_ctrl.hw.held_signals import signals_held
from robot_ctrl.hw.types import JointCommand, JointState, LifecycleState

S = LifecycleState
logger = logging.getLogger("robot_ctrl.hw")


class LifecycleError(RuntimeError):
    """A call was made in a lifecycle state that does not allow it."""


class HardwareFault(RuntimeError):
    """A backend failed (a bus error, a silent motor); the safety layer put the servos in damping
    and latched FAULT. The message says what failed."""


class HardwareAdapter(ABC):
    """The interface every hardware backend implements (after ros2_control): a lifecycle
    (``configure``, ``activate``, ``deactivate``, ``estop``, ``reset``, ``close``; module docstring),
    ``read() -> JointState`` and ``write(JointCommand)`` for ``nj`` joints in the robot config's
    order, SI units. A backend implements the ``_on_*`` hooks, ``_read`` and ``_write``; a backend
    call that raises leaves the adapter in ``FAULT``."""

    def __init__(self, nj: int):
        self.nj = nj
        self._state = S.UNCONFIGURED
        self._closed = False
        # Bus statistics (they stay zero where there is no bus): replies missed in all, per motor in a
        # row, replies that came after their tick's wait, error frames, frames of other senders, second
        # answers to one request (a duplicate or another node's spoof: neither is taken).
        self.missing_replies = 0
        self.missed = np.zeros(nj, dtype=int)
        self.late_replies = 0
        self.error_frames = 0
        self.foreign_frames = 0
        self.duplicate_replies = 0

    @property
    def state(self) -> LifecycleState:
        return self._state

    @property
    def drive_timeout_joints(self) -> tuple[str, ...]:
        """Joints whose drive stops by itself when the host stops sending (none by default)."""
        return ()

    @property
    def without_drive_timeout(self) -> str | None:
        """Why the drives without a timeout of their own may be enabled, as the bus config states it."""
        return None

    def _require(self, call: str, *allowed: LifecycleState) -> None:
        if self._closed:
            raise LifecycleError(f"{call}() after close()")
        if self._state not in allowed:
            names = ", ".join(s.value for s in allowed)
            raise LifecycleError(f"{call}() is not allowed in state {self._state.value!r} (allowed: {names})")

    def configure(self) -> None:
        self._require("configure", S.UNCONFIGURED)
        self._guarded(self._on_configure)
        self._state = S.INACTIVE

    def activate(self) -> None:
        self._require("activate", S.INACTIVE)
        self._guarded(self._on_activate)
        self._state = S.ACTIVE

    def bring_up(self) -> None:
        """:meth:`configure` and :meth:`activate`, whichever is still to do (a start sequence may
        have done both)."""
        if self._state is S.UNCONFIGURED:
            self.configure()
        if self._state is S.INACTIVE:
            self.activate()

    def deactivate(self) -> None:
        self._require("deactivate", S.ACTIVE)
        self._guarded(self._on_deactivate)
        self._state = S.INACTIVE

    def estop(self) -> None:
        """Latch the emergency stop, then put the servos in a safe (damping) mode. Latched before the
        bus is touched, so a failing send still leaves no way to write; each call sends again."""
        if self._closed:
            return
        self._state = S.ESTOP
        self._on_estop()

    def reset(self) -> None:
        """Clear a latched e-stop or a fault: the backend goes back to INACTIVE (servos still safe)."""
        self._require("reset", S.ESTOP, S.FAULT)
        self._guarded(self._on_reset)
        self._state = S.INACTIVE

    def close(self) -> None:
        """Release the backend. After an e-stop or a fault every motor is sent damping (again: a
        fault may have come before any) and then disabled, each step best effort (a bus that fails
        is logged, and closed anyway). Ctrl-C and SIGTERM wait until it is done."""
        if self._closed:
            return
        with signals_held():
            try:
                if self._state in (S.ESTOP, S.FAULT):
                    self._safe_stop()
            finally:
                self._on_close()
                self._closed = True

    def _safe_stop(self) -> None:
        for step, call in (("damping", self._on_estop), ("disabling the motors", self._on_disable)):
            try:
                call()
            except Exception:
                logger.exception("close: %s after %s failed", step, self._state.value)

    def read(self) -> JointState:
        self._require("read", S.INACTIVE, S.ACTIVE, S.FAULT, S.ESTOP)
        return self._guarded(self._read)

    def write(self, command: JointCommand) -> None:
        self._require("write", S.ACTIVE)
        command.validate(self.nj)
        self._guarded(lambda: self._write(command))

    def run_ahead(self) -> bool:
        """Simulate the next control period before its command is written, where the backend already
        holds the command that period applies (a simulated command latency of a period or more): the
        robot moves on while the controller computes, and the next ``write`` only queues its command.
        ``RobotProcess`` calls it after each write. False where nothing ran (the default: a real
        robot moves on by itself, and a simulation without latency needs the next command)."""
        if self._closed or self._state is not S.ACTIVE:
            return False
        return self._guarded(self._run_ahead)

    def _guarded(self, call):
        """``call()``; whatever stops it (a Ctrl-C halfway through enabling the drives too) latches FAULT,
        from which :meth:`close` brings every motor to its safe state."""
        try:
            return call()
        except BaseException:
            self._state = S.FAULT
            raise

    # Backend hooks.
    @abstractmethod
    def _on_configure(self) -> None: ...

    def _on_activate(self) -> None:
        pass

    def _on_deactivate(self) -> None:
        pass

    @abstractmethod
    def _on_estop(self) -> None: ...

    def _on_reset(self) -> None:
        pass

    def _on_disable(self) -> None:
        """Torque off on every motor, whatever the lifecycle state (:meth:`close` after an e-stop or
        a fault). A simulation has nothing to disable."""

    def _on_close(self) -> None:
        pass

    @abstractmethod
    def _read(self) -> JointState: ...

    @abstractmethod
    def _write(self, command: JointCommand) -> None: ...

    def _run_ahead(self) -> bool:
        return False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
