"""JointLimits: position and velocity limits as bounds on the IK velocity, at every level."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.robot.model import RobotModel


class LimitViolation(ValueError):
    """The configuration given to the IK lies outside the hard (URDF) joint limits."""


@dataclass(frozen=True)
class JointLimits:
    """Bounds ``lo ≤ v_j ≤ hi`` for the actuated dofs ``v_index`` over one step ``dt``::

        lo = max(-v_max, min(0, (q_min - q) / dt)),  hi = min(v_max, max(0, (q_max - q) / dt))

    ``[q_min, q_max]`` are the URDF limits shrunk by the config's margin (soft limits): the IK
    never moves a joint into the margin, and a joint already inside it may stay or move out of
    it. ``v_max`` is the URDF velocity limit times the config's fraction. A configuration
    outside the hard URDF limits ``[hard_min, hard_max]`` raises :class:`LimitViolation`.
    """

    q_index: np.ndarray
    v_index: np.ndarray
    names: tuple[str, ...]
    hard_min: np.ndarray
    hard_max: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray

    @classmethod
    def from_robot(cls, robot: RobotModel) -> "JointLimits":
        margin = robot.config.position_margin
        return cls(robot.q_index, robot.v_index, robot.joint_names, robot.lower, robot.upper,
                   robot.lower + margin, robot.upper - margin,
                   robot.velocity_limit * robot.config.velocity_fraction)

    def bounds(self, q: np.ndarray, dt: float, tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
        qj = q[self.q_index]
        outside = np.flatnonzero((qj < self.hard_min - tol) | (qj > self.hard_max + tol))
        if outside.size:
            detail = ", ".join(f"{self.names[i]} = {qj[i]:.4f} not in [{self.hard_min[i]:.4f}, {self.hard_max[i]:.4f}]"
                               for i in outside)
            raise LimitViolation(f"configuration outside the joint limits: {detail}")
        lo = np.maximum(-self.v_max, np.minimum(0.0, (self.q_min - qj) / dt))
        hi = np.minimum(self.v_max, np.maximum(0.0, (self.q_max - qj) / dt))
        return lo, hi
