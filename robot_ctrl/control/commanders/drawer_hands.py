"""DrawerHands: the hands of the walk-and-reach task, on the IK's hand tasks.

The synthesized upper body drives the arms through the posture task; the final approach of each
hand is corrected by its hand task (thesis 3.8: the hand reaches its target):

- over the last short cycle the left hand blends from its synthesized path to the handle, the
  gripper opens; with the config's ``grasp.hand_rpy`` the hand turns to it on the way, to a point
  behind the handle against its fingers, and goes straight in from there (the fingers slide round
  the bar instead of sweeping across it). Once the hand is measured near the handle the gripper
  closes (with ``grasp.hook`` it stays open: the fingers hook the bar), and once the gripper is
  measured to have stopped the hand holds the handle;
- holding, it pulls the drawer to the task's opening with the synthesized pull's timing, moving
  along the drawer's slide and keeping, across it and in its orientation, what it had when it took
  hold (the bar stays between the fingers); the drawer's opening is the hand's measured travel since;
- standing, the right hand keeps where it is while the drawer opens toward it (its synthesized reach
  would meet the drawer's front panel on its way out), then, once the drawer is pulled, rises to the
  object's height and reaches over the front panel to the object.

A free hand's target is corrected by the low-passed error of the measured hand against the IK's
reference hand (servo sag under the arm's weight, the base's lean), at most ``MAX_HAND_BIAS``. The
error is taken for such a slow offset only while the reference hand moves slower than
``BIAS_SPEED``: in a reach the arm lags its reference (servo lag, command latency), and a bias that
learned the lag would push the target ahead of the hand, the reference further from the arm, and
the lag up, until the servos saturate.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import pinocchio as pin

from robot_ctrl.control.commanders.drawer_targets import DrawerTargets
from robot_ctrl.control.commanders.synthesized_body import SynthesizedBody
from robot_ctrl.geometry import SIDES, Side, minimum_jerk

REACH = (0.35, 0.95)  # share of the short cycle over which the left hand blends to the handle
REACH_PHASE_TIME = 1.0  # [s] the right hand's rise to the object's height, and its way across to it
RISEN_WITHIN = 0.03  # [m] of the object's height, the measured right hand has risen
DRAWER_CLEARANCE = 0.1  # [m] the waiting right hand keeps this far back from the open drawer's front
CLOSE_DISTANCE = 0.03  # [m] the measured hand this near the handle: close the gripper
PRE_GRASP_DEPTH = 0.10  # [m] behind the handle, a turned hand's fingertips are clear of the bar
PRE_GRASP_SHARE = 0.7  # of the blend to the handle, spent reaching that point (and turning the hand)
GRIPPER_OPENING = 0.35  # share of the short cycle the gripper takes to open (a slow servo)
GRIPPER_CLOSE_TIME = 0.6  # [s] to command the gripper from open to closed
GRIPPER_STOPPED = 0.05  # [rad/s] a closing gripper measured slower than this (low-passed) has stopped
GRIPPER_SPEED_TIME = 0.1  # [s] time constant of that low-pass
MAX_PULL_SPEED = 0.2  # [m/s]
MIN_SYNTHESIZED_PULL = 0.02  # [m] of the synthesized pull left when the hand takes hold, for its timing to lead
HAND_BIAS_TIME = 0.5  # [s] time constant of the measured hand error fed back into a hand's target
MAX_HAND_BIAS = 0.06  # [m] a slow kinematic offset, not the arm's lag in a fast motion
BIAS_SPEED = 0.05  # [m/s] of the reference hand, below which its measured error is taken for an offset


class DrawerHands:
    def __init__(self, controller, targets: DrawerTargets, body: SynthesizedBody):
        """``controller``: the :class:`~robot_ctrl.control.controllers.walking_controller.WalkingController`."""
        self.controller, self.targets, self.body = controller, targets, body
        robot = controller.robot
        self._gripper = robot.config.joint_index("grippers", "left")  # the left hand pulls
        # Closed: the gripper's closing end, within the IK's soft limit; open: ``opening`` back from it.
        self._closing = robot.config.grippers.closing_sign("left")
        end = robot.upper if self._closing > 0 else robot.lower
        self._closed = float(end[self._gripper]) - self._closing * robot.config.position_margin
        self._open = self._closed - self._closing * robot.config.grippers.opening
        self._hand_rpy = robot.config.grippers.hand_rpy
        self._hook = robot.config.grippers.hook
        self._rotation_from: dict[str, np.ndarray] = {}  # each hand's IK orientation where its turn began
        self._bias = {s: np.zeros(3) for s in SIDES}
        self._last: dict[str, np.ndarray] = {}  # each hand's last target, or the IK's hand while free
        self._reference: dict[str, np.ndarray] = {}  # each hand of the IK's reference at the last tick
        self._path_offset: dict[str, np.ndarray] = {}
        self._closing_since: float | None = None
        self._gripper_q: float | None = None  # the measured gripper angle, low-passed [rad]
        self._gripper_speed = 0.0  # its speed, low-passed [rad/s]
        self.holding = False  # the gripper is measured closed at the handle
        self.grasp_hand: np.ndarray | None = None  # measured left hand when it took hold [m]
        self._grasp_relative = np.zeros(3)
        self._grasp_rotation: np.ndarray | None = None  # the IK's left hand orientation when it took hold
        self._pull_total = 0.0
        self.pull_command = 0.0  # [m] the opening the left hand is pulling to
        self._right_hold: np.ndarray | None = None  # where the right hand waits while the drawer opens
        self._pulled_at: float | None = None
        self._across_from: float | None = None  # when the right hand set off across the drawer's front
        self.reached = False  # the right hand's reach to the object is over

    @property
    def opening(self) -> float:
        """The drawer's opening as the robot knows it: the left hand's measured travel since it took hold [m]."""
        est = self.controller.estimate
        if self.grasp_hand is None or est is None:
            return 0.0
        return float(max(0.0, (self.grasp_hand - est.hands["left"]) @ self.targets.forward))

    @property
    def pulled(self) -> bool:
        return self.holding and self.pull_command >= self.targets.opening - 1e-9

    def reach(self, t: float, share: float, upper_q: np.ndarray, posture: np.ndarray,
              final_upper: Callable[[], np.ndarray]) -> None:
        """The last short cycle at ``share`` of it (and, at share 1, standing until the hand holds)."""
        self._left(t, share, upper_q, posture, final_upper)

    def stand(self, t: float, share: float, upper_q: np.ndarray, posture: np.ndarray,
              final_upper: Callable[[], np.ndarray]) -> None:
        """The standing action at ``share`` of it (1 once the sequence has ended)."""
        self._left(t, 1.0, upper_q, posture, final_upper)
        if self._right_hold is None:  # where it is, but out of the opening drawer's way
            targets, hand = self.targets, self.controller.reference_hand("right")
            beyond = targets.advance(hand) - (targets.distance(t) - targets.opening - DRAWER_CLEARANCE)
            self._right_hold = hand - targets.forward * max(0.0, beyond)
        if not self.pulled:
            self._free("right", self._right_hold)
            return
        self._pulled_at = t if self._pulled_at is None else self._pulled_at
        target, start = self.targets.object(t, self.opening), self._right_hold
        # Up to the object's height first, then, once the hand is measured there, across over the
        # drawer's front (the forearm follows the hand: crossing lower, it meets the front).
        rise = minimum_jerk(t - self._pulled_at, REACH_PHASE_TIME)[0]
        risen = self.controller.estimate.hands["right"][2] >= target[2] - RISEN_WITHIN
        if self._across_from is None and rise >= 1.0 and (risen or t - self._pulled_at >= 3 * REACH_PHASE_TIME):
            self._across_from = t
        across = 0.0 if self._across_from is None else minimum_jerk(t - self._across_from, REACH_PHASE_TIME)[0]
        self.reached = self._across_from is not None and t - self._across_from >= REACH_PHASE_TIME
        self._free("right", np.array([*(start[:2] + across * (target[:2] - start[:2])),
                                      start[2] + rise * (target[2] - start[2])]))

    def _left(self, t: float, reach: float, upper_q: np.ndarray, posture: np.ndarray,
              final_upper: Callable[[], np.ndarray]) -> None:
        c, targets = self.controller, self.targets
        handle = targets.handle(t)
        near = float(np.linalg.norm(c.estimate.hands["left"] - handle))
        if self._closing_since is None and near <= CLOSE_DISTANCE:
            self._closing_since = t
        opened = minimum_jerk(reach, GRIPPER_OPENING)[0]
        posture[self._gripper] += (self._open - posture[self._gripper]) * opened
        if self._closing_since is not None and not self._hook:
            posture[self._gripper] += (self._closed - self._open) * minimum_jerk(t - self._closing_since,
                                                                                 GRIPPER_CLOSE_TIME)[0]
        relative = self.body.hands_from_pelvis(upper_q, c.reference_configuration(), targets.start[2])["left"]
        if not self.holding:
            # Its speed from the low-passed angle (an encoder's noise, differenced, would never look still).
            gripper = float(c.estimate.configuration[c.robot.q_index[self._gripper]])
            smooth = min(1.0, c.dt / GRIPPER_SPEED_TIME)
            if self._gripper_q is not None:
                filtered = self._gripper_q + (gripper - self._gripper_q) * smooth
                speed = abs(filtered - self._gripper_q) / c.dt
                self._gripper_speed += (speed - self._gripper_speed) * smooth
                gripper = filtered
            self._gripper_q = gripper
            stopped = (self._closing_since is not None and t - self._closing_since >= GRIPPER_CLOSE_TIME
                       and self._gripper_speed < GRIPPER_STOPPED)
            if not stopped:
                s, _ = minimum_jerk(reach - REACH[0], REACH[1] - REACH[0])
                if self._hand_rpy is None:
                    self._free("left", self._blend("left", s, upper_q, handle))
                    return
                # Turned to the handle behind it first, then straight in: the fingers slide round the
                # bar instead of sweeping across it.
                turn, advance = min(1.0, s / PRE_GRASP_SHARE), max(0.0, (s - PRE_GRASP_SHARE) / (1 - PRE_GRASP_SHARE))
                rotation = self._turn("left", turn)
                back = (self._turn("left", 1.0) @ [0.0, 0.0, 1.0]) * PRE_GRASP_DEPTH  # against the fingers
                target = self._blend("left", turn, upper_q, handle + back)
                self._free("left", None if target is None else target - back * advance, rotation)
                return
            self.holding = True
            self.grasp_hand = c.estimate.hands["left"].copy()
            self._grasp_rotation = self._turn("left", 1.0)
            if self._grasp_rotation is None:
                self._grasp_rotation = c.reference_hand_rotation("left")
            self._grasp_relative = relative
            end = self.body.hands_from_pelvis(final_upper(), c.reference_configuration(), targets.start[2])["left"]
            self._pull_total = float(targets.forward @ (relative - end))
        # The synthesized pull's timing (relative to the pelvis: the base's own sway must not pull
        # the drawer), to the task's opening.
        pulled = targets.forward @ (self._grasp_relative - relative)
        share = float(np.clip(pulled / self._pull_total, 0.0, 1.0)) if self._pull_total > MIN_SYNTHESIZED_PULL else 1.0
        # Never back: the synthesized arm may sway back at the end of its pull; the drawer stays open.
        step = min(targets.opening * share, self.pull_command + MAX_PULL_SPEED * c.dt)
        self.pull_command = max(self.pull_command, step)
        # Along the slide, the hand goes where the pull wants it; across it, and in its orientation, it
        # stays as it took hold, so that the bar stays between the fingers (it could leave the closed
        # hand sideways).
        missing = self.pull_command - self.opening
        along = c.estimate.hands["left"] - targets.forward * missing
        across = self.grasp_hand - targets.forward * (targets.forward @ self.grasp_hand)
        self._command("left", across + targets.forward * (targets.forward @ along) - self._bias["left"],
                      self._grasp_rotation)

    def _turn(self, side: Side, s: float) -> np.ndarray | None:
        """A hand's orientation target as it turns to the config's ``grasp.hand_rpy`` (in the task's
        frame; world): from the IK's orientation where the turn began, by ``s`` along the geodesic;
        None without one (or before the turn)."""
        if self._hand_rpy is None or s <= 0:
            self._rotation_from.pop(side, None)
            return None
        target = pin.utils.rpyToMatrix(0.0, 0.0, float(self.targets.start[2])) @ pin.utils.rpyToMatrix(*self._hand_rpy)
        start = self._rotation_from.setdefault(side, self.controller.reference_hand_rotation(side))
        return start @ pin.exp3(s * pin.log3(start.T @ target))

    def _blend(self, side: Side, s: float, upper_q: np.ndarray, target: np.ndarray) -> np.ndarray | None:
        """From the hand's synthesized path toward ``target`` by ``s``, the target itself at s = 1.
        The path is taken through where the IK had the hand when the task switched on (the posture
        task tracks the synthesized angles only loosely), so that the task starts without a jump."""
        if s <= 0:
            self._path_offset.pop(side, None)
            return None
        c = self.controller
        synthesized = self.body.hands(upper_q, c.reference_configuration())[side]
        if side not in self._path_offset:
            self._path_offset[side] = c.reference_hand(side) - synthesized
        return (1 - s) * (synthesized + self._path_offset[side]) + s * target

    def _free(self, side: Side, target: np.ndarray | None, rotation: np.ndarray | None = None) -> None:
        """Command ``target`` for a free hand, less the bias of the measured hand."""
        c = self.controller
        if target is None or c.estimate is None:
            self._bias[side][:] = 0.0
            self._command(side, None)
            return
        reference = c.reference_hand(side)
        before = self._reference.get(side, reference)
        self._reference[side] = reference
        if np.linalg.norm(reference - before) <= BIAS_SPEED * c.dt:
            error = c.estimate.hands[side] - reference
            bias = self._bias[side] + (error - self._bias[side]) * min(1.0, c.dt / HAND_BIAS_TIME)
            self._bias[side] = bias * min(1.0, MAX_HAND_BIAS / max(float(np.linalg.norm(bias)), 1e-9))
        self._command(side, target - self._bias[side], rotation)

    def _command(self, side: Side, target: np.ndarray | None, rotation: np.ndarray | None = None) -> None:
        """Hand ``target`` (None: free) with its velocity by finite difference; a task that switches on
        takes over the velocity the IK's hand had, so the IK's solution does not jump (a jump in the
        commanded joint velocity is a torque spike through the servos' damping)."""
        c = self.controller
        last = self._last.get(side)
        if target is None:
            self._last[side] = c.reference_hand(side)
            c.set_hand_target(side, None)
            return
        velocity = np.zeros(3) if last is None else (target - last) / c.dt
        self._last[side] = target
        c.set_hand_target(side, target, velocity, rotation)
