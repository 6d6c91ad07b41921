"""Drawer scenario (the headline task, thesis 3.8, Fig. 3.40): walk to a chest of drawers, pull the
drawer open with the left hand and reach the object with the right, the whole pipeline at 200 Hz:
synthesis → WPG → dynamic filter → stack-of-tasks IK → hardware, in MuJoCo with a real drawer.

Poses in the report are in the start frame (the base's pose at the start, on the floor).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from robot_ctrl.control.drawer_targets import DrawerTargets
from robot_ctrl.control.loop import ControlLoop
from robot_ctrl.control.pacer import Pacer
from robot_ctrl.control.walk_reach_commander import WalkReachCommander
from robot_ctrl.control.walking_controller import WalkingController
from robot_ctrl.eval import FallCriterion, RunMetrics
from robot_ctrl.eval.drawer_recorder import DrawerRecorder
from robot_ctrl.eval.push_capture import PushCapture
from robot_ctrl.eval.recorders import Fell, HeldFor, MetricsRecorder, ProgressBar, TimeLimit
from robot_ctrl.eval.report_file import write_report
from robot_ctrl.eval.walk_log import WalkLog
from robot_ctrl.eval.walk_recorder import WalkRecorder
from robot_ctrl.geometry import GRAVITY, base_pose_xy_yaw
from robot_ctrl.geometry.drawer import SLOTS, DrawerGeometry
from robot_ctrl.hw.disturbances import Disturbances
from robot_ctrl.hw.safety import SafetyLayer
from robot_ctrl.modes import BaseState, FilterMode
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.scenarios.run_start import start_run
from robot_ctrl.sot.whole_body_ik import TRUNK_POSTURE_FACTOR
from robot_ctrl.synthesis.primitives import WalkReachPrimitives
from robot_ctrl.synthesis.synthesizer import GoalJump

STAND_AFTER = 1.0  # [s] standing after the sequence ended
MAX_DISTANCE = 6.0  # [m] farthest cabinet: a room's length
WALK_IN = 0.30  # [m] most the pelvis advances before the synthesis starts (the WPG's start and two steps: 0.26-0.28 m measured)


@dataclass(frozen=True)
class DrawerTask:
    distance: float  # [m] closed front panel from the start pelvis, along the start heading
    slot: str = "front_left"
    jumps: tuple[GoalJump, ...] = ()
    dynfilter: FilterMode = FilterMode.FULL
    control_dt: float = 0.005  # [s]
    base_state: BaseState = BaseState.SIMULATED  # where the controller's base pose and velocity come from

    def check(self, comfort: float, shortest: float) -> None:
        """Raise ValueError naming the setting and its allowed range."""
        nearest = round(comfort + shortest + WALK_IN, 2)
        if self.slot not in SLOTS:
            raise ValueError(f"slot = {self.slot!r} is not one of {', '.join(SLOTS)}")
        for name, d in [("distance", self.distance)] + [("goal jump distance", j.distance) for j in self.jumps]:
            if not nearest <= d <= MAX_DISTANCE:
                raise ValueError(f"{name} = {d} m is outside the allowed range [{nearest}, {MAX_DISTANCE}] m")
        before = self.distance
        for j in sorted(self.jumps, key=lambda j: j.time):
            if not 0 < j.time <= 30:
                raise ValueError(f"goal jump time = {j.time} s is outside the allowed range (0, 30] s")
            if not j.distance > before:
                raise ValueError(f"goal jump distance = {j.distance} m must be farther than the {before} m before it "
                                 "(the cabinet moves away, thesis Fig. 3.39; nearer would put it into the robot)")
            before = j.distance


def run_drawer(robot: RobotModel, hw: SafetyLayer, primitives: WalkReachPrimitives, task: DrawerTask,
               out_dir: Path | None = None, log: Callable[[str], None] = print, progress: bool = False,
               disturbances: Disturbances = Disturbances(), recorders: Sequence = (),
               geometry: DrawerGeometry = DrawerGeometry(), pacer: Pacer | None = None) -> dict:
    """Run ``task`` on ``hw`` (from ``open_hardware(..., drawer=...)``, which placed the cabinet);
    ``recorders`` (a tick log) see every tick; ``pacer`` keeps a real robot's ticks on time (the
    cabinet then stands where the task says, and its drawer is not measured)."""
    dt = task.control_dt
    controller, view, state = start_run(robot, hw, task.base_state, lambda seen: WalkingController(
        robot, seen, None, dt, dynfilter=task.dynfilter, dynfilter_worker=True, trunk_weight=TRUNK_POSTURE_FACTOR,
        balance_with_arms=False), pacer, recorders, log)
    start = base_pose_xy_yaw(state.base_pos, state.base_quat_xyzw)
    targets = DrawerTargets(start, float(state.base_pos[2]), task.distance, task.slot, task.jumps, geometry)
    commander = WalkReachCommander(controller, primitives, targets, log)
    metrics = RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(state.base_pos[2])))
    foot = robot.config.foot
    walk = WalkRecorder(controller, WalkLog(robot.mass * GRAVITY, start, (foot.length, foot.width)), start,
                        lambda line: None)
    drawer = DrawerRecorder(commander, robot)
    capture = PushCapture(controller, disturbances.pushes, float(start[2]))
    done = HeldFor(lambda: commander.finished and controller.standing,
                   STAND_AFTER, "the task ended")
    limit = 8.0 * max([task.distance] + [j.distance for j in task.jumps]) + 15.0
    bar = ProgressBar(limit / 2, progress)
    loop = ControlLoop([view.hardware(hw)], [view.stepped], dt, commanders=[commander],
                       recorders=[MetricsRecorder([metrics]), walk, drawer, capture, bar, *view.recorders, *recorders],
                       stops=[Fell([metrics]), done, TimeLimit(limit, "the task did not end")], pacer=pacer)
    try:
        result = loop.run([state])
    finally:
        bar.close()
    log(result.stop_reason)
    walk_figures = walk.log.metrics()
    report = metrics.report() | {"robot": robot.name, "distance_m": task.distance, "slot": task.slot,
                                 "goal_jumps": [{"time_s": j.time, "distance_m": j.distance} for j in task.jumps],
                                 "dynfilter": task.dynfilter.value} | drawer.report(
        metrics.fell, geometry, task.slot, primitives.comfort_distance) | dict(
        zmp_in_support_ratio=walk.zmp_in_support_ratio, footsteps=walk.footsteps, **walk_figures,
        dynfilter_fallbacks=controller.filter_fallbacks, **view.report(), safety=hw.report(), disturbances=disturbances.to_dict(),
        push_capture=capture.report(), rtf=round(result.rtf, 3), control_rate_hz=round(1.0 / dt, 3))
    report["success"] = report["success"] and done.held(result.states[0].t) >= STAND_AFTER
    if pacer is not None:
        report["timing"] = pacer.report()
    log(f"success: {str(report['success']).lower()}  fell: {str(report['fell']).lower()}  steps "
        f"{report['planned_step_lengths_m']} planned, {report['realized_step_lengths_m']} realized [m]  pelvis to "
        f"drawer {report['final_pelvis_to_drawer_m']} m (comfort {report['comfort_distance_m']})  drawer open "
        f"{report['drawer_opening_m']} m (needs {report['drawer_opening_required_m']})  right hand to object "
        f"{report['hand_to_object_m']} m  rtf {report['rtf']}")
    write_report(report, out_dir, log)
    if out_dir is not None:
        walk.log.save(out_dir)
        log(f"wrote {drawer.save(out_dir)}")
    return report
