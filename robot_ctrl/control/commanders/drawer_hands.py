"""DrawerHands: the hands of the walk-and-reach task, on the IK's hand tasks.

The synthesized upper body drives the arms through the posture task; the final approach of each
hand is corrected by its hand task (thesis 3.8: the hand reaches its target):

- over the last short cycle the left hand blends from its synthesized path to the handle, the
  gripper opens; once the hand is measured near the handle the gripper closes, and once the gripper
  is measured closed there the hand holds the handle;
- holding, it pulls the drawer to the task's opening with the synthesized pull's timing, moving
  only along the drawer's slide (elsewhere it keeps where it measurably is, so the arm does not fight
  the runners); the drawer's opening is the hand's measured travel since it closed;
- standing, the right hand blends to the object in the open drawer.

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

from robot_ctrl.control.commanders.drawer_targets import DrawerTargets
from robot_ctrl.control.commanders.synthesized_body import SynthesizedBody
from robot_ctrl.geometry import SIDES, Side, minimum_jerk

REACH = (0.35, 0.95)  # share of the short cycle over which the left hand blends to the handle
OBJECT_REACH = (0.25, 0.85)  # share of the standing action over which the right hand blends to the object
CLOSE_DISTANCE = 0.02  # [m] the measured hand this near the handle: close the gripper
GRASP_DISTANCE = 0.01  # [m] and this near, with the gripper closed: it holds the handle
GRIPPER_OPENING = 0.35  # share of the short cycle the gripper takes to open (a slow servo)
GRIPPER_CLOSE_TIME = 0.6  # [s]
GRIPPER_CLOSED = 0.05  # [rad] a measured gripper this near its closed target is closed
MAX_PULL_SPEED = 0.4  # [m/s]
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
        self._opening = robot.config.grippers.opening
        self._bias = {s: np.zeros(3) for s in SIDES}
        self._last: dict[str, np.ndarray] = {}  # each hand's last target, or the IK's hand while free
        self._reference: dict[str, np.ndarray] = {}  # each hand of the IK's reference at the last tick
        self._path_offset: dict[str, np.ndarray] = {}
        self._closing_since: float | None = None
        self.holding = False  # the gripper is measured closed at the handle
        self.grasp_hand: np.ndarray | None = None  # measured left hand when it took hold [m]
        self._grasp_relative = np.zeros(3)
        self._pull_total = 0.0
        self.pull_command = 0.0  # [m] the opening the left hand is pulling to

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
        s, _ = minimum_jerk(share - OBJECT_REACH[0], OBJECT_REACH[1] - OBJECT_REACH[0])
        self._free("right", self._blend("right", s, upper_q, self.targets.object(t, self.opening)))

    def _left(self, t: float, reach: float, upper_q: np.ndarray, posture: np.ndarray,
              final_upper: Callable[[], np.ndarray]) -> None:
        c, targets = self.controller, self.targets
        handle = targets.handle(t)
        near = float(np.linalg.norm(c.estimate.hands["left"] - handle))
        if self._closing_since is None and near <= CLOSE_DISTANCE:
            self._closing_since = t
        opened = minimum_jerk(reach, GRIPPER_OPENING)[0]
        if self._closing_since is not None:
            opened *= 1.0 - minimum_jerk(t - self._closing_since, GRIPPER_CLOSE_TIME)[0]
        posture[self._gripper] = self._closed - self._closing * self._opening * opened
        relative = self.body.hands_from_pelvis(upper_q, c.reference_configuration(), targets.start[2])["left"]
        if not self.holding:
            gripper = c.estimate.configuration[c.robot.q_index[self._gripper]]
            closed = self._closing * (gripper - self._closed) >= -GRIPPER_CLOSED
            if self._closing_since is None or not closed or near > GRASP_DISTANCE:
                s, _ = minimum_jerk(reach - REACH[0], REACH[1] - REACH[0])
                self._free("left", self._blend("left", s, upper_q, handle))
                return
            self.holding = True
            self.grasp_hand = c.estimate.hands["left"].copy()
            self._grasp_relative = relative
            end = self.body.hands_from_pelvis(final_upper(), c.reference_configuration(), targets.start[2])["left"]
            self._pull_total = float(targets.forward @ (relative - end))
        # The synthesized pull's timing (relative to the pelvis: the base's own sway must not pull
        # the drawer), to the task's opening.
        pulled = targets.forward @ (self._grasp_relative - relative)
        share = float(np.clip(pulled / self._pull_total, 0.0, 1.0)) if self._pull_total > 1e-3 else 1.0
        self.pull_command = min(targets.opening * share, self.pull_command + MAX_PULL_SPEED * c.dt)
        missing = self.pull_command - self.opening
        self._command("left", c.estimate.hands["left"] - self._bias["left"] - targets.forward * missing)

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

    def _free(self, side: Side, target: np.ndarray | None) -> None:
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
        self._command(side, target - self._bias[side])

    def _command(self, side: Side, target: np.ndarray | None) -> None:
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
        c.set_hand_target(side, target, velocity)
