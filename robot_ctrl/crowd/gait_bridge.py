"""GaitBridge: one robot's crowd outputs (gait frequency ω_i, step-length scale μ_i, heading rate)
mapped onto its walking pattern generator's inputs.

The gait cycle is two steps, so the step period is ``π / ω_i``: the pattern generator's time scale
is ``ω₀ / ω_i`` with ``ω₀ = π / T_step`` its nominal frequency. The forward speed follows the
crowd model's propagation law ``ż = (1 + μ_i) ω_i g(φ)``: step length ``(1 + μ_i)`` times the
nominal one, so ``v_x = (1 + μ_i) (ω_i / ω₀) v₀``. The heading rate is the yaw-rate reference.
Time scale and μ are clamped to ranges the walking controller handles; the command says when.
Velocities are in the robot's heading frame (x forward, y left), SI units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GaitCommand:
    time_scale: float  # step period / nominal step period
    velocity: tuple[float, float, float]  # (vx [m/s], vy [m/s], ωz [rad/s]) in the heading frame
    saturated: bool  # a clamp was active


@dataclass(frozen=True)
class GaitBridge:
    step_period: float  # nominal step period T_step [s]
    speed: float  # nominal forward speed v₀ [m/s]
    time_scale_range: tuple[float, float] = (0.8, 1.25)
    mu_range: tuple[float, float] = (-0.5, 0.5)
    max_yaw_rate: float = 0.3  # [rad/s]

    def __post_init__(self):
        if not (np.isfinite(self.step_period) and self.step_period > 0):
            raise ValueError(f"step_period = {self.step_period} s must be > 0")
        if not (np.isfinite(self.speed) and 0 <= self.speed <= 1.0):
            raise ValueError(f"speed = {self.speed} m/s must be in [0, 1]")

    @property
    def omega0(self) -> float:
        """Nominal gait frequency [rad/s] (2π per two steps)."""
        return np.pi / self.step_period

    def command(self, omega: float, mu: float, yaw_rate: float) -> GaitCommand:
        if not all(np.isfinite(v) for v in (omega, mu, yaw_rate)):
            raise ValueError(f"crowd outputs must be finite, got ω={omega}, μ={mu}, ψ̇={yaw_rate}")
        lo, hi = self.time_scale_range
        scale = self.omega0 / omega if omega > 0 else hi
        clamped_scale = float(np.clip(scale, lo, hi))
        clamped_mu = float(np.clip(mu, *self.mu_range))
        clamped_yaw = float(np.clip(yaw_rate, -self.max_yaw_rate, self.max_yaw_rate))
        vx = (1.0 + clamped_mu) * self.speed / clamped_scale
        saturated = clamped_scale != scale or clamped_mu != mu or clamped_yaw != yaw_rate
        return GaitCommand(clamped_scale, (vx, 0.0, clamped_yaw), bool(saturated))
