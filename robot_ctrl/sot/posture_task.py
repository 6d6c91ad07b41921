"""PostureTask: hold chosen joints at reference angles."""

from __future__ import annotations

import numpy as np

from robot_ctrl.sot.task import Task


class PostureTask(Task):
    """Error ``w_j (q*_j - q_j)`` [rad] for the joints at Pinocchio indices ``q_index``/``v_index``,
    with per-joint weights ``w_j`` (``joint_weights``, default 1) on top of the task's weight."""

    def __init__(self, name: str, q_index: np.ndarray, v_index: np.ndarray, nv: int, **kw):
        super().__init__(name, **kw)
        self.q_index = np.asarray(q_index)
        self.target = np.zeros(len(self.q_index))
        self._J = np.zeros((len(self.q_index), nv))
        self._J[np.arange(len(self.q_index)), v_index] = 1.0
        self.joint_weights = np.ones(len(self.q_index))
        self._weighted_J = self._J

    def set_joint_weights(self, weights: np.ndarray) -> None:
        self.joint_weights = np.asarray(weights, dtype=float)
        self._weighted_J = self.joint_weights[:, None] * self._J

    def set_target(self, angles: np.ndarray) -> None:
        self.target = np.asarray(angles, dtype=float)

    def error_and_jacobian(self, model, data, q):
        return self.joint_weights * (self.target - q[self.q_index]), self._weighted_J
