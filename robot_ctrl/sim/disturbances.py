"""Disturbances of a simulated robot: what the real world does to a controller that its model
does not know. Applied by the MuJoCo backend (``MujocoBackend``, ``MujocoWorld``); the controller's
own model (Pinocchio) stays nominal.

- ``pushes``: horizontal forces on the base for ``Push.duration`` (0.1 s) whose impulse is
  ``impulse`` N·s per kg of the simulated robot's mass, direction ``angle`` in the robot's start
  frame (0 forward, π/2 left), from ``time`` on. Applied through the physics rollout's control
  (``xfrc_applied`` per physics step), so they act exactly over their window.
- ``mass_scale``: every body's mass and inertia of the robot times S.
- ``friction_scale``: every geom's sliding friction times S (floor and feet: MuJoCo takes the larger
  of the two geoms' coefficients for a contact).
- ``latency``: each command reaches the servos this long after it was written (a whole number of
  control periods; until the first one arrives the servos hold the start posture).
- ``sensor_noise``: Gaussian noise on what ``read`` reports, standard deviations ``NOISE``.
- ``reply_loss``: on the emulated MIT-CAN bus, each servo reply is lost with this probability
  (a noisy bus; the backend holds the lost values, ``docs/hardware.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

#: Standard deviations of the sensor noise: joint encoders [rad], base orientation per axis [rad]
#: (an IMU's attitude estimate), foot force [N] and torque [N·m] per axis (6-axis F/T sensors).
NOISE = {"joint_position": 1e-3, "base_orientation": math.radians(0.5), "foot_force": 5.0, "foot_torque": 0.5}


@dataclass(frozen=True)
class Push:
    """A horizontal push on the base: from ``time`` [s] for ``duration`` [s], in direction
    ``angle`` [rad] of the robot's start frame (0 forward, π/2 left), of ``impulse`` [N·s/kg] per kg
    of the robot's mass (the CLI's ``--push TIME:ANGLE_DEG:IMPULSE``)."""

    time: float  # [s] start
    angle: float  # [rad] direction in the start frame, 0 forward, π/2 left
    impulse: float  # [N·s/kg] per kg of the robot's mass
    duration: float = 0.1  # [s]

    def __post_init__(self):
        if not (math.isfinite(self.time) and self.time >= 0):
            raise ValueError(f"push time = {self.time} s must be ≥ 0")
        if not math.isfinite(self.angle):
            raise ValueError(f"push angle = {self.angle} must be finite")
        if not (math.isfinite(self.impulse) and 0 <= self.impulse <= 2.0):
            raise ValueError(f"push impulse = {self.impulse} N·s/kg is outside the allowed range [0, 2]")

    @classmethod
    def parse(cls, text: str) -> "Push":
        """``TIME:ANGLE_DEG:IMPULSE``, e.g. ``1.9:-90:0.3``."""
        try:
            t, angle, impulse = (float(v) for v in text.split(":"))
        except ValueError:
            raise ValueError(f"--push {text!r} must be TIME:ANGLE_DEG:IMPULSE, e.g. 1.9:-90:0.3") from None
        return cls(t, math.radians(angle), impulse)


@dataclass(frozen=True)
class Disturbances:
    """What the real world does to a simulated robot that the controller's model does not know:
    pushes, mass and friction scale, command latency [s], sensor noise (with its seed), lost bus
    replies (probability). ``open_hardware("mujoco", robot, disturbances=Disturbances(latency=0.01))``."""

    pushes: tuple[Push, ...] = ()
    mass_scale: float = 1.0
    friction_scale: float = 1.0
    latency: float = 0.0  # [s]
    sensor_noise: bool = False
    seed: int = 0  # of the sensor noise
    noise: dict = field(default_factory=lambda: dict(NOISE))
    reply_loss: float = 0.0  # probability of each reply lost on the emulated MIT-CAN bus

    def __post_init__(self):
        for name, (lo, hi) in {"mass_scale": (0.5, 2.0), "friction_scale": (0.05, 3.0), "latency": (0.0, 0.1),
                               "reply_loss": (0.0, 0.5)}.items():
            value = getattr(self, name)
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"{name} = {value} is outside the allowed range [{lo}, {hi}]")

    def latency_ticks(self, control_dt: float) -> int:
        """The latency in control periods; refused unless it is a whole number of them."""
        ticks = round(self.latency / control_dt)
        if abs(ticks * control_dt - self.latency) > 1e-9:
            raise ValueError(f"latency = {self.latency * 1e3:g} ms must be a multiple of the control period "
                             f"({control_dt * 1e3:g} ms)")
        return ticks

    def to_dict(self) -> dict:
        return {"pushes": [{"time_s": p.time, "angle_deg": round(math.degrees(p.angle), 6),
                            "impulse_ns_per_kg": p.impulse, "duration_s": p.duration} for p in self.pushes],
                "mass_scale": self.mass_scale, "friction_scale": self.friction_scale,
                "latency_ms": round(self.latency * 1e3, 6),
                "sensor_noise": dict(self.noise) if self.sensor_noise else None, "reply_loss": self.reply_loss}
