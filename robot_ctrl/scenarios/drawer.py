"""Drawer scenario (the headline task, thesis 3.8, Fig. 3.40): walk to a chest of drawers, pull the
drawer open with the left hand and reach the object with the right, the whole pipeline at 200 Hz:
synthesis → WPG → dynamic filter → stack-of-tasks IK → hardware, in MuJoCo with a real drawer. With
``DrawerMethod.NAIVE`` the thesis's naive baseline does the task instead: the walking controller
walks in, then learned joint angles are played on the servos (``control/commanders/naive_commander.py``).

Poses in the report are in the start frame (the base's pose at the start, on the floor).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from robot_ctrl.control.commanders.approach_walk import SPEED, TURN_RATE, ApproachWalk
from robot_ctrl.control.commanders.drawer_targets import DrawerTargets
from robot_ctrl.control.commanders.naive_commander import NaiveCommander
from robot_ctrl.control.commanders.walk_reach_commander import WalkReachCommander
from robot_ctrl.control.controllers.joint_playback import JointPlayback
from robot_ctrl.control.controllers.walking_controller import WalkingController, WalkingOptions
from robot_ctrl.control.loop.pacer import Pacer
from robot_ctrl.eval.recording.drawer_recorder import DrawerRecorder, room_layout
from robot_ctrl.eval.recording.push_capture import PushCapture
from robot_ctrl.eval.recording.recorders import HeldFor, ProgressBar, TimeLimit
from robot_ctrl.eval.recording.report_file import write_report
from robot_ctrl.eval.recording.walk_log import WalkLog
from robot_ctrl.eval.recording.walk_recorder import WalkRecorder
from robot_ctrl.geometry import GRAVITY, base_pose_xy_yaw
from robot_ctrl.hw.safety import SafetyLayer
from robot_ctrl.modes import DrawerMethod
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.scenarios.drawer_task import DrawerTask
from robot_ctrl.scenarios.robot_run import start_run
from robot_ctrl.sim.disturbances import Disturbances
from robot_ctrl.sot.whole_body_ik import TRUNK_POSTURE_FACTOR
from robot_ctrl.synthesis.primitives import WalkReachPrimitives

STAND_AFTER = 1.0  # [s] standing after the sequence ended


def run_drawer(robot: RobotModel, hw: SafetyLayer, primitives: WalkReachPrimitives, task: DrawerTask, *,
               out_dir: Path | None = None, log: Callable[[str], None] = print, progress: bool = False,
               disturbances: Disturbances = Disturbances(), recorders: Sequence = (),
               pacer: Pacer | None = None) -> dict:
    """Run ``task`` on ``hw`` (from ``open_hardware(..., prop=DrawerPlacement(...))``, which placed the cabinet);
    ``recorders`` (a tick log) see every tick; ``pacer`` keeps a real robot's ticks on time (the
    cabinet then stands where the task says, and its drawer is not measured)."""
    dt, geometry = task.control_dt, robot.config.drawer
    options = WalkingOptions(control_dt=dt, dynfilter=task.dynfilter, dynfilter_worker=True,
                             trunk_weight=TRUNK_POSTURE_FACTOR, balance_with_arms=False)
    naive = task.method is DrawerMethod.NAIVE

    def build(seen):
        walking = WalkingController(robot, seen, options)
        return JointPlayback(walking) if naive else walking

    stepped, run = start_run(robot, hw, task.base_state, build, pacer, recorders, log)
    controller = stepped.walking if naive else stepped
    start = base_pose_xy_yaw(run.state.base_pos, run.state.base_quat_xyzw)
    plan = task.approach(primitives.comfort_distance, geometry)
    approach = None
    if plan is not None and plan.walks:
        approach = ApproachWalk(controller, plan, lambda: controller.start_pose, log, task.moves,
                                task.replanner(plan, geometry))
    if approach is None:
        frame, distance = (lambda: controller.start_pose), task.distance
    else:  # in a room: the task's frame is the hand-over pose (that of the path now walked), the cabinet ahead of it
        frame, distance = (lambda: approach.handover), plan.handover_distance
    targets = DrawerTargets(frame, float(run.state.base_pos[2]), distance, task.slot, task.jumps, geometry)
    if naive:  # DrawerTask.check: straight ahead
        commander = NaiveCommander(stepped, primitives, targets, log, speed=task.speed.scale)
    else:
        commander = WalkReachCommander(controller, primitives, targets, log, speed=task.speed.scale,
                                       position_feedback=task.position_feedback, approach=approach)
    foot = robot.config.foot
    walk = WalkRecorder(controller, WalkLog(robot.mass * GRAVITY, start, (foot.length, foot.width)), start,
                        lambda line: None)
    drawer = DrawerRecorder(commander, robot)
    capture = PushCapture(controller, disturbances.pushes, float(start[2]))
    done = HeldFor(lambda: commander.done, STAND_AFTER, "the task ended")
    stops = [done]
    limit = 8.0 * max([distance] + [j.distance for j in task.jumps]) + 15.0
    if approach is not None:  # turning on the spot at TURN_RATE and walking at a third of SPEED, at worst
        for path in [plan] + task.move_approaches(primitives.comfort_distance, geometry):
            limit += 3.0 * path.length / SPEED + 2 * np.pi * (len(path.waypoints) - 1) / TURN_RATE
        stops.append(HeldFor(lambda: approach.failed is not None and controller.standing, STAND_AFTER,
                             "the approach found no way to the moved cabinet"))
    bar = ProgressBar(limit / 2, progress)
    result = run.loop(dt, bar, recorders=[walk, drawer, capture], commanders=[commander],
                      stops=stops + [TimeLimit(limit, "the task did not end")])
    log(result.stop_reason)
    report = run.metrics.report() | {"robot": robot.name, "distance_m": task.distance, "slot": task.slot,
                                     "goal_jumps": [{"time_s": j.time, "distance_m": j.distance} for j in task.jumps],
                                     "dynfilter": task.dynfilter.value, "speed": task.speed.value, "method": task.method.value,
                                     "position_feedback": task.position_feedback,
                                     "sources": "{}+{}".format(*primitives.sources)} | drawer.report(
        run.metrics.fell, geometry, task.slot, primitives.comfort_distance, walk.footsteps) | dict(
        zmp_in_support_ratio=walk.zmp_in_support_ratio, footsteps=walk.footsteps, **walk.log.metrics(),
        dynfilter_fallbacks=controller.filter_fallbacks, push_recoveries=controller.push_recoveries,
        push_capture=capture.report()) | run.report(result, disturbances)
    report["success"] = report["success"] and done.held(result.states[0].t) >= STAND_AFTER
    if task.in_room:
        report |= room_layout(task.cabinet, task.room, plan, geometry.footprint(), task.moves)
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

