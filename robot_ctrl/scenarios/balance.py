"""Balance demo: the :class:`~robot_ctrl.control.controllers.balance_controller.BalanceController` motion
(weight shift, foot lift, right-hand reach) on any hardware adapter, with falls, torques, GRF and
the measured hand error at the end of the reach's hold."""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

from robot_ctrl.control.controllers.balance_controller import BalanceController, BalanceParams
from robot_ctrl.control.loop.pacer import Pacer
from robot_ctrl.eval.recording.hand_error import HandError
from robot_ctrl.eval.recording.recorders import ProgressBar, TimeLimit
from robot_ctrl.eval.recording.report_file import write_report
from robot_ctrl.hw.safety import SafetyLayer
from robot_ctrl.modes import BaseState
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.scenarios.robot_run import start_run
from robot_ctrl.sim.disturbances import Disturbances


def run_balance(robot: RobotModel, hw: SafetyLayer, params: BalanceParams = BalanceParams(), *,
                out_dir: Path | None = None, log: Callable[[str], None] = print, progress: bool = False,
                disturbances: Disturbances = Disturbances(), recorders: Sequence = (),
                base_state: BaseState = BaseState.SIMULATED, pacer: Pacer | None = None) -> dict:
    """Run the balance demo on ``hw`` (from :func:`robot_ctrl.backends.open_hardware`); return
    (and write to ``out_dir``) the report; ``recorders`` (a tick log) see every tick; the
    controller sees the base as ``base_state`` says; ``pacer`` keeps a real robot's ticks on time."""
    dt = params.control_dt
    controller, run = start_run(robot, hw, base_state, lambda seen: BalanceController(robot, seen, params),
                                pacer, recorders, log)
    hand = HandError(controller, log)
    result = run.loop(dt, ProgressBar(controller.duration, progress), recorders=[hand],
                      stops=[TimeLimit(controller.duration - dt / 2, "motion done:")])
    if run.metrics.fell:
        log(result.stop_reason)
    report = run.metrics.report() | dict(robot=robot.name, hand_error_m=hand.error,
                                         hand_target_floor_m=list(params.hand_target)) | run.report(
        result, disturbances)
    log(f"safety layer: {report['safety']}")
    log(f"fell: {str(report['fell']).lower()}  hand_error_m: {hand.error}  peak_torque_ratio: "
        f"{report['peak_torque_ratio']:.3f} ({report['peak_torque_joint']})  peak_grf_n: {report['peak_grf_n']}  "
        f"rtf: {report['rtf']}")
    write_report(report, out_dir, log)
    return report
