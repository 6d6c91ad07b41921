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
        rows = np.array([_AXES[a] for a in axes])
        # Only the parts of the error that the axes ask for are computed, and the rows are taken as
        # slices where they can be: this runs for every frame task on every tick.
        self._linear, self._angular = bool((rows < 3).any()), bool((rows >= 3).any())
        self._rows, self._all_rows = _as_slice(rows), rows.tolist() == list(range(6))
        self._error_rows = _as_slice(rows - (0 if self._linear else 3))
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
        J = pin.getFrameJacobian(model, data, self.frame_id, pin.LOCAL_WORLD_ALIGNED)
        if not self._angular:
            e = self._target_translation - current.translation
        elif not self._linear:
            e = pin.log3(self._target_rotation @ current.rotation.T)
        else:
            e = np.concatenate((self._target_translation - current.translation,
                                pin.log3(self._target_rotation @ current.rotation.T)))
        if self._all_rows:
            return e, J
        return e[self._error_rows], J[self._rows]

    def feedforward(self):
        return self.target_velocity if self._all_rows else self.target_velocity[self._rows]


def _as_slice(rows: np.ndarray) -> slice | np.ndarray:
    """``rows`` as a slice when they are consecutive (a view rather than a copy), else as they are."""
    if rows.size and (np.diff(rows) == 1).all():
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return rows
