"""Task: the common shape of every IK task.

A task asks for ``J v = gain * e + v_ff``: ``e`` its error (desired minus current), ``J`` the
Jacobian of the task quantity w.r.t. the Pinocchio velocity ``v`` (nv), ``v_ff`` a feedforward
task velocity. Tasks read kinematics from a ``pinocchio.Data`` on which the solver has already
run ``computeJointJacobians`` for the current configuration (joint placements and Jacobians); a
frame task updates its own frame's placement.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
import pinocchio as pin


class Task(ABC):
    def __init__(self, name: str, gain: float = 50.0, weight: float = 1.0):
        if not gain > 0 or not weight > 0:
            raise ValueError(f"task {name!r}: gain [1/s] and weight must be > 0 (got {gain}, {weight})")
        self.name = name
        self.gain = gain
        self.weight = weight
        self.active = True

    @abstractmethod
    def error_and_jacobian(self, model: pin.Model, data: pin.Data, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(e, J)``: error (m,) and Jacobian (m, nv)."""

    def feedforward(self) -> np.ndarray | None:
        """The feedforward task velocity ``v_ff`` (m,); None: none."""
        return None

    def error(self, model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
        """The error alone, at the configuration of the last :meth:`rows` (a task whose Jacobian
        does not depend on its target may skip recomputing it)."""
        return self.error_and_jacobian(model, data, q)[0]

    @property
    @abstractmethod
    def size(self) -> int:
        """The number of rows m, fixed when the task is built (the solver lays out its rows by it)."""

    def rows(self, model: pin.Model, data: pin.Data, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted least-squares rows ``(A, b)`` with ``A v ≈ b``."""
        A, b = np.empty((self.size, model.nv)), np.empty(self.size)
        self.write_rows(model, data, q, A, b)
        return A, b

    def write_rows(self, model: pin.Model, data: pin.Data, q: np.ndarray, A: np.ndarray, b: np.ndarray) -> None:
        """:meth:`rows` written into ``A`` (m, nv) and ``b`` (m,), the solver's stack of all rows."""
        e, J = self.error_and_jacobian(model, data, q)
        A[:] = J if self.weight == 1.0 else self.weight * J
        b[:] = self._weighted_rhs(e)

    def rhs(self, model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
        """``b`` of :meth:`rows` for the current target, at the configuration of the last ``rows``."""
        return self._weighted_rhs(self.error(model, data, q))

    def _weighted_rhs(self, e: np.ndarray) -> np.ndarray:
        feedforward = self.feedforward()
        b = self.gain * e if feedforward is None else self.gain * e + feedforward
        return b if self.weight == 1.0 else self.weight * b
