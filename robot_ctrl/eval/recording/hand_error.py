"""HandError: the balance demo's measured hand error at the end of its reach."""

from __future__ import annotations

from typing import Callable

import numpy as np
import pinocchio as pin

from robot_ctrl.control.controllers.balance_controller import BalanceController
from robot_ctrl.robot.model import configuration


class HandError:
    """Logs each phase as it starts, and measures the right hand (forward kinematics of the read
    state) against the reach target at the end of the ``hold_reach`` phase."""

    def __init__(self, controller: BalanceController, log: Callable[[str], None]):
        self.controller, self.log = controller, log
        self.robot = controller.robot
        self.data = pin.Data(self.robot.pin)
        self.error: float | None = None
        self._phase = None

    def on_command(self, tick) -> None:
        if self.controller.phase != self._phase:
            self._phase = self.controller.phase
            self.log(f"t = {tick.t:6.2f} s  {self._phase}")

    def on_state(self, tick) -> None:
        motion = self.controller.motion
        if self._phase == "hold_reach" and motion.phase_at(tick.t + self.controller.dt).name != "hold_reach":
            state, robot = tick.states[0], self.robot
            pin.framesForwardKinematics(robot.pin, self.data,
                                        configuration(robot, state.base_pos, state.base_quat_xyzw, state.q))
            hand = self.data.oMf[robot.frame_ids["right_hand"]].translation
            self.error = float(np.linalg.norm(hand - motion.hand_target))
            self.log(f"t = {state.t:6.2f} s  hand error {self.error * 1000:.1f} mm")
