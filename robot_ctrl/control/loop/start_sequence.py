"""StartSequence: the first motion of a real robot, from wherever it is to its start posture.

1. **Check** the measured posture before anything moves: every joint inside its position limits
   (with ``limit_tolerance``) and within ``max_start_error`` of the target, which must itself lie
   inside the limits. A joint outside
   usually means a wrong zero offset or direction sign in the bus mapping, or a robot not hanging
   as expected; :class:`StartRefused` names the joints.
2. **Move** every joint from its measured angle to the start posture on a minimum-jerk profile
   (Flash & Hogan 1985) over ``duration`` seconds, at ``gain_scale`` × the servo stiffness and
   √``gain_scale`` × the damping (the damping ratio of the full gains); the torque feedforward
   (``feedforward``, e.g. the gravity torques at the start posture) ramps in on the same profile.
3. **Watch** the tracking error at every tick: a joint more than ``max_tracking_error`` from its
   reference (a sign error drives it the other way; a blocked joint stays behind) raises
   :class:`TrackingFault`, which the caller turns into damping.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.geometry.interpolation import minimum_jerk
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.robot.model import RobotModel


class StartRefused(ValueError):
    """The measured posture is not one the start sequence may move from; the message names the joints."""


class TrackingFault(RuntimeError):
    """A joint left its reference during the start sequence; the message names it."""


@dataclass(frozen=True)
class StartParams:
    duration: float = 4.0  # [s] of the move
    gain_scale: float = 0.3  # share of the servo stiffness during the move
    max_start_error: float = 1.0  # [rad] from the start posture before moving
    max_tracking_error: float = 0.15  # [rad] from the moving reference
    limit_tolerance: float = 0.02  # [rad] a measured joint may be outside its limits (encoder, compliance)
    control_dt: float = 0.005  # [s]

    def __post_init__(self):
        checks = {"duration": (0.5, 60.0), "gain_scale": (0.01, 1.0), "max_start_error": (0.01, 6.3),
                  "max_tracking_error": (0.005, 1.0), "limit_tolerance": (0.0, 0.5), "control_dt": (1e-4, 0.1)}
        for name, (lo, hi) in checks.items():
            value = getattr(self, name)
            if not (np.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"StartParams.{name} = {value} is outside the allowed range [{lo}, {hi}]")


class StartSequence:
    """A :class:`~robot_ctrl.control.loop.control_loop.Controller` from the measured ``state`` to ``target``
    (joint order, rad; default the robot's start posture, half-sitting)."""

    def __init__(self, robot: RobotModel, state: JointState, target: np.ndarray | None = None,
                 params: StartParams = StartParams(), feedforward: np.ndarray | None = None):
        self.robot, self.params = robot, params
        self.target = np.array(robot.config.half_sitting if target is None else target, dtype=float)
        self.feedforward = np.zeros(robot.nj) if feedforward is None else np.asarray(feedforward, dtype=float)
        self.start = np.asarray(state.q, dtype=float).copy()
        self._check(self.start)
        self.k = 0
        self.largest_error = 0.0  # [rad] of tracking, over the move

    @property
    def done(self) -> bool:
        """The move has reached the start posture (its reference has)."""
        return self.k * self.params.control_dt >= self.params.duration

    def prepare(self) -> None:
        pass

    def step(self, state: JointState) -> JointCommand:
        p, robot = self.params, self.robot
        s, ds = minimum_jerk(self.k * p.control_dt, p.duration)
        self.k += 1
        reference = np.clip(self.start + s * (self.target - self.start), robot.lower, robot.upper)
        error = np.abs(reference - state.q)
        self.largest_error = max(self.largest_error, float(error.max()))
        if error.max() > p.max_tracking_error:
            raise TrackingFault(f"{self._names(error > p.max_tracking_error)} {error.max():.3f} rad from the "
                                f"reference (limit {p.max_tracking_error} rad): check the direction sign and the "
                                "zero offset in the bus mapping")
        return JointCommand(q=reference, dq=ds * (self.target - self.start), kp=p.gain_scale * robot.kp,
                            kd=np.sqrt(p.gain_scale) * robot.kd, tau_ff=s * self.feedforward)

    def close(self) -> None:
        pass

    def _check(self, q: np.ndarray) -> None:
        r, p = self.robot, self.params
        beyond = (self.target < r.lower) | (self.target > r.upper)
        if beyond.any():
            raise StartRefused("; ".join(f"{r.joint_names[i]} would go to {self.target[i]:.3f} rad, outside its "
                                         f"limits [{r.lower[i]:.3f}, {r.upper[i]:.3f}]" for i in np.flatnonzero(beyond)))
        outside = (q < r.lower - p.limit_tolerance) | (q > r.upper + p.limit_tolerance)
        if outside.any():
            raise StartRefused(f"{self._names(outside)} outside the position limits: check the zero offsets and "
                               "direction signs in the bus mapping")
        far = np.abs(q - self.target) > p.max_start_error
        if far.any():
            raise StartRefused(f"{self._names(far)} more than {p.max_start_error} rad from the start posture: move "
                               "them closer by hand, or check the bus mapping")

    def _names(self, mask: np.ndarray) -> str:
        return ", ".join(self.robot.joint_names[i] for i in np.flatnonzero(mask))
