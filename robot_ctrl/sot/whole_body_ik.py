"""WholeBodyIK: the humanoid stack of tasks used by every controller.

Levels (strict priority, docs/ik.md)::

    1. feet        left and right sole poses (6D each)
    2. balance     centre of mass (3D) and waist orientation
    3. upper body  hand positions (when active) and a joint posture over all joints (low weight)

Joint limits bound every level. The IK integrates its own reference configuration ``q``
(Pinocchio convention, base in the world frame): a position-controlled robot is commanded the
joint part of that reference, the way HRP-2 and Talos are driven.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robot_ctrl.geometry import SIDES
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.sot.com_task import ComTask
from robot_ctrl.sot.frame_task import FrameTask, support_columns
from robot_ctrl.sot.joint_limits import JointLimits
from robot_ctrl.sot.posture_task import PostureTask
from robot_ctrl.sot.solver import HierarchicalQP


def hand_tool_dofs(robot: RobotModel) -> np.ndarray:
    """Velocity indices of the joints beyond the hand frames (grippers). They carry too little mass
    to serve balance, and a gripper rests on its joint limit: a balance task that used it would
    push it into the bound on every tick. The posture task alone moves them."""
    model = robot.pin
    hands = {model.frames[robot.frame_ids[f"{s}_hand"]].parentJoint for s in SIDES}
    return np.array([model.joints[j].idx_v for j in range(1, model.njoints)
                     if any(h in model.supports[j] and h != j for h in hands)], dtype=int)


def chain_dofs(robot: RobotModel, role: str) -> np.ndarray:
    """Velocity indices of the joints from the floating base out to an operational frame's parent
    joint (a leg for ``left_foot``, the torso joints for ``torso``), found in the kinematic tree:
    no joint names, so that any robot's config serves."""
    model = robot.pin
    columns = support_columns(model, model.frames[robot.frame_ids[role]].parentJoint)
    return columns[columns >= 6]  # not the floating base's


def upper_body_dofs(robot: RobotModel) -> np.ndarray:
    """Velocity indices of every joint but the legs' (torso, arms, grippers, head), in joint order."""
    legs = np.concatenate([chain_dofs(robot, f"{s}_foot") for s in SIDES])
    return np.array([v for v in robot.v_index if v not in legs], dtype=int)


#: A torso posture weight over the other joints' (``trunk_weight``) for tasks where the hands reach
#: with the arms and the trunk keeps still, as a person's does: the reaches of the walk-and-reach
#: task (Talos's torso servos cannot swing the whole upper body about quickly).
TRUNK_POSTURE_FACTOR = 10.0

#: A measured start configuration this close outside the URDF limits (encoder quantization,
#: calibration) is clamped into them; farther out, the IK refuses it (``LimitViolation``).
START_TOLERANCE = 0.01  # [rad]
HAND_ORIENTATION_WEIGHT = 0.2  # [m/rad] of a hand's orientation rows against its position rows


class WholeBodyIK:
    """The walking and balance controllers' stack of tasks on one robot: feet, then CoM and
    trunk, then hands and posture, in strict priority with joint limits at every level. Targets are
    set on its tasks (world frame, SI units); ``prepare`` then ``finish`` integrate one tick
    (docs/ik.md). ``WholeBodyIK(robot, q0)``."""

    def __init__(self, robot: RobotModel, q0: np.ndarray, gain: float = 40.0, posture_weight: float = 0.03,
                 trunk_weight: float = 1.0, balance_with_arms: bool = True, acceleration_limits: bool = True):
        """``trunk_weight``: the torso joints' posture weight relative to the other joints'.
        ``balance_with_arms``: the CoM task may move the torso, arms and head; without it, only the
        legs (the pelvis) carry the CoM, and the upper body is left to its posture and hands.
        ``acceleration_limits``: each upper-body joint's velocity changes by at most ``a_max dt`` per
        step (:class:`JointLimits`), so that its servo can follow it; off for a kinematic planner.
        The legs are left without: the feet must hold exactly, and a leg joint stopped at its
        position limit must be answered by the other leg joints at once (acceleration bounds on
        every joint of a closed chain cannot all be kept). Their motion comes from the walking
        pattern's smooth CoM and swing-foot paths, well inside their servos' accelerations."""
        self.robot = robot
        self.data = robot.pin.createData()
        self.q = np.array(q0, dtype=float)
        joints = self.q[robot.q_index]
        near = (joints > robot.lower - START_TOLERANCE) & (joints < robot.upper + START_TOLERANCE)
        self.q[robot.q_index] = np.where(near, np.clip(joints, robot.lower, robot.upper), joints)
        self._stale = True
        self._prepared: tuple | None = None  # (q it was prepared at, dt, retargetable tasks)
        # The last step's velocity (the start at rest): the acceleration limits' reference.
        self.v = np.zeros(robot.pin.nv)
        ids = robot.frame_ids
        self.feet = {s: FrameTask(f"{s}_foot", ids[f"{s}_foot"], gain=gain) for s in SIDES}
        locked = hand_tool_dofs(robot) if balance_with_arms else upper_body_dofs(robot)
        self.com = ComTask(gain=gain, locked_dofs=locked)
        self.waist = FrameTask("waist", ids["waist"], axes=("rx", "ry", "rz"), gain=gain)
        self.hands = {s: FrameTask(f"{s}_hand", ids[f"{s}_hand"], axes=("x", "y", "z"), gain=gain) for s in SIDES}
        # A hand's orientation, held only where a task asks for it (a hand holding a handle), and more
        # loosely than its position: where the arm cannot keep both, the hand turns.
        self.hand_orientations = {s: FrameTask(f"{s}_hand_orientation", ids[f"{s}_hand"], axes=("rx", "ry", "rz"),
                                               gain=gain, weight=HAND_ORIENTATION_WEIGHT) for s in SIDES}
        self.posture = PostureTask("posture", robot.q_index, robot.v_index, robot.pin.nv, gain=gain,
                                   weight=posture_weight)
        self.posture.set_joint_weights(np.where(np.isin(robot.v_index, chain_dofs(robot, "torso")), trunk_weight, 1.0))
        self.solver = HierarchicalQP(
            [[self.feet["left"], self.feet["right"]], [self.com, self.waist],
             [self.hands["left"], self.hands["right"], self.hand_orientations["left"],
              self.hand_orientations["right"], self.posture]],
            JointLimits.from_robot(robot, upper_body_dofs(robot) if acceleration_limits else None))
        self.hold_current()

    def hold_current(self) -> None:
        """Targets = the current configuration's values; hands inactive; posture = half-sitting
        (within the soft joint limits)."""
        for s in SIDES:
            self.feet[s].set_target(self.pose(f"{s}_foot"))
            self.hands[s].set_target(self.pose(f"{s}_hand"))
            self.hand_orientations[s].set_target(self.pose(f"{s}_hand"))
            self.hands[s].active = self.hand_orientations[s].active = False
        self.com.set_target(pin.centerOfMass(self.robot.pin, self.data, self.q))
        self.waist.set_target(self.pose("waist"))
        # Half-sitting puts the grippers on their URDF limit: aim inside the IK's soft limits instead,
        # or the posture task would push them against a bound on every tick.
        limits = self.solver.limits
        self.posture.set_target(np.clip(self.robot.config.half_sitting, limits.q_min, limits.q_max))

    def pose(self, role: str) -> pin.SE3:
        """World-frame pose of an operational frame at the IK's current configuration."""
        if self._stale:
            pin.framesForwardKinematics(self.robot.pin, self.data, self.q)
            self._stale = False
        return self.data.oMf[self.robot.frame_ids[role]].copy()

    def set_configuration(self, q: np.ndarray) -> None:
        """Restart the integration from ``q`` (Pinocchio configuration, base in the world frame)."""
        self.q = np.array(q, dtype=float)
        self._stale = True

    def com_position(self) -> np.ndarray:
        return pin.centerOfMass(self.robot.pin, self.data, self.q)

    def step(self, dt: float) -> np.ndarray:
        """Solve the stack, integrate ``q`` over ``dt`` and return the velocity ``v`` (nv)."""
        self.prepare(dt)
        return self.finish()

    def prepare(self, dt: float, retargetable: tuple = ()) -> None:
        """First half of :meth:`step` (``HierarchicalQP.prepare``): all the solve needs from ``q``
        and the targets set so far; ``retargetable`` tasks may get new targets before
        :meth:`finish` at little cost."""
        self.solver.prepare(self.robot.pin, self.data, self.q, dt, retargetable, self.v)
        self._prepared = (self.q, dt, retargetable)

    def finish(self, retargeted: tuple = (), tighter: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Second half of :meth:`step`, after the ``retargeted`` tasks got new targets. Prepares
        again first if ``q`` was set since :meth:`prepare`. ``tighter``: per-joint velocity bounds
        from the measured state (:func:`~robot_ctrl.sot.servo_bounds.servo_velocity_bounds`), in
        the robot's joint order, inside the joint limits'."""
        if self._prepared is None:
            raise RuntimeError("WholeBodyIK.finish without prepare")
        q, dt, retargetable = self._prepared
        if q is not self.q:
            self.prepare(dt, retargetable)
        self._prepared = None
        v = self.v = self.solver.finish(retargeted, tighter)
        self.q = pin.integrate(self.robot.pin, self.q, v * dt)
        self._stale = True  # frame placements are recomputed only when a pose is asked for
        return v
