"""DcmStabilizer: balance feedback for a position-controlled humanoid.

The robot cannot be sent a ZMP or a force, only joint positions, so the feedback acts on the CoM
reference the IK tracks (after Kajita et al. 2010, "Biped walking stabilization based on linear
inverted pendulum tracking", and DCM feedback of Englsberger et al. 2015). Per horizontal axis,
world frame, with ω = sqrt(g / h)::

    ξ = c + ċ / ω                                      DCM, measured (c, ċ from the estimator) and planned
    p_d = p_ref + K_dcm (ξ_meas − ξ_ref)               desired ZMP, clamped into the support polygon
    Δċ = k_zmp (p_meas − p_d) + k_com (c_ref − c_meas) − k_leak Δc
    c_cmd = c_ref + Δc,   |Δc| ≤ max_offset

If the measured ZMP lags behind the desired one, the CoM reference is moved back, which makes the
body accelerate backwards relative to the feet and shifts the real ZMP forwards (and vice versa).
``k_dcm = 1 + ω_dcm / ω`` gives the DCM error the convergence rate ω_dcm in the LIP model. ``K_dcm``
applies it per axis of the walking (heading) frame: forward ω_dcm = ``dcm_rate``, lateral
``lateral_dcm_rate`` (default the same). A sole is narrow across and long along the walk, so a robot
with narrow soles may need the lateral DCM error caught sooner than the forward one (Unitree G1:
``configs/robots/g1.yaml``).
The leak returns Δc to zero when errors vanish, so the plan is never drifted away from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Mapping

import numpy as np

from robot_ctrl.control.estimator import Estimate
from robot_ctrl.wpg.lipm import dcm, natural_frequency


@dataclass(frozen=True)
class StabilizerGains:
    dcm_rate: float = 2.0  # ω_dcm [1/s], forward (along the heading)
    lateral_dcm_rate: float | None = None  # ω_dcm [1/s] across the heading; None: dcm_rate
    k_zmp: float = 3.0  # [1/s]
    k_com: float = 2.0  # [1/s]
    k_leak: float = 1.0  # [1/s]
    max_offset: float = 0.04  # [m]

    @classmethod
    def of_robot(cls, stabilizer: Mapping[str, Any]) -> "StabilizerGains":
        """The defaults with a robot config's ``stabilizer:`` fields over them; ValueError naming a field
        that is not a gain or a value outside its range (rates in (0, 100] 1/s, ``max_offset`` in (0, 0.2] m)."""
        names = [f.name for f in fields(cls)]
        for name, value in stabilizer.items():
            if name not in names:
                raise ValueError(f"robot config stabilizer.{name} is not a stabilizer gain "
                                 f"(allowed: {', '.join(names)})")
            top = 0.2 if name == "max_offset" else 100.0
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value <= top:
                raise ValueError(f"robot config stabilizer.{name} = {value!r} must be a number in (0, {top}]")
        return cls(**{name: float(value) for name, value in stabilizer.items()})


class DcmStabilizer:
    def __init__(self, com_height: float, gains: StabilizerGains = StabilizerGains(), enabled: bool = True):
        self.omega = natural_frequency(com_height)
        self.gains = gains
        self.enabled = enabled
        self.offset = np.zeros(2)
        self.desired_zmp: np.ndarray | None = None

    def correction(self, est: Estimate, com_ref: np.ndarray, com_vel_ref: np.ndarray, zmp_ref: np.ndarray,
                   dt: float, heading: float = 0.0) -> np.ndarray:
        """CoM reference offset Δc (2,) [m] for this tick; ``heading``: the walking frame's yaw [rad]
        in the world frame."""
        if not self.enabled:
            return self.offset
        g = self.gains
        error = est.dcm(self.omega) - dcm(com_ref, com_vel_ref, self.omega)
        p_d = zmp_ref + (1.0 + g.dcm_rate / self.omega) * error
        if g.lateral_dcm_rate is not None and g.lateral_dcm_rate != g.dcm_rate:
            across = np.array([-math.sin(heading), math.cos(heading)])  # the heading frame's y axis
            p_d += (g.lateral_dcm_rate - g.dcm_rate) / self.omega * (across @ error) * across
        if est.support is not None:
            p_d = est.support.clamp(p_d)
        self.desired_zmp = p_d
        rate = g.k_com * (com_ref - est.com[:2]) - g.k_leak * self.offset
        if est.zmp is not None:
            rate += g.k_zmp * (est.zmp - p_d)
        self.offset = np.minimum(np.maximum(self.offset + rate * dt, -g.max_offset), g.max_offset)  # np.clip, faster
        return self.offset

