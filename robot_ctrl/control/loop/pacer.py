"""Pacer: holds a loop on real hardware to absolute deadlines ``t0 + k dt``.

A simulated robot waits for its controller (lock-step); a real one does not, so the loop must
keep time itself. Deadlines are absolute, so waiting errors do not accumulate; a tick whose work
ends after its deadline is an overrun, and the schedule starts again from then (the loop never
runs a burst of ticks to catch up). ``report()`` gives the overruns and the lateness of the wake-ups
(how long after its deadline each tick began): the loop's jitter. An overrun in which the loop's
thread ran on a CPU for less than half of the tick's wall time is also counted as off the CPU: the
host descheduled it, or it waited on I/O or another thread, rather than computed too long.
"""

from __future__ import annotations

import os
import time
from collections import deque
from typing import Callable

import numpy as np

LATENESS_WINDOW = 60_000  # ticks: 5 min at 200 Hz


class Pacer:
    def __init__(self, dt: float, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep):
        self.dt, self.clock, self.sleep = dt, clock, sleep
        self._deadline: float | None = None
        self.overruns = 0
        self.overruns_off_cpu = 0
        self._tick_start: tuple[float, float] | None = None  # (wall [s], thread CPU [s]) at the wake-up
        self.ticks = 0
        self.max_lateness = 0.0  # [s] over every tick
        self.lateness: deque[float] = deque(maxlen=LATENESS_WINDOW)  # [s] of the latest ticks

    @staticmethod
    def request_realtime() -> bool:
        """Ask for real-time scheduling (SCHED_FIFO) of this process; False where not permitted."""
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
            return True
        except (AttributeError, PermissionError, OSError):
            return False

    def wait(self) -> None:
        """Sleep until the next tick's deadline (the first call starts the schedule)."""
        now = self.clock()
        if self._deadline is None:
            self._deadline = now
        else:
            self._deadline += self.dt
            if now > self._deadline:
                self.overruns += 1
                self.overruns_off_cpu += self._ran_off_cpu()
                self._deadline = now  # start again from here: no burst of late ticks
            else:
                self.sleep(self._deadline - now)
        late = max(self.clock() - self._deadline, 0.0)
        self.lateness.append(late)
        self.ticks += 1
        self.max_lateness = max(self.max_lateness, late)
        self._tick_start = (time.monotonic(), time.thread_time())

    def _ran_off_cpu(self) -> bool:
        """Whether this thread ran on a CPU for less than half of the wall time since the last
        wake-up (real time, whatever ``clock`` keeps)."""
        if self._tick_start is None:
            return False
        wall, cpu = time.monotonic() - self._tick_start[0], time.thread_time() - self._tick_start[1]
        return cpu < 0.5 * wall

    def report(self) -> dict:
        """Overruns (and how many of them off the CPU) and the largest lateness over every tick;
        median and 99th percentile over the latest ``LATENESS_WINDOW`` ticks (a run of hours keeps
        a bounded record)."""
        late = np.array(self.lateness) * 1e3
        return {"ticks": self.ticks, "overruns": self.overruns, "overruns_off_cpu": self.overruns_off_cpu,
                "lateness_ms": {"median": round(float(np.median(late)), 3) if late.size else None,
                                "p99": round(float(np.percentile(late, 99)), 3) if late.size else None,
                                "max": round(self.max_lateness * 1e3, 3) if late.size else None}}
