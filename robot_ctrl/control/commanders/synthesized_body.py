"""SynthesizedBody: the robot with the synthesized upper-body angles, by forward kinematics.

Where the hands would be, and where the CoM would sit against the pelvis, if the upper body took the
angles the synthesis gives, at a given pelvis and legs (the IK's reference, or the measured state).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robot_ctrl.geometry import SIDES
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.synthesis.demonstrations import upper_body_joints


class SynthesizedBody:
    def __init__(self, robot: RobotModel):
        self.robot = robot
        names = list(robot.joint_names)
        self.upper = np.array([names.index(n) for n in upper_body_joints(robot)])  # joint order
        self._data = robot.pin.createData()

    def configuration(self, upper_q: np.ndarray, q: np.ndarray) -> np.ndarray:
        """``q`` (Pinocchio configuration) with the upper body at ``upper_q``."""
        q = np.array(q, dtype=float)
        q[self.robot.q_index[self.upper]] = upper_q
        return q

    def hands(self, upper_q: np.ndarray, q: np.ndarray) -> dict[str, np.ndarray]:
        """World hand positions [m] with the upper body at ``upper_q`` and the rest as in ``q``
        (Pinocchio configuration)."""
        r = self.robot
        pin.framesForwardKinematics(r.pin, self._data, self.configuration(upper_q, q))
        return {s: self._data.oMf[r.frame_ids[f"{s}_hand"]].translation.copy() for s in SIDES}

    def hands_from_pelvis(self, upper_q: np.ndarray, q: np.ndarray, yaw: float) -> dict[str, np.ndarray]:
        """The hands' offsets from the pelvis [m], the pelvis turned to ``yaw`` [rad] (world axes)."""
        q = np.array(q, dtype=float)
        q[:3], q[3:7] = 0.0, [0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)]
        return self.hands(upper_q, q)

    def com_from_pelvis(self, upper_q: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Horizontal offset of the CoM from the pelvis (world axes) [m]."""
        q = self.configuration(upper_q, q)
        return pin.centerOfMass(self.robot.pin, self._data, q)[:2] - q[:2]
