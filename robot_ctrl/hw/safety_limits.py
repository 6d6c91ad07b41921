"""SafetyLimits: what the safety layer (``hw/safety.py``) holds every command within, per joint,
and its timing (watchdog, staleness, soft start, faults). An immutable value, checked on creation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.robot.model import RobotModel


@dataclass(frozen=True)
class SafetyLimits:
    lower: np.ndarray  # (nj,) position limits [rad]
    upper: np.ndarray
    velocity: np.ndarray  # (nj,) [rad/s]
    effort: np.ndarray  # (nj,) [N·m]
    kd_damping: np.ndarray  # (nj,) damping-mode gains [N·m·s/rad]
    kp_max: np.ndarray  # (nj,) the largest stiffness a command may carry [N·m/rad]
    kd_max: np.ndarray  # (nj,) the largest damping a command may carry [N·m·s/rad]
    control_dt: float = 0.005  # [s]
    max_step: float | None = None  # [rad] per tick for every joint; None: each joint's velocity limit × control_dt
    soft_start: float = 0.5  # [s]
    watchdog_periods: float = 2.0
    stale_periods: float = 4.0
    rejected_fault_time: float = 0.02  # [s] of rejected commands in a row before a FAULT
    limit_tolerance: float = 0.02  # [rad] a measured position this far beyond a limit is flagged
    temperature_warn: float = 60.0  # [°C]
    temperature_derate: float = 70.0
    temperature_fault: float = 80.0

    def __post_init__(self):
        n = len(self.lower)
        for name in ("upper", "velocity", "effort", "kd_damping", "kp_max", "kd_max"):
            value = np.asarray(getattr(self, name))
            if value.shape != (n,) or not np.all(np.isfinite(value)) or np.any(value < 0):
                raise ValueError(f"SafetyLimits.{name} must be {n} finite values >= 0")
        if np.any(np.asarray(self.lower) >= np.asarray(self.upper)):
            raise ValueError("SafetyLimits.lower must be below upper for every joint")
        checks = {"control_dt": (1e-4, 0.1), "soft_start": (0.0, 10.0),
                  "watchdog_periods": (1.0, 100.0), "stale_periods": (1.0, 1000.0),
                  "rejected_fault_time": (1e-4, 1.0), "limit_tolerance": (0.0, 1.0)}
        if self.max_step is not None:
            checks["max_step"] = (1e-4, 1.0)
        for name, (lo, hi) in checks.items():
            value = getattr(self, name)
            if not (np.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"SafetyLimits.{name} = {value} is outside the allowed range [{lo}, {hi}]")
        if not self.temperature_warn <= self.temperature_derate < self.temperature_fault:
            raise ValueError("SafetyLimits temperatures must satisfy warn <= derate < fault")

    @property
    def step_limit(self) -> np.ndarray:
        """(nj,) [rad] how far a position target may move in one tick: no farther than the joint
        can move at its velocity limit (``max_step`` for every joint where it is set)."""
        if self.max_step is not None:
            return np.full(len(self.lower), float(self.max_step))
        return np.asarray(self.velocity) * self.control_dt

    @classmethod
    def for_simulation(cls, robot: RobotModel, control_dt: float = 0.005) -> "SafetyLimits":
        """The limits in front of a simulated robot: those of :meth:`from_robot` without the soft
        start (the simulation starts with the servos holding the start posture), so that a run
        within the limits is the same with or without the layer."""
        return cls.from_robot(robot, control_dt, soft_start=0.0)

    @classmethod
    def from_robot(cls, robot: RobotModel, control_dt: float = 0.005, **overrides) -> "SafetyLimits":
        """Limits from the robot model: URDF position limits (already inside the config's margins
        for the IK), velocity and effort limits, the default servo damping for damping mode, and
        gains capped at the config's ``max_gain_ratio`` times the servo gains."""
        ratio = robot.config.max_gain_ratio
        return cls(lower=robot.lower.copy(), upper=robot.upper.copy(), velocity=robot.velocity_limit.copy(),
                   effort=robot.effort.copy(), kd_damping=robot.kd.copy(), kp_max=ratio * robot.kp,
                   kd_max=ratio * robot.kd, control_dt=control_dt, **overrides)
