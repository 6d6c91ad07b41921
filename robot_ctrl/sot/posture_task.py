"""PostureTask: hold chosen joints at reference angles."""

from __future__ import annotations

import numpy as np

from robot_ctrl.kernels import FLOAT, INDICES, VECTOR, kernel
from robot_ctrl.sot.task import Task


class PostureTask(Task):
    """Error ``w_j (q*_j - q_j)`` [rad] for the joints at Pinocchio indices ``q_index``/``v_index``,
    with per-joint weights ``w_j`` (``joint_weights``, default 1) on top of the task's weight."""

    def __init__(self, name: str, q_index: np.ndarray, v_index: np.ndarray, nv: int, **kw):
        super().__init__(name, **kw)
        self.q_index = np.asarray(q_index, dtype=np.int64)
        self.target = np.zeros(len(self.q_index))
        self._J = np.zeros((len(self.q_index), nv))
        self._J[np.arange(len(self.q_index)), v_index] = 1.0
        self.joint_weights = np.ones(len(self.q_index))
        self._weighted_J = self._J
        self._scaled: tuple[float, np.ndarray] | None = None  # the task weight, and the weighted J times it

    def set_joint_weights(self, weights: np.ndarray) -> None:
        self.joint_weights = np.asarray(weights, dtype=float)
        self._weighted_J = self.joint_weights[:, None] * self._J
        self._scaled = None

    def set_target(self, angles: np.ndarray) -> None:
        self.target = np.ascontiguousarray(angles, dtype=float)

    @property
    def size(self) -> int:
        return self.q_index.size

    def error_and_jacobian(self, model, data, q):
        return self.joint_weights * (self.target - q[self.q_index]), self._weighted_J

    def write_rows(self, model, data, q, A, b):
        # The Jacobian is constant: scaled by the weight once, not on every tick.
        if self._scaled is None or self._scaled[0] != self.weight:
            self._scaled = (self.weight, self._weighted_J if self.weight == 1.0 else self.weight * self._weighted_J)
        A[:] = self._scaled[1]
        posture_rhs(q, self.q_index, self.target, self.joint_weights, self.gain, self.weight, b)


@kernel((VECTOR, INDICES, VECTOR, VECTOR, FLOAT, FLOAT, VECTOR))
def posture_rhs(q, q_index, target, joint_weights, gain, weight, b):
    """``b = weight gain w_j (q*_j − q_j)``, the rows' right-hand side. Compiled, as the frame tasks' rows."""
    for j in range(q_index.size):
        b[j] = weight * (gain * (joint_weights[j] * (target[j] - q[q_index[j]])))
