"""Pacer: holds a loop on real hardware to absolute deadlines ``t0 + k dt``.

A simulated robot waits for its controller (lock-step); a real one does not, so the loop must
keep time itself. Deadlines are absolute, so waiting errors do not accumulate; a tick whose work
ends after its deadline is an overrun, and the schedule starts again from then (the loop never
runs a burst of ticks to catch up). ``report()`` gives the overruns and the lateness of the wake-ups
(how long after its deadline each tick began): the loop's jitter.
"""

from __future__ import annotations

import os
import time
from typing import Callable

import numpy as np


class Pacer:
    def __init__(self, dt: float, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep):
        self.dt, self.clock, self.sleep = dt, clock, sleep
        self._deadline: float | None = None
        self.overruns = 0
        self.lateness: list[float] = []  # [s] per tick

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
                self._deadline = now  # start again from here: no burst of late ticks
            else:
                self.sleep(self._deadline - now)
        self.lateness.append(max(self.clock() - self._deadline, 0.0))

    def report(self) -> dict:
        late = np.array(self.lateness) * 1e3
        return {"ticks": len(late), "overruns": self.overruns,
                "lateness_ms": {"median": round(float(np.median(late)), 3) if late.size else None,
                                "p99": round(float(np.percentile(late, 99)), 3) if late.size else None,
                                "max": round(float(late.max()), 3) if late.size else None}}
