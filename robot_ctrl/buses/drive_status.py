"""What emulated drives are doing, for another process to watch: ``StatusFile`` rewrites a JSON
object every ``PERIOD`` (atomically: a reader sees the old object or the new one, never half)::

    {"t": wall_time,
     "drives": {joint: {"enabled": bool, "kp": float, "kd": float, "command_age_s": float | null,
                        "stopped": bool}}}

``kp`` and ``kd`` are what the drive acts with now, joint side (0 when it is disabled or limp);
``command_age_s`` is the wall-clock time since its last command (null before the first);
``stopped``: its own watchdog stopped it where it is (a Dynamixel Bus Watchdog: torque on, the goal
frozen at the present position).
"""

from __future__ import annotations

import json
import math
import os
import threading
import time
from pathlib import Path
from typing import Callable

PERIOD = 0.01  # [s] between rewrites (the command line promises at most 20 ms)


def drive_entry(enabled: bool, kp: float, kd: float, command_age_s: float, stopped: bool = False) -> dict:
    """One drive's status (``command_age_s`` NaN before its first command)."""
    return {"enabled": enabled, "kp": float(kp), "kd": float(kd),
            "command_age_s": None if math.isnan(command_age_s) else float(command_age_s), "stopped": stopped}


class StatusFile:
    def __init__(self, path: Path, read: Callable[[], dict[str, dict]]):
        """``read``: the drives' status now (``drive_entry`` per joint)."""
        self.path = Path(path)
        self.read = read
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="drive-status", daemon=True)

    def start(self) -> None:
        self.write()
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self.write()

    def write(self) -> None:
        partial = self.path.with_name(self.path.name + ".partial")
        partial.write_text(json.dumps({"t": time.time(), "drives": self.read()}))
        os.replace(partial, self.path)

    def _run(self) -> None:
        while not self._stop.wait(PERIOD):
            self.write()
