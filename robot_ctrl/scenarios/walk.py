"""Walk scenario: walk a path (straight, arc or side-step) with the MPC walking controller, stop in
double support, stand 2 s, and report falls, torques, ZMP and footsteps.

Poses in the report are in the *start frame*: the base's pose at the start (x forward, y left,
yaw about z), on the floor.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from robot_ctrl.control.commanders.path_commander import PathCommander
from robot_ctrl.control.commanders.path_follower import WalkGoal
from robot_ctrl.control.controllers.arm_swing import arm_motion
from robot_ctrl.control.controllers.walking_controller import WalkingController, WalkingOptions
from robot_ctrl.control.loop.pacer import Pacer
from robot_ctrl.eval.recording.push_capture import PushCapture
from robot_ctrl.eval.recording.recorders import HeldFor, ProgressBar, TimeLimit
from robot_ctrl.eval.recording.report_file import write_report
from robot_ctrl.eval.recording.walk_log import GRF_LIMIT_RATIO, WalkLog
from robot_ctrl.eval.recording.walk_recorder import WalkRecorder
from robot_ctrl.geometry import GRAVITY, base_pose_xy_yaw
from robot_ctrl.hw.safety import SafetyLayer
from robot_ctrl.modes import ArmMotion, BaseState, FilterMode
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.scenarios.robot_run import start_run
from robot_ctrl.sim.disturbances import Disturbances

STAND_AFTER = 2.0  # [s] standing after the stop


@dataclass(frozen=True)
class WalkSettings:
    """A walk's settings: the controller's options (step timing in ``controller.params``; the
    filter in a worker process by default), the arms, the GRF limit the report judges against, and
    where the controller's base pose and velocity come from."""

    controller: WalkingOptions = WalkingOptions(dynfilter_worker=True)
    arms: ArmMotion = ArmMotion.NONE
    grf_limit_ratio: float = GRF_LIMIT_RATIO
    base_state: BaseState = BaseState.SIMULATED


def run_walk(robot: RobotModel, hw: SafetyLayer, goal: WalkGoal, settings: WalkSettings = WalkSettings(), *,
             out_dir: Path | None = None, log: Callable[[str], None] = print, progress: bool = False,
             disturbances: Disturbances = Disturbances(), recorders: Sequence = (), pacer: Pacer | None = None) -> dict:
    """Walk ``goal`` on ``hw`` (from :func:`robot_ctrl.backends.open_hardware`, which applied
    ``disturbances``: the report lists them) and report; ``recorders`` (a tick log) see every tick;
    ``pacer`` keeps a real robot's ticks on time."""
    s, options = settings, settings.controller
    controller, run = start_run(robot, hw, s.base_state, lambda seen: WalkingController(
        robot, seen, options, upper_body=arm_motion(s.arms, robot)), pacer, recorders, log)
    start = base_pose_xy_yaw(run.state.base_pos, run.state.base_quat_xyzw)
    path = PathCommander(controller, goal, start, log)
    foot = robot.config.foot
    walk = WalkRecorder(controller, WalkLog(robot.mass * GRAVITY, start, (foot.length, foot.width),
                                            s.grf_limit_ratio), start, log)
    capture = PushCapture(controller, disturbances.pushes, float(start[2]))
    stood = HeldFor(lambda: controller.standing and path.done, STAND_AFTER, "stood at the goal")
    bar = ProgressBar(path.duration + STAND_AFTER + 1.0, progress)
    result = run.loop(options.control_dt, bar, recorders=[walk, capture],
                      stops=[stood, TimeLimit(path.time_limit, "did not finish the path")])
    log(result.stop_reason)
    filtered = options.dynfilter is not FilterMode.OFF
    report = run.metrics.report() | {"robot": robot.name} | walk.report(result.states[0], goal) | dict(
        stood_s=round(stood.held(result.states[0].t), 3), single_support_s=controller.params.single_support,
        double_support_s=controller.params.double_support, stabilizer=options.stabilize,
        push_recovery=options.recover_pushes,
        push_recoveries=controller.push_recoveries, arms=s.arms.value,
        dynfilter=options.dynfilter.value, dynfilter_passes=options.dynfilter_passes if filtered else 0,
        dynfilter_fallbacks=controller.filter_fallbacks, dynfilter_worker=options.dynfilter_worker and filtered,
        push_capture=capture.report()) | run.report(result, disturbances)
    log(f"fell: {str(report['fell']).lower()}  final base (x, y, yaw) {report['final_base_xy_yaw']} vs commanded "
        f"{report['commanded_base_xy_yaw']}  zmp_in_support_ratio {report['zmp_in_support_ratio']}  "
        f"peak_torque_ratio {report['peak_torque_ratio']:.3f}  steps {len(walk.footsteps)}  rtf {report['rtf']}")
    write_report(report, out_dir, log)
    if out_dir is not None:
        log(f"wrote {walk.log.save(out_dir)}")
    return report
