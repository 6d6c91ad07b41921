"""How a scenario's controller sees the robot's base: the simulator's ground truth, or the
floating-base estimator's estimate from the IMU, the encoders and the foot sensors
(``--base-state``). With a simulator, the recorders and the report use its measured state; a real
robot has no ground truth, so there everything, recorders included, sees the estimate."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, TypeVar

from robot_ctrl.control.estimation.base_estimator import BaseEstimator, EstimatedBaseController
from robot_ctrl.eval.recording.recorders import BaseEstimateError
from robot_ctrl.geometry import base_pose_xy_yaw
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.modes import BaseState
from robot_ctrl.robot.model import RobotModel

C = TypeVar("C")


@dataclass
class BaseView:
    kind: BaseState
    stepped: object  # the controller the loop steps
    first: JointState  # the first state, as the run's recorders see it
    error: BaseEstimateError | None = None
    estimator: BaseEstimator | None = None  # without ground truth: every state read goes through it

    @property
    def recorders(self) -> list:
        """What the loop must record for this view: the estimate's error, if there is an estimate
        and a truth to compare it with."""
        return [] if self.error is None else [self.error]

    def hardware(self, hw):
        """What the loop writes to and reads from: ``hw``, or, without ground truth, ``hw`` whose
        states carry the estimated base."""
        return hw if self.estimator is None else _EstimatedBase(hw, self.estimator)

    def report(self) -> dict:
        return {"base_state": self.kind.value, "base_ground_truth": self.estimator is None,
                "base_estimate_error": None if self.error is None else self.error.report()}


class _EstimatedBase:
    """A robot's hardware whose states carry the estimator's base pose and velocity."""

    def __init__(self, hw, estimator: BaseEstimator):
        self.hw, self.estimator = hw, estimator

    def write(self, command: JointCommand) -> None:
        self.hw.write(command)

    def read(self) -> JointState:
        return self.estimator.update(self.hw.read())


def seeing_base(kind: BaseState, robot: RobotModel, state: JointState, build: Callable[[JointState], C]) -> tuple[C, BaseView]:
    """The controller ``build`` makes from the first ``state`` as ``kind`` shows it, and its view.
    A state without a base pose is a real robot's: only the estimate can show it, and the run's
    frame is the start pose (x forward, y left, on the floor)."""
    if state.base_pos is None:
        if kind is not BaseState.ESTIMATED:
            raise ValueError("the robot reports no base pose (real servos): its base can only be estimated "
                             "(--base-state estimated)")
        estimator = BaseEstimator(robot, (0.0, 0.0, 0.0))
        first = estimator.update(state)
        controller = build(first)
        return controller, BaseView(kind, controller, first, estimator=estimator)
    if kind is BaseState.SIMULATED:
        controller = build(state)
        return controller, BaseView(kind, controller, state)
    estimator = BaseEstimator(robot, base_pose_xy_yaw(state.base_pos, state.base_quat_xyzw))
    controller = build(estimator.update(state))
    stepped = EstimatedBaseController(controller, estimator)
    error = BaseEstimateError(lambda: stepped.seen)
    return controller, BaseView(kind, stepped, state, error)
