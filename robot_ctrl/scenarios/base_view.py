"""How a scenario's controller sees the robot's base: the simulator's ground truth, or the
floating-base estimator's estimate from the IMU, the encoders and the foot sensors
(``--base-state``). The recorders and the report always use the measured (simulated) state."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, TypeVar

from robot_ctrl.control.base_estimator import BaseEstimator, EstimatedBaseController
from robot_ctrl.eval.recorders import BaseEstimateError
from robot_ctrl.geometry import base_pose_xy_yaw
from robot_ctrl.hw.types import JointState
from robot_ctrl.modes import BaseState
from robot_ctrl.robot.model import RobotModel

C = TypeVar("C")


@dataclass
class BaseView:
    kind: BaseState
    stepped: object  # the controller the loop steps
    error: BaseEstimateError | None = None

    @property
    def recorders(self) -> list:
        """What the loop must record for this view: the estimate's error, if there is an estimate."""
        return [] if self.error is None else [self.error]

    def report(self) -> dict:
        return {"base_state": self.kind.value,
                "base_estimate_error": None if self.error is None else self.error.report()}


def seeing_base(kind: BaseState, robot: RobotModel, state: JointState, build: Callable[[JointState], C]) -> tuple[C, BaseView]:
    """The controller ``build`` makes from the first ``state`` as ``kind`` shows it, and its view."""
    if kind is BaseState.SIMULATED:
        controller = build(state)
        return controller, BaseView(kind, controller)
    estimator = BaseEstimator(robot, base_pose_xy_yaw(state.base_pos, state.base_quat_xyzw))
    controller = build(estimator.update(state))
    stepped = EstimatedBaseController(controller, estimator)
    error = BaseEstimateError(lambda: stepped.seen)
    return controller, BaseView(kind, stepped, error)
