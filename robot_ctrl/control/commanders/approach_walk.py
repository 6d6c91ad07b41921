"""ApproachWalk: walks a walking controller along a room's approach path to the hand-over pose.

The path (:func:`~robot_ctrl.geometry.room.plan_approach`) is a polyline whose last stretch comes in
along the cabinet's axis. At every pattern-generator sample the planned base pose (the plan's CoM
carried back by the CoM's offset from the base at the start) is steered to the next corner: turning
on the spot while it faces more than ``TURN_FIRST`` away from it, walking straight (with a heading
correction) once it faces it. Near the hand-over pose the controller is told to stop with the feet at
the start stance carried to that pose; the approach is done once the robot stands there.

When the cabinet moves (a goal jump in a room, known to the robot as its targets are), the path is
planned again from the planned base's position at that sample to the moved cabinet's front, and
walked from its first corner; if there is none, the robot stops where it is and the approach has
``failed``.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from robot_ctrl.control.controllers.walking_controller import PlanSample, WalkingController
from robot_ctrl.geometry import absolute_pose, rotation, wrap_angle
from robot_ctrl.geometry.room import Approach, CabinetMove, CabinetPose
from robot_ctrl.wpg.footstep import stance_at

SPEED = 0.3  # [m/s] walking the straight stretches
TURN_RATE = 0.3  # [rad/s] at most, on the spot or walking
TURN_GAIN = 1.5  # [1/s] heading error to turn rate
SLOW_GAIN = 1.0  # [1/s] distance to the corner to speed: a walk slows into each corner
TURN_FIRST = 0.4  # [rad] facing farther than this from the next corner: turn on the spot first
WALK_WITHIN = 0.12  # [rad] ... until facing it within this
PASSED = 0.12  # [m] a corner this near is passed: on to the next
STOP_DISTANCE = 0.3  # [m] from the hand-over pose: stop there with both feet


def surely_walking_until(approach: Approach) -> float:
    """The latest time [s] (down to 0.1 s) at which a robot that set off from standing at the start
    of ``approach`` (facing the start frame's x) surely still walks it: it cannot have turned to its
    first stretch (beyond ``TURN_FIRST``) at ``TURN_RATE`` and walked to ``STOP_DISTANCE`` before its
    end at ``SPEED`` any sooner."""
    d = approach.waypoints[1] - approach.waypoints[0]
    turn = abs(float(np.arctan2(d[1], d[0])))
    t = max(approach.length - STOP_DISTANCE, 0.0) / SPEED + max(turn - TURN_FIRST, 0.0) / TURN_RATE
    return float(np.floor(t * 10.0 + 1e-9) / 10.0)


class ApproachWalk:
    def __init__(self, controller: WalkingController, approach: Approach, start_pose: Callable[[], np.ndarray],
                 log: Callable[[str], None] = print, moves: tuple[CabinetMove, ...] = (),
                 replan: Callable[[CabinetPose, np.ndarray], Approach] | None = None):
        """``approach``: in the start frame; ``start_pose``: the start frame's world pose (x, y, yaw) as
        the robot knows it; ``moves``: the cabinet's goal jumps, each planned for by ``replan(pose,
        xy)`` (the approach from the start-frame point ``xy``; ValueError: none)."""
        self.controller, self.approach, self.start_pose, self.log = controller, approach, start_pose, log
        self.moves, self.replan = sorted(moves, key=lambda m: m.time), replan
        self.plans: list[tuple[float, Approach]] = [(0.0, approach)]  # (time [s], the path walked from then on)
        self.failed: str | None = None  # why the robot stopped short of the hand-over pose
        start = start_pose()
        to_base = rotation(start[2]).T
        self.com_offset = to_base @ (controller.plan_sample().com_xy - start[:2])  # base frame
        self.feet_offset = {s: to_base @ (f.xy - start[:2]) for s, f in controller.footsteps().items()}
        self.corner = 1  # index of the waypoint walked to
        self.turning = True
        self.stopping = False

    @property
    def done(self) -> bool:
        """Standing at the hand-over pose."""
        return self.stopping and self.failed is None and self.controller.standing

    @property
    def handover(self) -> np.ndarray:
        """The hand-over pose in the world (x, y, yaw)."""
        return absolute_pose(self.approach.handover, self.start_pose())

    def steer(self, sample: PlanSample) -> None:
        if self.stopping:
            return
        c, start = self.controller, self.start_pose()
        base = np.array([*(sample.com_xy - rotation(sample.heading) @ self.com_offset), sample.heading])
        if self.moves and sample.t >= self.moves[0].time - 1e-9:
            self._replan(self.moves.pop(0), sample.t, rotation(start[2]).T @ (base[:2] - start[:2]))
            if self.stopping:
                return
        waypoints = self.approach.waypoints @ rotation(start[2]).T + start[:2]
        last = len(waypoints) - 1
        while self.corner < last and np.linalg.norm(waypoints[self.corner] - base[:2]) < PASSED:
            self.corner += 1
            self.turning = True
        to_corner = waypoints[self.corner] - base[:2]
        distance = float(np.linalg.norm(to_corner))
        if self.corner == last and distance < STOP_DISTANCE:
            goal = self.handover
            c.stop_at(*stance_at(goal, self.feet_offset))
            self.stopping = True
            self.log(f"t = {sample.t:6.2f} s  approach: stopping at the hand-over pose, "
                     f"{self.approach.handover_distance:.2f} m in front of the cabinet")
            return
        error = wrap_angle(float(np.arctan2(to_corner[1], to_corner[0])) - base[2])
        self.turning = abs(error) > (WALK_WITHIN if self.turning else TURN_FIRST)
        turn = float(np.clip(TURN_GAIN * error, -TURN_RATE, TURN_RATE))
        c.set_velocity(0.0 if self.turning else min(SPEED, SLOW_GAIN * distance + 0.05), 0.0, turn)

    def _replan(self, move: CabinetMove, t: float, xy: np.ndarray) -> None:
        """The cabinet moved: the path from ``xy`` (start frame) to its new front, or a stop here."""
        pose = move.pose
        self.log(f"t = {t:6.2f} s  the cabinet moved to ({pose.x:g}, {pose.y:g}) m facing "
                 f"{np.degrees(pose.front_yaw):g} deg: planning the approach again")
        try:
            self.approach = self.replan(pose, xy)
        except ValueError as exc:
            self.failed = f"no way to the moved cabinet: {exc}"
            self.log(f"t = {t:6.2f} s  approach: {self.failed}; stopping here")
            self.controller.set_velocity(0.0, 0.0, 0.0)
            self.stopping = True
            return
        self.plans.append((t, self.approach))
        self.corner, self.turning = 1, True
