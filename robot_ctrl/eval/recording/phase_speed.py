"""PhaseSpeedRecorder: the measured CoM's forward speed against the gait phase, for the gait profile g(φ)."""

from __future__ import annotations

import numpy as np

from robot_ctrl.control.controllers.walking_controller import WalkingController


class PhaseSpeedRecorder:
    """(gait phase, measured CoM forward speed) of every tick within cycles 1..``cycles``; its
    ``reason`` ends the run after them."""

    def __init__(self, controller: WalkingController, cycles: int):
        self.controller, self.cycles = controller, cycles
        self.phases: list[float] = []
        self.speeds: list[float] = []
        self._phase = None

    def on_command(self, tick) -> None:
        self._phase = self.controller.gait_phase(tick.t) if tick.k else None
        if self._phase is not None and 2 * np.pi <= self._phase < 2 * np.pi * (self.cycles + 1):
            self.phases.append(self._phase)
            self.speeds.append(self.controller.estimate.com_velocity[0])

    def on_state(self, tick) -> None:
        pass

    def reason(self, tick) -> str | None:
        done = self._phase is not None and self._phase >= 2 * np.pi * (self.cycles + 1)
        return f"{self.cycles} gait cycles measured" if done else None
