"""StateEstimator: CoM, DCM, ZMP and support polygon of the robot from one JointState.

Uses the measured base pose and velocity (IMU/base estimate of the backend) and the joint
encoders with Pinocchio, and the feet's force/torque readings. All outputs in the world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robot_ctrl.hw.types import JointState
from robot_ctrl.robot.model import RobotModel, configuration
from robot_ctrl.wpg.footstep import yaw_of
from robot_ctrl.wpg.support_polygon import SupportPolygon

SIDES = ("left", "right")


@dataclass(frozen=True)
class Estimate:
    com: np.ndarray  # (3,) [m]
    com_velocity: np.ndarray  # (3,) [m/s]
    soles: dict[str, pin.SE3]  # measured sole poses
    in_contact: dict[str, bool]  # normal force above the contact threshold
    zmp: np.ndarray | None  # (2,) on the floor, None without contact [m]
    support: SupportPolygon | None  # hull of the soles in contact

    def dcm(self, omega: float) -> np.ndarray:
        """Divergent component of motion ξ = c + ċ/ω (horizontal) [m]."""
        return self.com[:2] + self.com_velocity[:2] / omega


class StateEstimator:
    def __init__(self, robot: RobotModel, contact_threshold: float = 0.05):
        """``contact_threshold``: share of the robot's weight on a foot that counts as contact."""
        self.robot = robot
        self.data = robot.pin.createData()
        self.threshold = contact_threshold * robot.mass * 9.81

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
        soles = {s: self.data.oMf[r.frame_ids[f"{s}_foot"]].copy() for s in SIDES}
        wrench = state.foot_wrench or {}
        contact = {s: s in wrench and wrench[s][2] > self.threshold for s in SIDES}
        zmp = measured_zmp({s: (soles[s], wrench[s]) for s in SIDES if contact[s]})
        down = [s for s in SIDES if contact[s]]
        support = None
        if down:
            foot = r.config.foot
            support = SupportPolygon.of_soles(
                [(soles[s].act(np.array([*foot.center_offset, 0.0]))[:2], yaw_of(soles[s].rotation)) for s in down],
                foot.length, foot.width)
        return Estimate(com.copy(), com_velocity, soles, contact, zmp, support)


def measured_zmp(contacts: dict[str, tuple[pin.SE3, np.ndarray]]) -> np.ndarray | None:
    """ZMP on the floor plane z = 0 from sole-frame contact wrenches.

    Each wrench ``[f, m]`` (sole frame, about the sole origin) is moved to the world origin; with
    total force F and moment M there, the ZMP on z = 0 is ``(−M_y / F_z, M_x / F_z)``.
    """
    if not contacts:
        return None
    world = sum((pose.act(pin.Force(w)) for pose, w in contacts.values()), pin.Force.Zero())  # about the origin
    force, moment = world.linear, world.angular
    if force[2] <= 1e-6:
        return None
    return np.array([-moment[1] / force[2], moment[0] / force[2]])
