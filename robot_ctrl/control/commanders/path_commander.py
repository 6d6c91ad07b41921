"""PathCommander: steers a walking controller along a :class:`WalkGoal`'s path.

At every pattern-generator sample it hands the controller the :class:`PathFollower`'s velocity for
the planned base pose (the plan's CoM carried back by the CoM's offset from the base at the start),
and, once the follower is done, the final footsteps: the start stance carried to the goal pose.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from robot_ctrl.control.commanders.path_follower import PathFollower, WalkGoal
from robot_ctrl.control.controllers.walking_controller import PlanSample, WalkingController
from robot_ctrl.geometry import rotation
from robot_ctrl.wpg.footstep import stance_at


class PathCommander:
    """Steers a walking controller along a :class:`WalkGoal`'s path from ``start`` (world x [m],
    y [m], yaw [rad]), through its ``set_velocity`` and ``stop_at`` at every pattern-generator
    sample. ``PathCommander(controller, WalkGoal(distance=3.0), start)``, then run the loop."""

    def __init__(self, controller: WalkingController, goal: WalkGoal, start: np.ndarray,
                 log: Callable[[str], None] = print):
        """``start``: world (x, y, yaw) of the base at the start: the path's origin."""
        self.controller, self.goal, self.log = controller, goal, log
        to_base = rotation(start[2]).T
        self.com_offset = to_base @ (controller.plan_sample().com_xy - start[:2])  # base frame
        self.feet_offset = {s: to_base @ (f.xy - start[:2]) for s, f in controller.footsteps().items()}
        self.follower = PathFollower(goal, start, tolerance=(0.03, 0.03))
        self.goal_base = self.follower.world_pose(goal.pose_at(goal.length))
        controller.on_sample(self._steer)

    @property
    def done(self) -> bool:
        return self.follower.done

    @property
    def duration(self) -> float:
        """How long walking the path takes [s]: the follower's progress profile, or for side-steps the
        gait's own lateral limit if it is slower (one reach_y of sideways progress per gait cycle)."""
        if not self.goal.lateral:
            return self.follower.end_time
        p = self.controller.params
        return max(self.follower.end_time, abs(self.goal.lateral) / (p.reach_y[1] / (2 * p.step_period)))

    @property
    def time_limit(self) -> float:
        """When a walk of this path has clearly failed to end [s]: the path's duration, the
        follower's settling time and 10 s to stop and stand."""
        return self.duration + self.follower.settle_time + 10.0

    def _steer(self, sample: PlanSample) -> None:
        planned_base = np.array([*(sample.com_xy - rotation(sample.heading) @ self.com_offset), sample.heading])
        was_done = self.follower.done
        velocity = self.follower.velocity(sample.t, planned_base)
        if self.follower.done and not was_done:
            goal = self.goal_base
            self.controller.stop_at(*stance_at(goal, self.feet_offset))
            self.log(f"t = {sample.t:6.2f} s  path done, stopping at the goal")
        elif not self.follower.done:
            self.controller.set_velocity(*velocity)
