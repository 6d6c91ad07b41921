"""StateEstimator: CoM, its velocity, ZMP, contacts and support from one JointState, checked against
Pinocchio computed here and against wrenches whose ZMP is known by construction."""

import numpy as np
import pinocchio as pin

from robot_ctrl.control.estimation.state_estimator import StateEstimator
from robot_ctrl.geometry import GRAVITY
from robot_ctrl.hw.types import JointState


def yaw_quat_xyzw(yaw):
    return np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])


def sole_wrench(pose: pin.SE3, point_world: np.ndarray, force: float) -> np.ndarray:
    """Sole-frame wrench [f, m] about the sole origin of a vertical force ``force`` [N] applied at
    ``point_world`` on the floor."""
    f_world = np.array([0.0, 0.0, force])
    m_world = np.cross(point_world - pose.translation, f_world)
    return np.concatenate([pose.rotation.T @ f_world, pose.rotation.T @ m_world])


def test_com_velocity_zmp_and_support_of_a_turned_moving_robot(talos):
    rng = np.random.default_rng(0)
    yaw, base = 0.7, np.array([1.0, -2.0, 1.02])
    q_joints = np.array(talos.config.half_sitting) + rng.normal(0.0, 0.05, talos.nj)
    q_joints = np.clip(q_joints, talos.lower, talos.upper)
    velocity_world = np.array([0.3, -0.1, 0.0])
    q = talos.q_half_sitting.copy()
    q[:3], q[3:7] = base, yaw_quat_xyzw(yaw)
    q[talos.q_index] = q_joints
    data = talos.pin.createData()
    pin.framesForwardKinematics(talos.pin, data, q)
    soles = {s: data.oMf[talos.frame_ids[f"{s}_foot"]].copy() for s in ("left", "right")}
    expected_com = pin.centerOfMass(talos.pin, data, q)
    # Weight split 70 / 30 over a point on each sole: the ZMP is their weighted mean.
    weight = talos.mass * GRAVITY
    points = {s: soles[s].translation + soles[s].rotation @ [0.03, -0.01, 0.0] for s in soles}
    points = {s: np.array([p[0], p[1], 0.0]) for s, p in points.items()}
    wrench = {"left": sole_wrench(soles["left"], points["left"], 0.7 * weight),
              "right": sole_wrench(soles["right"], points["right"], 0.3 * weight)}
    state = JointState(t=0.0, q=q_joints, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj), base_pos=base,
                       base_quat_xyzw=yaw_quat_xyzw(yaw), base_linvel=velocity_world, base_angvel=np.zeros(3),
                       foot_wrench=wrench)
    est = StateEstimator(talos).estimate(state)
    np.testing.assert_allclose(est.com, expected_com, atol=1e-9)
    np.testing.assert_allclose(est.com_velocity, velocity_world, atol=1e-9)  # a translating rigid posture
    np.testing.assert_allclose(est.base_xy_yaw, [1.0, -2.0, 0.7], atol=1e-9)
    expected_zmp = 0.7 * points["left"][:2] + 0.3 * points["right"][:2]
    np.testing.assert_allclose(est.zmp, expected_zmp, atol=1e-3)  # the soles are a few mm above the floor
    assert est.in_contact == {"left": True, "right": True}
    assert est.support.contains(expected_zmp) and not est.support.contains(expected_com[:2] + [0.0, 0.3])
    omega = np.sqrt(GRAVITY / 0.88)
    np.testing.assert_allclose(est.dcm(omega), expected_com[:2] + velocity_world[:2] / omega)


def test_a_light_foot_is_not_in_contact_and_spinning_moves_the_com(talos):
    q_joints = np.array(talos.config.half_sitting)
    q = talos.q_half_sitting.copy()
    data = talos.pin.createData()
    pin.framesForwardKinematics(talos.pin, data, q)
    left = data.oMf[talos.frame_ids["left_foot"]]
    right = data.oMf[talos.frame_ids["right_foot"]]
    weight = talos.mass * GRAVITY
    point = np.array([*left.translation[:2], 0.0])
    wrench = {"left": sole_wrench(left, point, 0.97 * weight), "right": sole_wrench(right, right.translation, 0.03 * weight)}
    spin = np.array([0.0, 0.0, 1.0])  # rad/s about the base's z axis, joints still
    state = JointState(t=0.0, q=q_joints, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj), base_pos=q[:3],
                       base_quat_xyzw=q[3:7], base_linvel=np.zeros(3), base_angvel=spin, foot_wrench=wrench)
    est = StateEstimator(talos).estimate(state)
    assert est.in_contact == {"left": True, "right": False}  # 3 % of the weight is below the 5 % threshold
    np.testing.assert_allclose(est.zmp, point[:2], atol=1e-3)
    lever = est.com - q[:3]
    np.testing.assert_allclose(est.com_velocity, np.cross(spin, lever), atol=1e-9)
