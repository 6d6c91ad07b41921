"""NaiveCommander: the naive baseline of thesis 3.8.4 on the drawer task.

Primitives learned from the feasible demonstrations' **whole body** (every joint angle and the
base's height, roll and pitch, with the pelvis twist: ``load_primitives(..., whole_body=True)``)
are synthesized for the new goal by the same planner, blending and speed classes as our method, and
their joint angles are played on the servos (:class:`~robot_ctrl.control.controllers.joint_playback.JointPlayback`):
no WPG, no dynamic filter, no stabilizer, no IK, no grasp logic (the gripper closes when the learned
gripper angle closes it; the simulated cabinet holds a hand that is closed at its handle).

The walk from standing into steady gait is the walking controller's, as for our method (the
walk-in at the first action's mean speed, ``WALK_IN_STEPS`` touch-downs), so both methods start
the learned sequence in the same state; the angles blend from the walking controller's last
command into the synthesized ones over ``HANDOVER_BLEND``. The learned base channels are not
commanded (a base cannot be), and the pelvis twist only times the synthesis as it does for ours.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from robot_ctrl.control.commanders.drawer_targets import DrawerTargets
from robot_ctrl.control.commanders.synthesized_body import SynthesizedBody
from robot_ctrl.control.commanders.walk_reach_commander import WALK_IN_STEPS, gait_time_scale, step_synthesis
from robot_ctrl.control.controllers.joint_playback import JointPlayback
from robot_ctrl.control.controllers.walking_controller import PlanSample
from robot_ctrl.geometry import minimum_jerk
from robot_ctrl.robot.model import configuration
from robot_ctrl.synthesis.demonstrations import PELVIS_CHANNELS, upper_body_joints
from robot_ctrl.synthesis.primitives import WalkReachPrimitives
from robot_ctrl.synthesis.step_planning import Action
from robot_ctrl.synthesis.synthesizer import Synthesizer, WalkReachGoal

HANDOVER_BLEND = 0.1  # [s] from the walking controller's last command into the played angles


class NaiveCommander:
    approach = None  # it walks straight in: a cabinet in a room is refused (DrawerTask.check)

    def __init__(self, playback: JointPlayback, primitives: WalkReachPrimitives, targets: DrawerTargets,
                 log: Callable[[str], None] = print, *, speed: float = 1.0):
        controller = playback.walking
        robot = controller.robot
        self.playback, self.controller, self.primitives, self.targets, self.log = playback, controller, primitives, targets, log
        self.speed = speed
        names = list(primitives.channels[len(PELVIS_CHANNELS):])
        self._joints = np.array([names.index(n) for n in robot.joint_names])  # synthesized channels → joint order
        self._upper = np.array([names.index(n) for n in upper_body_joints(robot)])
        self.body = SynthesizedBody(robot)
        self.synth: Synthesizer | None = None
        self.output = None
        self.synth_start_advance = 0.0
        self.boundaries: list[tuple[float, Action]] = []
        self.opening = 0.0  # the naive method does not track the drawer: its object target is the closed drawer's
        self.t = 0.0
        self._handover: tuple[float, np.ndarray] | None = None  # (time [s], the walking controller's last angles)
        first = Synthesizer(primitives, self._goal(0.0)).plan[0]
        controller.set_time_scale(gait_time_scale(controller, first.duration, speed))
        controller.set_velocity(speed * first.length / first.duration, 0.0, 0.0)
        controller.on_sample(self._on_sample)

    def _goal(self, t: float) -> WalkReachGoal:
        return WalkReachGoal(self.targets.distance(t) - self.synth_start_advance, self.targets.slot)

    @property
    def finished(self) -> bool:
        return self.synth is not None and self.synth.finished

    @property
    def done(self) -> bool:
        """The learned sequence has been played to its end."""
        return self.finished

    def synthesized_pose_at_measured(self) -> tuple[np.ndarray, np.ndarray]:
        """The played arm angles and the measured configuration (base pose and legs), for
        ``body.hands``."""
        s = self.playback.last_state
        return self.output.upper_body_q[self._upper], configuration(self.controller.robot, s.base_pos,
                                                                     s.base_quat_xyzw, s.q)

    def begin_tick(self, t: float) -> None:
        self.t = t
        if self.synth is None or self.synth.finished:
            return
        output = step_synthesis(self.synth, self.controller.dt * self.speed, self._goal(t), t, self.boundaries)
        if output is not None:
            self.output = output
        q = self.output.upper_body_q[self._joints]
        start, walked = self._handover
        s, _ = minimum_jerk(t - start, HANDOVER_BLEND)
        self.playback.play(walked + s * (q - walked))

    def _on_sample(self, sample: PlanSample) -> None:
        if self.synth is not None or len(self.controller.touchdowns) < WALK_IN_STEPS:
            return
        est = self.controller.estimate
        self.synth_start_advance = self.targets.advance(est.base_xy_yaw)
        self.synth = Synthesizer(self.primitives, self._goal(sample.t), self.controller.dt * self.speed)
        self.boundaries.append((sample.t, self.synth.plan[0].action))
        self._handover = (sample.t, self.playback.last_command.q.copy())
        self.log(f"t = {sample.t:6.2f} s  naive playback starts {self.synth_start_advance:.3f} m from the start: actions "
                 f"{[p.action for p in self.synth.plan]}, lengths {[round(p.length, 3) for p in self.synth.plan]} m")
