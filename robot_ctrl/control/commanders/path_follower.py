"""PathFollower: velocity reference (vx, vy, ωz) in the heading frame that walks a path to its end pose.

Paths (start frame: x forward, y left, from the start pose): a straight line, an arc of length
``distance`` whose heading turns by ``turn`` (radius distance / turn), or a side-step of
``lateral`` metres. The progress ``s(t)`` follows a trapezoidal profile (speed, acceleration); the
reference is its feedforward velocity plus proportional feedback on the pose error between the
path point at ``s(t)`` and the planned CoM pose, so the robot ends where commanded rather than
where an open-loop velocity integral would put it. Once the path is done and the error is small,
the reference is zero and the pattern generator stops.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.geometry import rotation, wrap_angle


@dataclass(frozen=True)
class WalkGoal:
    """A path from the start pose (start frame: x forward, y left): ``distance`` [m] forward
    (the arc's length when turning), ``turn`` [rad] of heading over it, or ``lateral`` [m] sideways
    (+ left), walked at ``speed`` [m/s]. ``WalkGoal(distance=2.0, turn=np.pi / 2)``."""

    distance: float = 0.0  # [m] path length forward (arc length when turning)
    turn: float = 0.0  # [rad] heading change over the path
    lateral: float = 0.0  # [m] side-step, + left
    speed: float = 0.25  # [m/s]

    def __post_init__(self):
        checks = {"distance": (0.0, 100.0), "turn": (-np.pi, np.pi), "lateral": (-10.0, 10.0), "speed": (0.02, 0.5)}
        for name, (lo, hi) in checks.items():
            value = getattr(self, name)
            if not (np.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"{name} = {value} is outside the allowed range [{lo}, {hi}]")
        if self.lateral and (self.distance or self.turn):
            raise ValueError("lateral walks side-steps only: give either lateral, or distance (and turn)")
        if self.turn and not self.distance:
            raise ValueError("turn needs a distance: the path is an arc of that length")

    @property
    def length(self) -> float:
        return abs(self.lateral) if self.lateral else self.distance

    def pose_at(self, s: float) -> np.ndarray:
        """Path pose (x, y, yaw) at arc length ``s`` in the start frame."""
        if self.lateral:
            return np.array([0.0, np.sign(self.lateral) * s, 0.0])
        if abs(self.turn) < 1e-9:
            return np.array([s, 0.0, 0.0])
        radius = self.distance / self.turn
        angle = s / radius
        return np.array([radius * np.sin(angle), radius * (1.0 - np.cos(angle)), angle])

    def velocity_at(self, s_dot: float) -> np.ndarray:
        """Feedforward (vx, vy, ωz) in the heading frame at path speed ``s_dot``."""
        if self.lateral:
            return np.array([0.0, np.sign(self.lateral) * s_dot, 0.0])
        curvature = self.turn / self.distance if self.distance else 0.0
        return np.array([s_dot, 0.0, curvature * s_dot])


class PathFollower:
    def __init__(self, goal: WalkGoal, start: np.ndarray, acceleration: float = 0.25, gain: float = 1.0,
                 yaw_gain: float = 1.0, tolerance: tuple[float, float] = (0.01, 0.01), settle_time: float = 4.0):
        """``start``: world pose (x, y, yaw) of the path's origin (the base at the start). Once the
        path's end is reached, the reference is zeroed when the error is within ``tolerance``
        (m, rad) or after ``settle_time`` seconds, whichever comes first."""
        self.goal = goal
        self.start = np.asarray(start, dtype=float)
        self.settle_time = settle_time
        self.accel = acceleration
        self.gain, self.yaw_gain = gain, yaw_gain
        self.tolerance = tolerance
        self.done = False

    @property
    def end_time(self) -> float:
        """Time at which the progress profile reaches the end of the path [s]."""
        L, v, a = self.goal.length, self.goal.speed, self.accel
        if L < v * v / a:
            return 2.0 * np.sqrt(L / a)
        return L / v + v / a

    def progress(self, t: float) -> tuple[float, float]:
        """Trapezoidal ``(s, ṡ)`` at time ``t``."""
        L, v, a = self.goal.length, self.goal.speed, self.accel
        t_ramp = v / a
        if L < v * t_ramp:  # triangle profile
            t_ramp = np.sqrt(L / a)
            v = a * t_ramp
        cruise = (L - v * t_ramp) / v
        if t < t_ramp:
            return 0.5 * a * t * t, a * t
        if t < t_ramp + cruise:
            return 0.5 * v * t_ramp + v * (t - t_ramp), v
        td = t - t_ramp - cruise
        if td < t_ramp:
            return L - 0.5 * a * (t_ramp - td) ** 2, a * (t_ramp - td)
        return L, 0.0

    def world_pose(self, local: np.ndarray) -> np.ndarray:
        xy = self.start[:2] + rotation(self.start[2]) @ local[:2]
        return np.array([xy[0], xy[1], self.start[2] + local[2]])

    def velocity(self, t: float, planned: np.ndarray) -> np.ndarray:
        """Reference (vx, vy, ωz) in the heading frame given the planned base pose (x, y, yaw), world frame."""
        if self.done:
            return np.zeros(3)
        s, s_dot = self.progress(t)
        target = self.world_pose(self.goal.pose_at(s))
        error_xy = rotation(planned[2]).T @ (target[:2] - planned[:2])
        error_yaw = wrap_angle(target[2] - planned[2])
        settled = np.linalg.norm(error_xy) < self.tolerance[0] and abs(error_yaw) < self.tolerance[1]
        if s >= self.goal.length and (settled or t > self.end_time + self.settle_time):
            self.done = True
            return np.zeros(3)
        v = self.goal.velocity_at(s_dot) + np.array([*(self.gain * error_xy), self.yaw_gain * error_yaw])
        limit = 1.2 * self.goal.speed
        norm = np.linalg.norm(v[:2])
        if norm > limit:
            v[:2] *= limit / norm
        return v
