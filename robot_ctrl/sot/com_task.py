"""ComTask: drive the centre of mass to a target position in the world frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robot_ctrl.kernels import FLOAT, INDICES, MATRIX, VECTOR, kernel
from robot_ctrl.sot.task import Task

_NO_FEEDFORWARD = np.zeros(3)


class ComTask(Task):
    """Error ``c* - c`` [m] (world frame), Jacobian ``∂c/∂v`` from Pinocchio. ``axes`` ⊂ {0, 1, 2};
    ``locked_dofs``: velocity indices the task may not use (their Jacobian columns are zeroed)."""

    def __init__(self, name: str = "com", axes=(0, 1, 2), locked_dofs=(), **kw):
        super().__init__(name, **kw)
        self._axes = np.asarray(axes, dtype=np.int64)
        self.locked_dofs = np.asarray(locked_dofs, dtype=np.int64)
        self.target = np.zeros(3)
        self.target_velocity = np.zeros(3)

    def set_target(self, position: np.ndarray, velocity: np.ndarray | None = None) -> None:
        self.target = np.ascontiguousarray(position, dtype=float)
        self.target_velocity = np.zeros(3) if velocity is None else np.ascontiguousarray(velocity, dtype=float)

    @property
    def axes(self) -> np.ndarray:
        """The task's CoM axes (read-only: they fix its number of rows)."""
        return self._axes

    @property
    def size(self) -> int:
        return self._axes.size

    def error_and_jacobian(self, model, data, q):
        J, e = np.empty((self.size, model.nv)), np.empty(self.size)
        self._weighted_rows(model, data, 1.0, 1.0, _NO_FEEDFORWARD, J, e)
        return e, J

    def write_rows(self, model, data, q, A, b):
        self._weighted_rows(model, data, self.gain, self.weight, self.target_velocity, A, b)

    def rhs(self, model, data, q):
        # Task.rhs compiled: the walking controller moves this target between prepare and finish.
        b = np.empty(self._axes.size)
        com_rhs(data.com[0], self.target, np.asarray(self.target_velocity, dtype=float), self.gain, self.weight,
                self._axes, b)
        return b

    def error(self, model, data, q):
        # The CoM that the last rows left in data.com[0]: it does not depend on the target.
        return (self.target - data.com[0])[self.axes]

    def feedforward(self):
        return self.target_velocity[self.axes]

    def _weighted_rows(self, model, data, gain: float, weight: float, feedforward: np.ndarray, A, b) -> None:
        # From the joint Jacobians the solver computed for q; also updates data.com[0].
        J = pin.jacobianCenterOfMass(model, data, False)
        com_rows(J, self.locked_dofs, data.com[0], self.target, np.asarray(feedforward, dtype=float),
                 gain, weight, self.axes, A, b)


@kernel((MATRIX, INDICES, VECTOR, VECTOR, VECTOR, FLOAT, FLOAT, INDICES, MATRIX, VECTOR))
def com_rows(J, locked, com, target, feedforward, gain, weight, axes, A, b):
    """The task's rows ``A = weight J[axes]``, ``b = weight (gain (c* − c)[axes] + v_ff[axes])``
    with the ``locked`` columns of the CoM Jacobian ``J`` zeroed. Compiled, as the frame tasks' rows."""
    nv = J.shape[1]
    for k in range(axes.size):
        i = axes[k]
        for c in range(nv):
            A[k, c] = weight * J[i, c]
        for c in locked:
            A[k, c] = 0.0
    com_rhs(com, target, feedforward, gain, weight, axes, b)


@kernel((VECTOR, VECTOR, VECTOR, FLOAT, FLOAT, INDICES, VECTOR))
def com_rhs(com, target, feedforward, gain, weight, axes, b):
    """``b = weight (gain (c* − c)[axes] + v_ff[axes])``, the rows' right-hand side."""
    for k in range(axes.size):
        b[k] = weight * (gain * (target[axes[k]] - com[axes[k]]) + feedforward[axes[k]])
