"""ArmSwing: an upper-body reference that swings joints sinusoidally around a base posture, the
fast upper-body motion used to exercise the dynamic filter (issue: walk with ``--arms swing``).

``posture(t) = base + r(t) amplitude · sin(2π f t)`` on the swing joints (all in phase), base
elsewhere, with ``r`` a smooth ramp from 0 to 1 over the first second (no velocity step at the
start); joint order of the robot config, radians. Talos has no shoulder pitch joint (its shoulder is yaw,
roll, yaw), so the default swings the elbows (``arm_*_4_joint``, pitch) forward and back, by
``AMPLITUDE`` at 1 Hz: as much as the elbows' servos follow within their torque limit (at 0.5 rad
they were asked for up to 1.28 × it, and the safety layer clamped 34 ticks of a 3 m walk). The
swing is clipped into the joint limits given.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from robot_ctrl.modes import ArmMotion
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.sot.joint_limits import JointLimits

AMPLITUDE = 0.35  # [rad] of the default swing (module docstring)


def elbows(robot: RobotModel) -> tuple[str, str]:
    """The joints ``--arms swing`` swings: the elbows the robot config names (``joints.elbows``)."""
    return tuple(robot.config.joint_roles["elbows"][s] for s in ("left", "right"))


def arm_motion(kind: ArmMotion | str, robot: RobotModel) -> Callable[[float], np.ndarray] | None:
    """The upper-body reference ``posture(t)`` for ``kind``; None: the controller's default posture."""
    if ArmMotion.parse(kind) is ArmMotion.NONE:
        return None
    limits = JointLimits.from_robot(robot)
    return ArmSwing.for_joints(elbows(robot), robot.joint_names,
                               np.clip(robot.config.half_sitting, limits.q_min, limits.q_max),
                               limits.q_min, limits.q_max)


@dataclass(frozen=True)
class ArmSwing:
    base: np.ndarray  # (nj,) posture [rad]
    joints: np.ndarray  # indices of the swinging joints
    lower: np.ndarray  # (nj,) limits the posture is clipped into [rad]
    upper: np.ndarray
    amplitude: float = AMPLITUDE  # [rad]
    frequency: float = 1.0  # [Hz]

    @classmethod
    def for_joints(cls, names: tuple[str, ...], joint_names: tuple[str, ...], base, lower, upper,
                   amplitude: float = AMPLITUDE, frequency: float = 1.0) -> "ArmSwing":
        missing = [n for n in names if n not in joint_names]
        if missing:
            raise ValueError(f"swing joints {missing} are not joints of the robot")
        if not (np.isfinite(amplitude) and 0 < amplitude <= 1.5 and np.isfinite(frequency) and 0 < frequency <= 3):
            raise ValueError(f"arm swing amplitude = {amplitude} rad must be in (0, 1.5] and frequency = "
                             f"{frequency} Hz in (0, 3]")
        return cls(np.asarray(base, dtype=float), np.array([joint_names.index(n) for n in names]),
                   np.asarray(lower), np.asarray(upper), amplitude, frequency)

    def __call__(self, t: float) -> np.ndarray:
        q = self.base.copy()
        s = min(max(t, 0.0), 1.0)
        q[self.joints] += s * s * (3 - 2 * s) * self.amplitude * np.sin(2 * np.pi * self.frequency * t)
        return np.clip(q, self.lower, self.upper)
