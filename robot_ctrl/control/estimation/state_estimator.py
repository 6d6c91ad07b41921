"""StateEstimator: CoM, DCM, ZMP and support polygon of the robot from one JointState.

Uses the measured base pose and velocity (IMU/base estimate of the backend) and the joint
encoders with Pinocchio, and the feet's force/torque readings. All outputs in the world frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robot_ctrl.geometry import GRAVITY, SIDES, Side, base_pose_xy_yaw
from robot_ctrl.geometry.support_polygon import SupportPolygon
from robot_ctrl.hw.types import JointState
from robot_ctrl.kernels import MATRIX, STACK, VECTOR, kernel
from robot_ctrl.robot.model import RobotModel, measured_configuration
from robot_ctrl.wpg.lipm import dcm


@dataclass(frozen=True)
class Estimate:
    com: np.ndarray  # (3,) [m]
    com_velocity: np.ndarray  # (3,) [m/s]
    soles: dict[str, pin.SE3]  # measured sole poses
    in_contact: dict[Side, bool]  # normal force above the contact threshold
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
        self._sole_offset = np.asarray(robot.config.foot.center_offset, dtype=float)

    def estimate(self, state: JointState) -> Estimate:
        r = self.robot
        q, v = measured_configuration(r, state.base_pos, state.base_quat_xyzw, state.base_linvel, state.base_angvel,
                                      state.q, state.dq)
        pin.forwardKinematics(r.pin, self.data, q, v)
        com = pin.centerOfMass(r.pin, self.data, pin.KinematicLevel.VELOCITY, False)  # reuses the kinematics above
        com_velocity = self.data.vcom[0].copy()
        # updateFramePlacement: the four frames read, not all of the model's, each returned.
        soles = {s: pin.updateFramePlacement(r.pin, self.data, self._sole_frames[s]).copy() for s in SIDES}
        wrench = state.foot_wrench or {}
        down = [s for s in SIDES if s in wrench and wrench[s][2] > self.threshold]
        zmp = support = None
        if down:
            placements = np.array([soles[s].homogeneous for s in down])
            zmp = measured_zmp(placements, np.array([wrench[s] for s in down]))
            foot = r.config.foot
            support = SupportPolygon.of_soles(sole_centres(placements, self._sole_offset), foot.length, foot.width)
        hands = {s: pin.updateFramePlacement(r.pin, self.data, f).translation.copy()
                 for s, f in self._hand_frames.items()}
        return Estimate(com.copy(), com_velocity, soles, {s: s in down for s in SIDES}, zmp, support, hands,
                        base_pose_xy_yaw(state.base_pos, state.base_quat_xyzw), q)


# Compiled: both run on every tick, on the serial path between the read and the command.
@kernel((STACK, VECTOR))
def sole_centres(placements: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Floor position (x, y) of each sole rectangle's centre (``offset`` (2,) in the sole frame) and
    the sole's heading [rad], (k, 3), from the soles' world placements (k, 4, 4)."""
    out = np.empty((placements.shape[0], 3))
    for i in range(placements.shape[0]):
        T = placements[i]
        out[i, 0] = T[0, 3] + T[0, 0] * offset[0] + T[0, 1] * offset[1]
        out[i, 1] = T[1, 3] + T[1, 0] * offset[0] + T[1, 1] * offset[1]
        out[i, 2] = math.atan2(T[1, 0], T[0, 0])
    return out


@kernel((STACK, MATRIX))
def measured_zmp(placements: np.ndarray, wrenches: np.ndarray) -> np.ndarray | None:
    """ZMP on the floor plane z = 0 from sole-frame contact wrenches ``[f, m]`` (k, 6) at the soles'
    world placements (k, 4, 4).

    Each wrench (sole frame, about the sole origin p) is moved to the world origin, ``F = R f``,
    ``M = R m + p × F``; with their sums, the ZMP on z = 0 is ``(−M_y / F_z, M_x / F_z)``; None when
    ``F_z`` ≤ 1e-6 N.
    """
    fz = mx = my = 0.0
    for i in range(placements.shape[0]):
        T, w = placements[i], wrenches[i]
        Fx = T[0, 0] * w[0] + T[0, 1] * w[1] + T[0, 2] * w[2]
        Fy = T[1, 0] * w[0] + T[1, 1] * w[1] + T[1, 2] * w[2]
        Fz = T[2, 0] * w[0] + T[2, 1] * w[1] + T[2, 2] * w[2]
        fz += Fz
        mx += T[0, 0] * w[3] + T[0, 1] * w[4] + T[0, 2] * w[5] + T[1, 3] * Fz - T[2, 3] * Fy
        my += T[1, 0] * w[3] + T[1, 1] * w[4] + T[1, 2] * w[5] + T[2, 3] * Fx - T[0, 3] * Fz
    if fz <= 1e-6:
        return None
    return np.array([-my / fz, mx / fz])
