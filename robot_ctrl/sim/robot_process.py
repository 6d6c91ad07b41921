"""RobotProcess: a backend run in a process of its own, as a robot runs its servos on its own computer.

The controller's process holds this adapter; the backend (a ``MujocoBackend``, say) lives in a
child process. ``write()`` puts the command in shared memory (:class:`SharedCommand`), wakes the
child and returns at once; the child writes the command to its backend (for MuJoCo: simulates the
control period), reads the backend's state into shared memory (:class:`SharedState`) and flags it
done. ``read()`` waits for that state. So the controller computes while the robot moves, as it
would with a real robot. Lifecycle calls (``configure``, ``activate``, ``estop``, ...) are
forwarded and waited for; a write followed by another write (or by a lifecycle call) first waits
for the first write's period to end. Nothing else differs from calling the backend directly: the
same calls reach it in the same order, so a run gives the same numbers either way. After each
write the child calls the backend's ``run_ahead()``: with a simulated command latency of a period
or more the robot then simulates the next period while the controller computes its command
(``MujocoBackend``), the states read still lock-step's, bit for bit.

Why a process and not a thread: a thread has to take Python's interpreter lock from the busy
controller to start each period, a hand-over that cost several times what waking a process costs
(docs/architecture.md). Why a spin on a flag for the reply, and a semaphore for the
call: the controller has nothing else to do while it waits, and it would take as long again to
wake; the child waits for about half of each tick, time another process (the dynamic filter's
worker) can use.

Errors: an exception the backend raises in the child is raised again here, by the call that takes
its reply (for a write: the next ``read``, ``write`` or lifecycle call), and the adapter goes to
FAULT as for any backend error. If the child process dies, calls raise RuntimeError.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import signal
import time
from typing import Callable, NoReturn

import numpy as np

from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.parent_death import die_with_parent
from robot_ctrl.sim.shared_state import SharedCommand, SharedState

CALLS = ("write", "read", "configure", "activate", "deactivate", "estop", "reset", "close")
SPIN_S = 2e-3  # [s] a reply is spun for this long, then polled every POLL_S (lifecycle calls)
POLL_S = 1e-4


class _CallSlot:
    """One call and its reply in shared memory: the call's number and name, the reply's number
    and kind (0 done, 1 done with a pickled value, 2 failed with a pickled exception), and the
    pickled bytes. The caller posts a semaphore; the child sets the reply's number last."""

    SEQ, CALL, REPLY, KIND, LENGTH = range(5)
    PAYLOAD = 1 << 16  # [bytes]

    def __init__(self, context):
        self.words = context.RawArray("q", 5)
        self.payload = context.RawArray("B", self.PAYLOAD)
        self.posted = context.Semaphore(0)
        self._attach()
        self.w[self.SEQ] = 1  # call 1: building the backend

    def _attach(self) -> None:
        self.w = np.frombuffer(self.words, dtype=np.int64)
        self.b = np.frombuffer(self.payload, dtype=np.uint8)

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k not in ("w", "b")}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._attach()

    # Caller side.
    def post(self, call: str) -> int:
        seq = int(self.w[self.SEQ]) + 1
        self.w[self.CALL] = CALLS.index(call)
        self.w[self.SEQ] = seq
        self.posted.release()
        return seq

    def done(self, seq: int) -> bool:
        return self.w[self.REPLY] == seq

    def result(self):
        """The reply's value (None unless the call returned one); raises the call's exception."""
        kind = self.w[self.KIND]
        if kind == 0:
            return None
        value = pickle.loads(self.b[:self.w[self.LENGTH]].tobytes())
        if kind == 2:
            raise value
        return value

    # Child side.
    def take(self, timeout: float) -> str | None:
        """The next call, or None after ``timeout`` seconds without one."""
        if not self.posted.acquire(timeout=timeout):
            return None
        return CALLS[self.w[self.CALL]]

    def reply(self, value=None, failed: bool = False) -> None:
        kind = 0
        if failed or value is not None:
            data = _pickled(value)
            if len(data) > self.PAYLOAD:
                data = _pickled(RuntimeError(f"{type(value).__name__}: {str(value)[:1000]} "
                                             "(reply too long to pass back)"))
            self.b[:len(data)] = np.frombuffer(data, dtype=np.uint8)
            self.w[self.LENGTH] = len(data)
            kind = 2 if failed else 1
        self.w[self.KIND] = kind
        self.w[self.REPLY] = self.w[self.SEQ]  # last: the caller spins on it


def _pickled(value) -> bytes:
    try:
        return pickle.dumps(value)
    except Exception:  # an exception that does not pickle
        return pickle.dumps(RuntimeError(f"{type(value).__name__}: {value}"))


def _serve(slot: _CallSlot, backend: Callable[[], HardwareAdapter], command: SharedCommand,
           state: SharedState) -> None:
    """Child process: build the backend, then answer calls until ``close`` or until the
    controller's process is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C stops the controller, which closes us
    die_with_parent()
    parent = os.getppid()
    try:
        hw = backend()
    except Exception as exc:
        slot.reply(exc, failed=True)
        return
    slot.reply()
    ahead_failure = None  # what the period run ahead raised: the next write's or read's reply
    while True:
        call = slot.take(timeout=1.0)
        if call is None:
            if os.getppid() != parent:  # orphaned
                hw.close()
                return
            continue
        if ahead_failure is not None and call in ("write", "read"):
            slot.reply(ahead_failure, failed=True)
            ahead_failure = None
            continue
        ahead_failure = None  # a lifecycle call (an e-stop, a close) runs all the same
        try:
            wrote = call == "write"
            if wrote:
                hw.write(command.get())
                call = "read"
            if call == "read":
                measured = hw.read()
                state.put(measured)
                value = measured.floor_contacts or None
            else:
                value = getattr(hw, call)()
        except Exception as exc:
            slot.reply(exc, failed=True)
        else:
            slot.reply(value)
            if wrote:
                try:
                    hw.run_ahead()  # the next period, where its command is known, while the controller computes
                except Exception as exc:
                    ahead_failure = exc
        if call == "close":
            return


class RobotProcess(HardwareAdapter):
    """``backend``: builds the backend in the child process (for instance
    ``functools.partial(MujocoBackend, robot)``); ``nj``: its number of joints. The constructor
    returns once the backend is built, and raises what its construction raised."""

    def __init__(self, backend: Callable[[], HardwareAdapter], nj: int, name: str = "robot"):
        super().__init__(nj)
        # fork shares the loaded models; other platforms pickle ``backend`` to a fresh interpreter.
        context = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
        self._slot = _CallSlot(context)
        self._command = SharedCommand.allocate(nj, context)
        self._measured = SharedState.allocate(nj, context)
        self._process = context.Process(target=_serve, args=(self._slot, backend, self._command, self._measured),
                                        daemon=True, name=name)
        self._process.start()
        self._seq = 1  # the call last posted (1: building the backend)
        self._pending = False  # a write whose period has not been waited for
        self._last: JointState | None = None  # the state after the last waited-for write
        try:
            self._reply()
        except BaseException:
            self._process.join(timeout=5.0)
            raise

    # Backend hooks: forwarded to the child ------------------------------------------------------
    def _on_configure(self) -> None:
        self._call("configure")

    def _on_activate(self) -> None:
        self._call("activate")

    def _on_deactivate(self) -> None:
        self._call("deactivate")

    def _on_estop(self) -> None:
        self._call("estop")

    def _on_reset(self) -> None:
        self._call("reset")

    def _on_close(self) -> None:
        try:
            if self._process.is_alive():
                self._call("close")
        finally:
            self._process.join(timeout=5.0)
            if self._process.is_alive():
                self._process.terminate()

    def _write(self, command: JointCommand) -> None:
        self._settle()
        self._command.put(command)
        self._seq = self._slot.post("write")
        self._pending = True

    def _read(self) -> JointState:
        if self._pending:
            self._settle()
            return self._last
        return self._measured.get(self._call("read") or ())

    # Calls ---------------------------------------------------------------------------------------
    def _call(self, call: str):
        self._settle()
        self._seq = self._slot.post(call)
        return self._reply()

    def _settle(self) -> None:
        """Wait for the period of a write still running, and keep its state."""
        if self._pending:
            self._pending = False
            self._last = self._measured.get(self._reply() or ())

    def _reply(self):
        """Wait for the last call's reply: spin (the period ends within a tick), then poll."""
        slot, seq = self._slot, self._seq
        if not slot.done(seq):
            start = time.perf_counter()
            while not slot.done(seq):
                if time.perf_counter() - start > SPIN_S:
                    if not self._process.is_alive():
                        self._stopped()
                    time.sleep(POLL_S)
        return slot.result()

    def _stopped(self) -> NoReturn:
        self._process.join(timeout=1.0)
        raise RuntimeError(f"the robot process {self._process.name!r} stopped (exit code {self._process.exitcode})"
                           "; its error, if it raised one, is printed above") from None
