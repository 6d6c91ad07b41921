"""PreviewIK: the whole-body configuration of a preview sample, one Newton step at a time.

The dynamic filter needs, for every sample of the plan, the configuration the controller's IK
would reach: feet, CoM and waist orientation as planned, the joints otherwise at the posture
reference (upper body from its reference, legs at half-sitting). The controller's IK solves this
as a strict hierarchy of QPs (``robot_ctrl.sot``); the preview solves the same tasks as one
weighted least-squares Newton step, the posture with a small weight μ so it acts (almost) only
in the null space of the tasks (it biases them by O(μ²), micrometres)::

    e = [p*_L − p_L, log3(R*_L R_Lᵀ), p*_R − p_R, log3(R*_R R_Rᵀ), c* − c, log3(R*_w R_wᵀ)]  (world frame)
    (JᵀJ + μ² PᵀP + λI) Δv = Jᵀe + μ² Pᵀ(q*_joints − q_joints)

with P selecting the joints. Joint limits are left out: the preview only predicts the ZMP of the
plan, it does not command the robot. Cost: one Jacobian evaluation and a 38 x 38 Cholesky solve
for Talos instead of a three-level QP hierarchy.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from robot_ctrl.geometry import SIDES
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.sot.com_task import ComTask
from robot_ctrl.sot.frame_task import FrameTask
from robot_ctrl.sot.whole_body_ik import hand_tool_dofs

POSTURE_WEIGHT = 1e-3  # μ: its bias on the tasks scales with μ², its pull in their null space does not (μ² ≫ λ)
DAMPING = 1e-8  # λ
_posv = lapack.dposv


class PreviewIK:
    """The controller's IK tasks (``robot_ctrl.sot``: feet, CoM, waist orientation), stacked into
    one weighted least-squares step: their errors and Jacobians are the strict hierarchy's."""

    def __init__(self, robot: RobotModel):
        self.robot = robot
        model = robot.pin
        self.data = model.createData()
        ids = robot.frame_ids
        self.feet = [FrameTask(f"{s}_foot", ids[f"{s}_foot"]) for s in SIDES]
        self.com = ComTask(locked_dofs=hand_tool_dofs(robot))  # as in the controller's CoM task
        self.waist = FrameTask("waist", ids["waist"], axes=("rx", "ry", "rz"))
        self.tasks = (*self.feet, self.com, self.waist)
        self.q = robot.q_half_sitting.copy()
        self._J = np.zeros((18, model.nv))
        self._e = np.zeros(18)
        self._diagonal = np.full(model.nv, DAMPING)  # λ I + μ² PᵀP
        self._diagonal[robot.v_index] += POSTURE_WEIGHT**2

    def set_configuration(self, q: np.ndarray) -> None:
        self.q = np.array(q, dtype=float)

    def step(self, feet: list[pin.SE3], com: np.ndarray, waist: np.ndarray, posture: np.ndarray) -> np.ndarray:
        """One Newton step towards the feet poses (left, right), CoM position and waist rotation, all
        in the world frame, and the joint ``posture`` (robot joint order). Returns the new configuration."""
        robot, model, data, q, J, e = self.robot, self.robot.pin, self.data, self.q, self._J, self._e
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for task, target in zip(self.feet, feet):
            task.set_target(target)
        self.com.set_target(com)
        self.waist.set_target(pin.SE3(waist, np.zeros(3)))
        row = 0
        for task in self.tasks:
            task_error, task_jacobian = task.error_and_jacobian(model, data, q)
            e[row : row + len(task_error)] = task_error
            J[row : row + len(task_error)] = task_jacobian
            row += len(task_error)
        H = J.T @ J
        H.flat[:: H.shape[0] + 1] += self._diagonal
        g = J.T @ e
        g[robot.v_index] += POSTURE_WEIGHT**2 * (posture - q[robot.q_index])
        _, dv, info = _posv(H, g)
        if info != 0:
            raise np.linalg.LinAlgError(f"preview IK: singular system (LAPACK posv info {info})")
        self.q = pin.integrate(model, q, dv)
        return self.q
