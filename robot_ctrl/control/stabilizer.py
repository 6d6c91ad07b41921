"""DcmStabilizer: balance feedback for a position-controlled robot (placeholder gains: off)."""

from __future__ import annotations

import numpy as np

from robot_ctrl.hw.types import JointState
from robot_ctrl.robot.model import RobotModel


class DcmStabilizer:
    def __init__(self, robot: RobotModel, com_height: float, enabled: bool = False):
        self.enabled = enabled

    def correction(self, state: JointState, ref, dt: float) -> np.ndarray:
        return np.zeros(2)
