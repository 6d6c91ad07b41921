"""Compiled kernels: the numba functions of the control loop, each registered with the argument
types its callers pass, so that they are all loaded (or, on a machine's first run, compiled)
before the robot is brought up rather than inside the first paced ticks.

numba compiles a function on its first call with new argument types and caches the machine code on
disk (``cache=True``). Left to that, a machine's first run compiles each kernel inside the first
control tick that calls it, seconds that a paced run on real servos cannot wait: the watchdog
would send the servos to damping. :func:`load_kernels` (called by the safety layer before it
activates the backend, docs/hardware.md) compiles or loads every registered signature at once.
A call with other types still compiles on first use, as any numba function would.
"""

from __future__ import annotations

import threading
import time
from typing import Callable

from numba import njit, types
from numba.core.registry import CPUDispatcher

#: Argument types as the control loop passes them: C-contiguous float64 and int64 arrays.
VECTOR = types.float64[::1]
MATRIX = types.float64[:, ::1]
FORTRAN_MATRIX = types.float64[::1, :]
STACK = types.float64[:, :, ::1]  # (k, rows, columns)
INDICES = types.int64[::1]
FLOAT = types.float64
INT = types.int64

_REGISTERED: list[tuple[CPUDispatcher, tuple[tuple, ...]]] = []


def kernel(*signatures: tuple):
    """``@njit(cache=True)``, registered with the argument types of its calls from Python (tuples
    of numba types). A kernel called only from other kernels takes none: it is compiled into them."""

    def register(function) -> CPUDispatcher:
        dispatcher = njit(cache=True)(function)
        _REGISTERED.append((dispatcher, signatures))
        return dispatcher

    return register


def load_kernels(slow: Callable[[int, int], None] | None = None, after: float = 1.0, every: float = 5.0) -> float:
    """Load from the disk cache, or compile, every registered kernel of the modules imported so far
    for its registered argument types; the seconds it took (well under one once cached, tens on a
    machine's first run). Quick once they are loaded. ``slow(done, total)`` is told, from another
    thread, when it has taken ``after`` seconds and then every ``every`` seconds (kernels done of
    all), so that a first run does not wait in silence."""
    start = time.perf_counter()
    total = sum(len(signatures) for _, signatures in _REGISTERED)
    done = [0]
    finished = threading.Event()

    def tell() -> None:
        wait = after
        while not finished.wait(wait):
            slow(done[0], total)
            wait = every

    teller = threading.Thread(target=tell, name="kernel-progress", daemon=True) if slow is not None else None
    if teller is not None:
        teller.start()
    try:
        for dispatcher, signatures in _REGISTERED:
            for signature in signatures:
                dispatcher.compile(signature)
                done[0] += 1
    finally:
        finished.set()
        if teller is not None:
            teller.join()
    return time.perf_counter() - start


def registered() -> list[CPUDispatcher]:
    """The kernels registered so far (those of the modules imported so far)."""
    return [dispatcher for dispatcher, _ in _REGISTERED]
