"""Quasi-static torque feedforward: gravity compensation with a planned contact-force distribution.

For a configuration ``q`` (Pinocchio, base in the world frame) with feet in contact carrying
shares ``α_i`` (Σ α_i = 1) of the weight, find sole wrenches ``f_i`` (sole frame, about its
origin) that balance gravity on the floating base, closest to the planned split::

    f_ref,i = α_i [0, 0, m g, 0, 0, 0]
    f = f_ref + W Jbᵀ (Jb W Jbᵀ)⁻¹ (g_b − Jb f_ref),   Jb = [J_1,bᵀ … J_k,bᵀ],  W = diag(α_i I₆)

(``J_i`` the LOCAL frame Jacobian of sole i, ``g`` the generalized gravity, subscript b the six
base rows), then the joint torques that hold the posture statically: ``τ = g_j − Σ J_i,jᵀ f_i``.
A position-controlled robot sent ``τ`` as feedforward keeps its servos near zero position error
under load, so its real posture matches the IK reference.

With a CoM acceleration ``c̈`` (walking), the d'Alembert force of the linear inverted pendulum is
added by replacing gravity ``g`` with ``g − c̈`` (every body accelerating with the CoM): the contact
wrenches then carry the inertial load, and their centre of pressure is the cart-table ZMP.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin

from robot_ctrl.geometry import SIDES
from robot_ctrl.kernels import FLOAT, MATRIX, VECTOR, kernel
from robot_ctrl.robot.model import RobotModel, configuration


class ContactSplit(NamedTuple):
    """The soles in contact (Pinocchio frame ids) and the share of the weight each carries."""

    frames: list[int]
    shares: list[float]


class StaticTorques(NamedTuple):
    """Joint torques that hold a posture statically (nv, base rows ≈ 0) [N·m], and the sole-frame
    wrench of each contact (6,) [N, N·m]."""

    torques: np.ndarray
    wrenches: list[np.ndarray]


def static_torques(model: pin.Model, data: pin.Data, q: np.ndarray, sole_frames: list[int], shares: list[float],
                   com_acceleration: np.ndarray | None = None) -> StaticTorques:
    """The torques and contact wrenches that hold ``q`` with the weight split by ``shares``.

    ``shares`` must be positive; they are normalized to sum to one. ``com_acceleration`` (3,) [m/s²],
    world frame, adds the inertial load of the whole body accelerating with the CoM.
    """
    gravity = model.gravity.linear
    effective = gravity if com_acceleration is None else gravity - com_acceleration
    pin.computeJointJacobians(model, data, q)
    J = np.vstack([pin.getFrameJacobian(model, data, f, pin.LOCAL) for f in sole_frames])  # (6k, nv)
    tau, f = _balanced(J, pin.jacobianCenterOfMass(model, data, False), pin.computeTotalMass(model),
                       np.ascontiguousarray(effective, dtype=float), np.asarray(shares, dtype=float))
    return StaticTorques(tau, list(f.reshape(-1, 6)))


@kernel((MATRIX, MATRIX, FLOAT, VECTOR, VECTOR))
def _balanced(J, J_com, mass, gravity, shares):
    """``(τ, f)`` of the module docstring from the soles' stacked LOCAL Jacobians ``J`` (6k, nv), the
    CoM Jacobian ``J_com`` (3, nv), the total mass [kg], the (effective) gravity (3,) [m/s²] and the
    contact shares (k,). The generalized gravity is ``g = −m J_comᵀ g⃗``, the gradient of the
    potential energy (equal to Pinocchio's ``computeGeneralizedGravity`` to rounding, without
    changing the model's gravity for the d'Alembert term). Compiled: the walking controller asks it
    on every tick, a handful of small products."""
    g = -mass * (J_com.T @ gravity)
    weight = mass * np.sqrt(gravity @ gravity)
    alpha = shares / shares.sum()
    rows = J.shape[0]
    f_ref = np.zeros(rows)
    W = np.empty(rows)
    for i in range(alpha.size):
        f_ref[6 * i + 2] = alpha[i] * weight
        W[6 * i:6 * i + 6] = alpha[i]
    Jb = np.ascontiguousarray(J[:, :6].T)  # (6, 6k)
    residual = g[:6] - Jb @ f_ref
    y = np.linalg.solve((Jb * W) @ Jb.T, residual)  # symmetric positive definite (6 × 6)
    f = f_ref + W * (Jb.T @ y)
    return g - J.T @ f, f


def weight_shares(com_xy: np.ndarray, left_xy: np.ndarray, right_xy: np.ndarray,
                  floor: float = 0.02) -> tuple[float, float]:
    """Left/right weight shares from the CoM's position along the segment between the sole centres
    (0 at the right foot, 1 at the left), kept in ``[floor, 1 - floor]`` so both stay positive."""
    axis = left_xy - right_xy
    s = float(np.dot(com_xy - right_xy, axis) / np.dot(axis, axis))
    s = min(max(s, floor), 1.0 - floor)
    return s, 1.0 - s


def upper_body_gravity(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Gravity torques of the joints at the posture ``q`` (joint order, base upright), zero for the
    legs: whether the robot hangs in a gantry or stands changes the legs' load, not the upper body's."""
    model = robot.pin
    tau = pin.computeGeneralizedGravity(model, model.createData(), configuration(
        robot, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), q))[robot.v_index]
    feet = [model.frames[robot.frame_ids[f"{side}_foot"]].parentJoint for side in SIDES]
    legs = [i for i, name in enumerate(robot.joint_names)
            if any(model.getJointId(name) in model.supports[foot] for foot in feet)]
    tau[legs] = 0.0
    return tau
