"""BalanceController: the balance demo's motion as a controller. Stand, shift the CoM over the left
foot, lift the right foot 5 cm and put it back, shift back, reach the right hand to a point and
return. Quasi-static and open-loop: the stack-of-tasks IK integrates a reference that position
servos track, with a quasi-static torque feedforward (gravity and planned contact forces) so the
servos do not sag under load. There is no balance feedback (the walking controller has the DCM
stabilizer).

All targets are in the *start floor frame*: origin on the floor midway between the two sole
frames at the start, x along the feet's mean heading, z up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from robot_ctrl.control.controllers.static_feedforward import ContactSplit, static_torques, weight_shares
from robot_ctrl.geometry import interpolate
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.robot.model import RobotModel, configuration
from robot_ctrl.sot.whole_body_ik import WholeBodyIK

#: Phases in which the right foot is off the floor (single support on the left foot).
RIGHT_SWING = ("lift_right", "hold_lifted", "lower_right")
#: (name, duration [s]) in order.
PHASES = (
    ("stand", 1.0), ("shift_left", 2.0), ("settle_left", 0.5), ("lift_right", 1.0), ("hold_lifted", 0.5),
    ("lower_right", 1.0), ("settle_down", 0.5), ("shift_back", 2.0), ("reach", 2.5), ("hold_reach", 1.0),
    ("return", 2.5), ("stand_end", 1.0),
)


class PhaseTime(NamedTuple):
    """A phase of the balance motion by name, the time spent in it [s] and its duration [s]."""

    name: str
    elapsed: float
    duration: float


@dataclass(frozen=True)
class BalanceParams:
    """The balance demo's motion: how high the right foot lifts, where the right hand reaches
    (start floor frame: on the floor midway between the soles at the start, x along the feet's
    heading, z up), the control period. ``BalanceController(robot, state, BalanceParams())``."""

    lift_height: float = 0.05  # [m]
    hand_target: tuple[float, float, float] = (0.4, -0.2, 0.8)  # right hand, start floor frame [m]
    control_dt: float = 0.005  # [s] (200 Hz)


def floor_frame(left: pin.SE3, right: pin.SE3) -> pin.SE3:
    """Frame on the floor midway between two sole poses, x along their mean heading."""
    yaw = np.arctan2(*(left.rotation[1::-1, 0] + right.rotation[1::-1, 0]))
    origin = (left.translation + right.translation) / 2
    origin[2] = 0.0
    return pin.SE3(pin.utils.rpyToMatrix(0.0, 0.0, yaw), origin)


class BalanceMotion:
    """Task targets of the balance demo as functions of time, applied to a :class:`WholeBodyIK`."""

    def __init__(self, ik: WholeBodyIK, params: BalanceParams):
        self.ik = ik
        self.params = params
        robot = ik.robot
        self.left0, self.right0 = ik.pose("left_foot"), ik.pose("right_foot")
        self.floor = floor_frame(self.left0, self.right0)
        self.com0 = ik.com_position()
        offset = np.array([*robot.config.foot.center_offset, 0.0])
        over_left = self.left0.act(offset)
        self.com_left = np.array([over_left[0], over_left[1], self.com0[2]])
        self.hand0 = ik.pose("right_hand").translation
        self.hand_target = self.floor.act(np.array(params.hand_target))
        starts = np.cumsum([0.0] + [d for _, d in PHASES])
        self.phases = [(name, s, d) for (name, d), s in zip(PHASES, starts)]
        self.duration = float(starts[-1])

    def phase_at(self, t: float) -> PhaseTime:
        """The phase at ``t`` [s] and how far into it (the last phase's end after the motion)."""
        for name, start, duration in self.phases:
            if t < start + duration:
                return PhaseTime(name, t - start, duration)
        return PhaseTime(self.phases[-1][0], self.phases[-1][2], self.phases[-1][2])

    def apply(self, t: float) -> str:
        """Set the IK targets for time ``t`` [s]; return the phase name."""
        name, tp, dur = self.phase_at(t)
        ik = self.ik
        com, com_v = self.com0, None
        foot_z, foot_vz = 0.0, 0.0
        if name == "shift_left":
            com, com_v = interpolate(self.com0, self.com_left, tp, dur)
        elif name in ("settle_left", "lift_right", "hold_lifted", "lower_right", "settle_down"):
            com = self.com_left
        elif name == "shift_back":
            com, com_v = interpolate(self.com_left, self.com0, tp, dur)
        if name == "lift_right":
            z, vz = interpolate(np.zeros(1), np.array([self.params.lift_height]), tp, dur)
            foot_z, foot_vz = z[0], vz[0]
        elif name == "hold_lifted":
            foot_z = self.params.lift_height
        elif name == "lower_right":
            z, vz = interpolate(np.array([self.params.lift_height]), np.zeros(1), tp, dur)
            foot_z, foot_vz = z[0], vz[0]
        ik.com.set_target(com, com_v)
        foot = self.right0.copy()
        foot.translation = foot.translation + [0.0, 0.0, foot_z]
        ik.feet["right"].set_target(foot, np.array([0.0, 0.0, foot_vz, 0.0, 0.0, 0.0]))

        hand = ik.hands["right"]
        if name in ("reach", "hold_reach", "return"):
            hand.active = True
            if name == "reach":
                p, v = interpolate(self.hand0, self.hand_target, tp, dur)
            elif name == "hold_reach":
                p, v = self.hand_target, np.zeros(3)
            else:
                p, v = interpolate(self.hand_target, self.hand0, tp, dur)
            hand.set_target(pin.SE3(np.eye(3), p), np.concatenate([v, np.zeros(3)]))
        else:
            hand.active = False
        return name

    def contacts(self, name: str) -> ContactSplit:
        """Sole frames in contact and their planned weight shares, from the reference CoM."""
        ids = self.ik.robot.frame_ids
        if name in RIGHT_SWING:
            return ContactSplit([ids["left_foot"]], [1.0])
        left, right = weight_shares(self.ik.com.target[:2], self.left0.translation[:2], self.right0.translation[:2])
        return ContactSplit([ids["left_foot"], ids["right_foot"]], [left, right])


class BalanceController:
    """Runs :class:`BalanceMotion` from the measured start state. The commands do not depend on
    the measured state, so all of a tick is prepared while the robot moves."""

    def __init__(self, robot: RobotModel, state: JointState, params: BalanceParams = BalanceParams()):
        self.robot, self.dt = robot, params.control_dt
        self.ik = WholeBodyIK(robot, configuration(robot, state.base_pos, state.base_quat_xyzw, state.q))
        self.motion = BalanceMotion(self.ik, params)
        self._statics = pin.Data(robot.pin)
        self.k = 0
        self.phase: str | None = None  # the phase of the last command
        self._prepared: tuple[str, JointCommand] | None = None

    @property
    def duration(self) -> float:
        return self.motion.duration

    def prepare(self) -> None:
        robot = self.robot
        name = self.motion.apply(self.k * self.dt)
        v = self.ik.step(self.dt)
        tau, _ = static_torques(robot.pin, self._statics, self.ik.q, *self.motion.contacts(name))
        tau_ff = np.clip(tau[robot.v_index], -robot.effort, robot.effort)  # what the servos can give
        self._prepared = name, JointCommand(q=robot.joints_from_q(self.ik.q), dq=v[robot.v_index], kp=robot.kp,
                                            kd=robot.kd, tau_ff=tau_ff)

    def step(self, state: JointState) -> JointCommand:
        if self._prepared is None:
            self.prepare()
        (self.phase, command), self._prepared = self._prepared, None
        self.k += 1
        return command

    def close(self) -> None:
        pass
