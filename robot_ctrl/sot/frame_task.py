"""FrameTask: drive an operational frame (foot, hand, waist) to a target pose in the world frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robot_ctrl.sot.task import Task

_AXES = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}


class FrameTask(Task):
    """Pose of frame ``frame_id`` in the world frame.

    Error ``e = [p* - p, log3(R* Rᵀ)]`` (world-aligned, linear then angular), Jacobian the
    frame Jacobian in ``LOCAL_WORLD_ALIGNED``. ``axes`` selects rows, e.g. ``("rx", "ry", "rz")``
    for an orientation-only task.
    """

    def __init__(self, name: str, frame_id: int, axes=("x", "y", "z", "rx", "ry", "rz"), **kw):
        super().__init__(name, **kw)
        self.frame_id = frame_id
        self.rows_idx = np.array([_AXES[a] for a in axes])
        self._all_rows = self.rows_idx.tolist() == list(range(6))
        self.target = pin.SE3.Identity()
        self.target_velocity = np.zeros(6)  # [linear (m/s), angular (rad/s)] in the world frame

    @property
    def target(self) -> pin.SE3:
        return self._target

    @target.setter
    def target(self, pose: pin.SE3) -> None:
        # Its translation and rotation read once: each read of an SE3's member is a copy.
        self._target, self._target_translation, self._target_rotation = pose, pose.translation, pose.rotation

    def set_target(self, pose: pin.SE3, velocity: np.ndarray | None = None) -> None:
        self.target = pose
        self.target_velocity = np.zeros(6) if velocity is None else np.asarray(velocity, dtype=float)

    def error_and_jacobian(self, model, data, q):
        current = data.oMf[self.frame_id]
        e = np.concatenate((self._target_translation - current.translation,
                            pin.log3(self._target_rotation @ current.rotation.T)))
        J = pin.getFrameJacobian(model, data, self.frame_id, pin.LOCAL_WORLD_ALIGNED)
        if self._all_rows:
            return e, J
        return e[self.rows_idx], J[self.rows_idx]

    def feedforward(self):
        return self.target_velocity if self._all_rows else self.target_velocity[self.rows_idx]
