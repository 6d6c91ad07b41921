"""RobotRun: the frame of a single-robot scenario run: the hardware brought up, the controller
built, on real servos the start sequence, then the control loop with what every run records (falls
and torques, the base estimate's error) and the report fields every run has.

On real servos the robot first moves to its start posture (``bringup.move``, as ``hw stand``:
checks, a minimum-jerk move at reduced gains, a hold). The scenario's controller is built before that move,
from the state the move ends in (the measured body sensors, the joints at the start posture),
and its first tick prepared, because both take longer than the safety layer's watchdog allows
between two commands: done after the move, the servos would drop to damping in between."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Sequence, TypeVar

import numpy as np

from robot_ctrl.control.loop.control_loop import ControlLoop, LoopResult
from robot_ctrl.control.loop.pacer import Pacer
from robot_ctrl.control.loop.start_sequence import StartParams
from robot_ctrl.eval.recording import FallCriterion, RunMetrics
from robot_ctrl.eval.recording.recorders import Fell, MetricsRecorder, ProgressBar
from robot_ctrl.hw.adapter import HardwareFault
from robot_ctrl.hw.safety import SafetyLayer
from robot_ctrl.hw.types import JointState
from robot_ctrl.modes import BaseState
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.scenarios.base_view import BaseView, seeing_base
from robot_ctrl.scenarios.bringup import move
from robot_ctrl.sim.disturbances import Disturbances

C = TypeVar("C")


@dataclass
class RobotRun:
    """A started run: ``state`` is its first state as the recorders see it; ``metrics`` judge falls
    and torques; ``recorders`` (a tick log) and ``pacer`` (real servos) come from the caller."""

    robot: RobotModel
    hw: SafetyLayer
    view: BaseView
    state: JointState
    pacer: Pacer | None
    recorders: Sequence
    metrics: RunMetrics

    def loop(self, dt: float, bar: ProgressBar, recorders: Sequence = (), stops: Sequence = (),
             commanders: Sequence = ()) -> LoopResult:
        """Run the loop at ``dt`` until a fall or one of ``stops``; ``bar`` is closed after it."""
        loop = ControlLoop([self.view.hardware(self.hw)], [self.view.stepped], dt, commanders=commanders,
                           recorders=[MetricsRecorder([self.metrics]), *recorders, bar, *self.view.recorders,
                                      *self.recorders],
                           stops=[Fell([self.metrics]), *stops], pacer=self.pacer)
        try:
            return loop.run([self.state])
        finally:
            self.hw.disarm_watchdog()  # the report is built while the servos hold the last command
            bar.close()

    def report(self, result: LoopResult, disturbances: Disturbances) -> dict:
        """The fields every run's report ends with: how the base was seen, the safety layer, the
        disturbances, why the loop stopped, the real-time factor and rate, and on real servos the
        pacer's timing."""
        safety = self.hw.report()
        # Per joint, what the controller asked for before the safety layer; `peak_torque_ratio` is
        # what the servos delivered after it.
        safety["demanded_peak_torque_ratio"] = dict(zip(self.robot.joint_names, safety["demanded_peak_torque_ratio"]))
        report = dict(**self.view.report(), safety=safety, disturbances=disturbances.to_dict(),
                      stop_reason=result.stop_reason, rtf=round(result.rtf, 3),
                      control_rate_hz=round(1.0 / result.dt, 3))
        if self.pacer is not None:
            report["timing"] = self.pacer.report()
        return report


def start_run(robot: RobotModel, hw: SafetyLayer, base_state: BaseState, build: Callable[[JointState], C],
              pacer: Pacer | None = None, recorders: Sequence = (),
              log: Callable[[str], None] = print) -> tuple[C, RobotRun]:
    """``(controller, run)`` on ``hw``: ``build`` makes the controller from the first state as
    ``base_state`` shows it (``seeing_base``); with ``pacer`` (real servos) the start sequence runs
    first, its ticks seen by ``recorders``."""
    hw.bring_up()
    state = hw.read()
    if pacer is None:
        controller, view = seeing_base(base_state, robot, state, build)
        first = view.first
    else:
        at_start = dataclasses.replace(state, q=np.array(robot.config.half_sitting, dtype=float),
                                       dq=np.zeros(robot.nj))
        controller, view = seeing_base(base_state, robot, at_start, build)
        view.stepped.prepare()  # the first tick's planning, done before the move, not between it and the run
        _start_sequence(robot, hw, pacer, recorders, log)
        first = view.hardware(hw).read()
    metrics = RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(first.base_pos[2])))
    return controller, RobotRun(robot, hw, view, first, pacer, recorders, metrics)


def _start_sequence(robot: RobotModel, hw: SafetyLayer, pacer: Pacer, recorders: Sequence,
                    log: Callable[[str], None]) -> None:
    """The start sequence to half-sitting and its hold, on ``pacer``; a :class:`HardwareFault` (the
    servos in damping) if it did not settle."""
    report = move(robot, hw, None, StartParams(control_dt=pacer.dt), pacer, recorders)
    log(f"start sequence: {'held half-sitting' if report['reached'] else 'did not settle'}, largest tracking "
        f"error {report['largest_tracking_error_rad']} rad")
    if not report["reached"]:
        hw.estop()
        raise HardwareFault(f"the start sequence did not settle (final error {report['final_error_rad']} rad at "
                            f"{report['final_error_joint']}); the servos were sent damping")
