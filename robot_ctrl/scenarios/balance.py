"""Balance demo: the :class:`~robot_ctrl.control.balance_controller.BalanceController` motion
(weight shift, foot lift, right-hand reach) on any hardware adapter, with falls, torques, GRF and
the measured hand error at the end of the reach's hold."""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pinocchio as pin

from robot_ctrl.control.balance_controller import BalanceController, BalanceParams
from robot_ctrl.control.pacer import Pacer
from robot_ctrl.eval.recorders import ProgressBar, TimeLimit
from robot_ctrl.eval.report_file import write_report
from robot_ctrl.hw.disturbances import Disturbances
from robot_ctrl.hw.safety import SafetyLayer
from robot_ctrl.modes import BaseState
from robot_ctrl.robot.model import RobotModel, configuration
from robot_ctrl.scenarios.robot_run import start_run


class HandError:
    """Logs each phase as it starts, and measures the right hand (forward kinematics of the read
    state) against the reach target at the end of the ``hold_reach`` phase."""

    def __init__(self, controller: BalanceController, log: Callable[[str], None]):
        self.controller, self.log = controller, log
        self.robot = controller.robot
        self.data = pin.Data(self.robot.pin)
        self.error: float | None = None
        self._phase = None

    def on_command(self, tick) -> None:
        if self.controller.phase != self._phase:
            self._phase = self.controller.phase
            self.log(f"t = {tick.t:6.2f} s  {self._phase}")

    def on_state(self, tick) -> None:
        motion = self.controller.motion
        if self._phase == "hold_reach" and motion.phase_at(tick.t + self.controller.dt)[0] != "hold_reach":
            state, robot = tick.states[0], self.robot
            pin.framesForwardKinematics(robot.pin, self.data,
                                        configuration(robot, state.base_pos, state.base_quat_xyzw, state.q))
            hand = self.data.oMf[robot.frame_ids["right_hand"]].translation
            self.error = float(np.linalg.norm(hand - motion.hand_target))
            self.log(f"t = {state.t:6.2f} s  hand error {self.error * 1000:.1f} mm")


def run_balance(robot: RobotModel, hw: SafetyLayer, params: BalanceParams = BalanceParams(), *,
                out_dir: Path | None = None, log: Callable[[str], None] = print, progress: bool = False,
                disturbances: Disturbances = Disturbances(), recorders: Sequence = (),
                base_state: BaseState = BaseState.SIMULATED, pacer: Pacer | None = None) -> dict:
    """Run the balance demo on ``hw`` (from :func:`robot_ctrl.hw.hardware.open_hardware`); return
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
