"""StateEstimator: CoM, DCM, ZMP and support polygon of the robot from one JointState.

Uses the measured base pose and velocity (IMU/base estimate of the backend) and the joint
encoders with Pinocchio, and the feet's force/torque readings. All outputs in the world frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robot_ctrl.geometry import GRAVITY, SIDES, base_pose_xy_yaw
from robot_ctrl.geometry.support_polygon import SupportPolygon
from robot_ctrl.hw.types import JointState
from robot_ctrl.robot.model import RobotModel, configuration
from robot_ctrl.wpg.lipm import dcm


@dataclass(frozen=True)
class Estimate:
    com: np.ndarray  # (3,) [m]
    com_velocity: np.ndarray  # (3,) [m/s]
    soles: dict[str, pin.SE3]  # measured sole poses
    in_contact: dict[str, bool]  # normal force above the contact threshold
    zmp: np.ndarray | None  # (2,) on the floor, None without contact [m]
    support: SupportPolygon | None  # hull of the soles in contact
    hands: dict[str, np.ndarray]  # measured hand frame positions [m]
    base_xy_yaw: np.ndarray  # measured base (pelvis) pose on the floor: x, y [m], yaw [rad]
    configuration: np.ndarray  # the measured Pinocchio configuration (base in the world frame)

    def dcm(self, omega: float) -> np.ndarray:
        """Divergent component of motion ξ = c + ċ/ω (horizontal) [m]."""
        return dcm(self.com[:2], self.com_velocity[:2], omega)


class StateEstimator:
    def __init__(self, robot: RobotModel, contact_threshold: float = 0.05):
        """``contact_threshold``: share of the robot's weight on a foot that counts as contact."""
        self.robot = robot
        self.data = robot.pin.createData()
        self.threshold = contact_threshold * robot.mass * GRAVITY
        self._sole_frames = {s: robot.frame_ids[f"{s}_foot"] for s in SIDES}
        self._hand_frames = {s: robot.frame_ids[f"{s}_hand"] for s in SIDES}

    def estimate(self, state: JointState) -> Estimate:
        r = self.robot
        q = configuration(r, state.base_pos, state.base_quat_xyzw, state.q)
        rot = pin.Quaternion(state.base_quat_xyzw[3], *state.base_quat_xyzw[:3]).matrix()
        v = np.zeros(r.pin.nv)
        v[:3] = rot.T @ state.base_linvel  # Pinocchio's free-flyer velocity is in the base frame
        v[3:6] = state.base_angvel
        v[r.v_index] = state.dq
        pin.forwardKinematics(r.pin, self.data, q, v)
        pin.updateFramePlacements(r.pin, self.data)
        com = pin.centerOfMass(r.pin, self.data, pin.KinematicLevel.VELOCITY, False)  # reuses the kinematics above
        com_velocity = self.data.vcom[0].copy()
        soles = {s: self.data.oMf[self._sole_frames[s]].copy() for s in SIDES}
        wrench = state.foot_wrench or {}
        down = [s for s in SIDES if s in wrench and wrench[s][2] > self.threshold]
        zmp = measured_zmp([(soles[s], wrench[s]) for s in down])
        support = None
        if down:
            foot = r.config.foot
            support = SupportPolygon.of_soles([_sole_centre(soles[s], foot.center_offset) for s in down],
                                              foot.length, foot.width)
        hands = {s: self.data.oMf[f].translation.copy() for s, f in self._hand_frames.items()}
        return Estimate(com.copy(), com_velocity, soles, {s: s in down for s in SIDES}, zmp, support, hands,
                        base_pose_xy_yaw(state.base_pos, state.base_quat_xyzw), q)


def _sole_centre(pose: pin.SE3, offset) -> tuple[tuple[float, float], float]:
    """Floor position of the sole rectangle's centre (``offset`` (2,) in the sole frame) and the
    sole's heading [rad]."""
    (r00, r01, _), (r10, r11, _), _ = pose.rotation.tolist()
    x, y, _ = pose.translation.tolist()
    ox, oy = offset
    return (x + r00 * ox + r01 * oy, y + r10 * ox + r11 * oy), math.atan2(r10, r00)


def measured_zmp(contacts: list[tuple[pin.SE3, np.ndarray]]) -> np.ndarray | None:
    """ZMP on the floor plane z = 0 from sole-frame contact wrenches ``(pose, [f, m])``.

    Each wrench (sole frame, about the sole origin p) is moved to the world origin, ``F = R f``,
    ``M = R m + p × F``; with their sums, the ZMP on z = 0 is ``(−M_y / F_z, M_x / F_z)``.
    Plain floats: numpy and Pinocchio calls cost more than the arithmetic here.
    """
    fz = mx = my = 0.0
    for pose, w in contacts:
        R = pose.rotation.tolist()
        px, py, pz = pose.translation.tolist()
        f0, f1, f2, m0, m1, m2 = w.tolist()
        Fx, Fy, Fz = (row[0] * f0 + row[1] * f1 + row[2] * f2 for row in R)
        fz += Fz
        mx += R[0][0] * m0 + R[0][1] * m1 + R[0][2] * m2 + py * Fz - pz * Fy
        my += R[1][0] * m0 + R[1][1] * m1 + R[1][2] * m2 + pz * Fx - px * Fz
    if fz <= 1e-6:
        return None
    return np.array([-my / fz, mx / fz])
