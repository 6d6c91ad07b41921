"""WalkRecorder: what a walk is judged by, recorded tick by tick from a walking controller.

- the time series of :class:`~robot_ctrl.eval.recording.walk_log.WalkLog` (plan against estimate);
- ``zmp_in_support_ratio``: share of the ticks with foot contact whose ZMP, measured from the
  contact wrenches, lies in the convex hull of the soles in contact (measured by kinematics);
- ``footsteps``: each planned touch-down with the sole pose measured ``SETTLE_AFTER_TOUCHDOWN``
  after it (start frame: x, y, yaw).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from robot_ctrl.eval.recording.walk_log import WalkLog, step_length_errors
from robot_ctrl.geometry import SIDES, base_pose_xy_yaw, relative_pose, wrap_angle, yaw_of
from robot_ctrl.wpg.plan import GaitPhase

SETTLE_AFTER_TOUCHDOWN = 0.1  # [s] when a landed foot's pose is measured


class WalkRecorder:
    def __init__(self, controller, log: WalkLog, start: np.ndarray, announce: Callable[[str], None] = print):
        """``controller``: a :class:`~robot_ctrl.control.controllers.walking_controller.WalkingController`;
        ``start``: world (x, y, yaw) of the start frame."""
        self.controller, self.log, self.start, self.announce = controller, log, start, announce
        self.inside = self.contact_samples = 0
        self.footsteps: list[dict] = []
        self._pending: list[tuple[float, object]] = []

    def on_command(self, tick) -> None:
        c, state = self.controller, tick.states[0]
        ref, est = c.reference, c.estimate
        stance = next(s for s in SIDES if ref.in_contact[s]) if ref.phase is GaitPhase.SINGLE else None
        sole = None
        if stance is not None:
            pose = est.soles[stance]
            sole = (pose.translation[:2], yaw_of(pose.rotation))
        grf = {side: float(w[2]) for side, w in (state.foot_wrench or {}).items()}
        self.log.record(state.t, ref.zmp, est.zmp, ref.com, est.com, c.heading, stance, sole, grf)
        if est.zmp is not None:
            self.contact_samples += 1
            self.inside += est.support.contains(est.zmp)
        touchdowns = c.touchdowns
        while len(self._pending) + len(self.footsteps) < len(touchdowns):
            td = touchdowns[len(self._pending) + len(self.footsteps)]
            self._pending.append((td.t + SETTLE_AFTER_TOUCHDOWN, td))
            self.announce(f"t = {td.t:6.2f} s  {td.planned.side} foot down at ({td.planned.x:.3f}, {td.planned.y:.3f}) m")

    def on_state(self, tick) -> None:
        # The soles as the controller estimated them from the state before this read.
        state, est = tick.states[0], self.controller.estimate
        while self._pending and state.t >= self._pending[0][0] - 1e-9:
            _, td = self._pending.pop(0)
            sole = est.soles[td.planned.side]
            realized = np.array([sole.translation[0], sole.translation[1], yaw_of(sole.rotation)])
            planned = np.array([td.planned.x, td.planned.y, td.planned.yaw])
            self.footsteps.append({"side": td.planned.side, "t": round(td.t, 3),
                                   "planned": relative_pose(planned, self.start).round(4).tolist(),
                                   "realized": relative_pose(realized, self.start).round(4).tolist()})

    @property
    def zmp_in_support_ratio(self) -> float:
        return round(self.inside / max(self.contact_samples, 1), 5)

    def report(self, state, goal) -> dict:
        """The walk's figures once it ended in ``state``: where the base ended against the ``goal``'s
        end pose (start frame), the footsteps, ZMP and CoM tracking, GRF, MPC solve times."""
        final = relative_pose(base_pose_xy_yaw(state.base_pos, state.base_quat_xyzw), self.start)
        target = goal.pose_at(goal.length)
        solve = np.asarray(self.controller.solve_times) * 1e3
        return dict(
            goal={"distance_m": goal.distance, "turn_deg": float(np.degrees(goal.turn)), "lateral_m": goal.lateral,
                  "speed_mps": goal.speed},
            final_base_xy_yaw=[round(float(final[0]), 4), round(float(final[1]), 4), round(float(final[2]), 5)],
            commanded_base_xy_yaw=[round(float(v), 4) for v in target],
            final_position_error_m=round(float(np.linalg.norm(final[:2] - target[:2])), 4),
            final_yaw_error_deg=round(float(np.degrees(abs(wrap_angle(final[2] - target[2])))), 3),
            ended_in_double_support=bool(all(self.controller.estimate.in_contact.values())),
            zmp_in_support_ratio=self.zmp_in_support_ratio,
            footsteps=self.footsteps,
            step_length_error_m=step_length_errors(self.footsteps),
            **self.log.metrics(),
            wpg_solve_ms_median=round(float(np.median(solve)), 4),
            wpg_solve_ms_p99=round(float(np.percentile(solve, 99)), 4),
        )
