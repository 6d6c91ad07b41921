"""ComTask: drive the centre of mass to a target position in the world frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robot_ctrl.sot.task import Task


class ComTask(Task):
    """Error ``c* - c`` [m] (world frame), Jacobian ``∂c/∂v`` from Pinocchio. ``axes`` ⊂ {0, 1, 2};
    ``locked_dofs``: velocity indices the task may not use (their Jacobian columns are zeroed)."""

    def __init__(self, name: str = "com", axes=(0, 1, 2), locked_dofs=(), **kw):
        super().__init__(name, **kw)
        self.axes = slice(None) if tuple(axes) == (0, 1, 2) else np.asarray(axes)  # all: a view, not a copy
        self.locked_dofs = np.asarray(locked_dofs, dtype=int)
        self._free: np.ndarray | None = None  # 1 on the dofs the task may use, 0 on the locked ones (by nv)
        self.target = np.zeros(3)
        self.target_velocity = np.zeros(3)

    def set_target(self, position: np.ndarray, velocity: np.ndarray | None = None) -> None:
        self.target = np.asarray(position, dtype=float)
        self.target_velocity = np.zeros(3) if velocity is None else np.asarray(velocity, dtype=float)

    def error_and_jacobian(self, model, data, q):
        # From the joint Jacobians the solver computed for q; also updates data.com[0].
        J = pin.jacobianCenterOfMass(model, data, False)
        if self.locked_dofs.size:
            if self._free is None or self._free.size != model.nv:
                self._free = np.ones(model.nv)
                self._free[self.locked_dofs] = 0.0
            J *= self._free  # a product rather than an indexed assignment: this runs every tick
        return (self.target - data.com[0])[self.axes], J[self.axes]

    def error(self, model, data, q):
        # The CoM that error_and_jacobian left in data.com[0]: it does not depend on the target.
        return (self.target - data.com[0])[self.axes]

    def feedforward(self):
        return self.target_velocity[self.axes]
