"""FrameTask: drive an operational frame (foot, hand, waist) to a target pose in the world frame."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from robot_ctrl.kernels import FLOAT, FORTRAN_MATRIX, INDICES, MATRIX, VECTOR, kernel
from robot_ctrl.sot.task import Task

_AXES = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}
_NO_FEEDFORWARD = np.zeros(6)


class FrameTask(Task):
    """Pose of frame ``frame_id`` in the world frame.

    Error ``e = [p* - p, log3(R* Rᵀ)]`` (world-aligned, linear then angular), Jacobian the
    frame Jacobian in ``LOCAL_WORLD_ALIGNED``. ``axes`` selects rows, e.g. ``("rx", "ry", "rz")``
    for an orientation-only task.
    """

    def __init__(self, name: str, frame_id: int, axes=("x", "y", "z", "rx", "ry", "rz"), **kw):
        super().__init__(name, **kw)
        self.frame_id = frame_id
        self._rows = np.array([_AXES[a] for a in axes], dtype=np.int64)
        # The data last read, its joints' Jacobians (a view that follows computeJointJacobians) and
        # the columns the frame moves with: read once, not on every tick.
        self._data: pin.Data | None = None
        self._jacobians = self._support = None
        self.target = pin.SE3.Identity()
        self.target_velocity = np.zeros(6)  # [linear (m/s), angular (rad/s)] in the world frame

    @property
    def target(self) -> pin.SE3:
        return self._target

    @target.setter
    def target(self, pose: pin.SE3) -> None:
        self._target, self._target_homogeneous = pose, pose.homogeneous  # read once: each read is a copy

    @property
    def target_velocity(self) -> np.ndarray:
        return self._target_velocity

    @target_velocity.setter
    def target_velocity(self, velocity) -> None:
        self._target_velocity = np.ascontiguousarray(velocity, dtype=float)  # as the compiled rows take it

    def set_target(self, pose: pin.SE3, velocity: np.ndarray | None = None) -> None:
        self.target = pose
        self.target_velocity = np.zeros(6) if velocity is None else velocity

    @property
    def size(self) -> int:
        return self._rows.size

    def error_and_jacobian(self, model, data, q):
        J, e = np.empty((self.size, model.nv)), np.empty(self.size)
        self._weighted_rows(model, data, 1.0, 1.0, _NO_FEEDFORWARD, J, e)
        return e, J

    def write_rows(self, model, data, q, A, b):
        self._weighted_rows(model, data, self.gain, self.weight, self._target_velocity, A, b)

    def feedforward(self):
        return self.target_velocity[self._rows]

    def _weighted_rows(self, model, data, gain: float, weight: float, feedforward: np.ndarray, A, b) -> None:
        """``A = weight J``, ``b = weight (gain e + v_ff)`` on the task's axes; ``feedforward``: all six."""
        if data is not self._data:  # a Data belongs to one model
            self._data, self._jacobians = data, data.J
            self._support = support_columns(model, model.frames[self.frame_id].parentJoint)
        # updateFramePlacement: this frame alone, and its pose returned (cheaper than reading data.oMf).
        frame_rows(self._jacobians, self._support, pin.updateFramePlacement(model, data, self.frame_id).homogeneous,
                   self._target_homogeneous, self._rows, feedforward, gain, weight, A, b)


def support_columns(model: pin.Model, joint: int) -> np.ndarray:
    """The velocity indices of the joints from the root to ``joint``: the columns of its frames'
    Jacobians that can be nonzero."""
    joints = [model.joints[j] for j in model.supports[joint] if j > 0]  # not the universe
    return np.array([v for joint in joints for v in range(joint.idx_v, joint.idx_v + joint.nv)], dtype=np.int64)


@kernel((FORTRAN_MATRIX, INDICES, MATRIX, MATRIX, INDICES, VECTOR, FLOAT, FLOAT, MATRIX, VECTOR))
def frame_rows(J, support, current, target, rows, feedforward, gain, weight, A, b):
    """The task's rows ``A = weight Jf[rows]``, ``b = weight (gain e[rows] + v_ff[rows])`` for the frame at
    the homogeneous pose ``current`` and its ``target`` (world frame): ``e = [p* − p, log3(R* Rᵀ)]``
    and ``Jf`` the frame Jacobian in ``LOCAL_WORLD_ALIGNED``, from the joints' world Jacobians
    ``J`` (Pinocchio's ``data.J`` after ``computeJointJacobians``) on the ``support`` columns:
    ``Jf = [J_v − p × J_ω; J_ω]``, as ``getFrameJacobian`` computes it. Compiled: the dozen small
    numpy calls per task and tick cost several times the arithmetic."""
    A[:, :] = 0.0
    error = np.zeros(6)
    linear = angular = False
    for r in rows:
        linear, angular = linear or r < 3, angular or r >= 3
    if linear:
        for i in range(3):
            error[i] = target[i, 3] - current[i, 3]
    if angular:
        R = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                R[i, j] = target[i, 0] * current[j, 0] + target[i, 1] * current[j, 1] + target[i, 2] * current[j, 2]
        log3(R, error[3:])
    px, py, pz = current[0, 3], current[1, 3], current[2, 3]
    column = np.empty(6)
    for c in support:
        wx, wy, wz = J[3, c], J[4, c], J[5, c]
        column[0] = J[0, c] - (py * wz - pz * wy)
        column[1] = J[1, c] - (pz * wx - px * wz)
        column[2] = J[2, c] - (px * wy - py * wx)
        column[3], column[4], column[5] = wx, wy, wz
        for k in range(rows.size):
            A[k, c] = weight * column[rows[k]]
    for k in range(rows.size):
        b[k] = weight * (gain * error[rows[k]] + feedforward[rows[k]])


_EPS = np.finfo(float).eps
_PREC = _EPS ** (1.0 / 3.0)  # Pinocchio's TaylorSeriesExpansion<double>::precision<2>()


@kernel()
def log3(R, out):
    """``out = log3(R)``, the rotation vector of the rotation matrix ``R``: Pinocchio's ``log3``
    (spatial/log.hxx) written out, for the compiled task rows: ``R`` renormalized, ``θ = acos((tr R
    − 1) / 2)``, ``out = θ / (2 sin θ) (R − Rᵀ)^∨``, with its series near 0 and its axis from the
    diagonal near π."""
    c0 = R[:, 0] / math.sqrt(R[0, 0] ** 2 + R[1, 0] ** 2 + R[2, 0] ** 2)
    c1 = R[:, 1] / math.sqrt(R[0, 1] ** 2 + R[1, 1] ** 2 + R[2, 1] ** 2)
    c2 = _cross(c0, c1)
    c0 = _cross(c1, c2)
    Rn = np.empty((3, 3))
    Rn[:, 0], Rn[:, 1], Rn[:, 2] = c0, c1, c2
    tr = Rn[0, 0] + Rn[1, 1] + Rn[2, 2]
    cos_value = (tr - 1.0) / 2.0
    if cos_value >= -1.0 + _PREC:
        acos_expansion = math.sqrt(2.0 * (1.0 - cos_value) + _EPS * _EPS)
        if tr > 3.0 - _PREC:
            theta = acos_expansion
        elif tr >= -1.0 + _PREC:
            theta = math.acos(cos_value)
        else:
            theta = math.pi - acos_expansion
        a0, a1, a2 = 0.5 * (Rn[2, 1] - Rn[1, 2]), 0.5 * (Rn[0, 2] - Rn[2, 0]), 0.5 * (Rn[1, 0] - Rn[0, 1])
        if theta >= _PREC:
            t = theta / math.sin(theta)
        else:
            n2 = a0 * a0 + a1 * a1 + a2 * a2
            t = 1.0 + n2 / 6.0 + n2 * n2 * 3.0 / 40.0
        out[0], out[1], out[2] = t * a0, t * a1, t * a2
        return
    # Near π: the axis from the largest diagonal entry (Pinocchio's compute_theta_axis).
    values = np.array([2.0 * Rn[k, k] - tr + 1.0 for k in range(3)])
    i0 = (0 if values[0] >= values[2] else 2) if values[0] >= values[1] else (1 if values[1] >= values[2] else 2)
    i1, i2 = (i0 + 1) % 3, (i0 + 2) % 3
    s = math.sqrt(values[i0] + _EPS + _EPS * _EPS) * (1.0 if Rn[i2, i1] >= Rn[i1, i2] else -1.0)
    axis = np.empty(3)
    axis[i0] = s / 2.0
    axis[i1] = 1.0 / (2.0 * s) * (Rn[i1, i0] + Rn[i0, i1])
    axis[i2] = 1.0 / (2.0 * s) * (Rn[i2, i0] + Rn[i0, i2])
    w = 1.0 / (2.0 * s) * (Rn[i2, i1] - Rn[i1, i2])
    norm = math.sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2])
    theta = 2.0 * math.atan2(norm, w)
    for k in range(3):
        out[k] = theta * (axis[k] / norm)


@kernel()
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
