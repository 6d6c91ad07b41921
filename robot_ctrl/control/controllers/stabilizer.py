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

from robot_ctrl.control.estimation.state_estimator import Estimate
from robot_ctrl.geometry.support_polygon import clamp_to_polygon
from robot_ctrl.kernels import FLOAT, MATRIX, VECTOR, kernel
from robot_ctrl.wpg.lipm import natural_frequency


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
        g, omega = self.gains, self.omega
        lateral = 0.0 if g.lateral_dcm_rate is None else (g.lateral_dcm_rate - g.dcm_rate) / omega
        self.offset, self.desired_zmp = dcm_feedback(
            est.com, est.com_velocity, com_ref, com_vel_ref, zmp_ref, omega, 1.0 + g.dcm_rate / omega, lateral,
            heading, _NO_POLYGON if est.support is None else est.support.vertices,
            _NO_ZMP if est.zmp is None else est.zmp, self.offset, g.k_com, g.k_leak, g.k_zmp, g.max_offset, dt)
        return self.offset


_NO_POLYGON = np.zeros((0, 2))
_NO_ZMP = np.zeros(0)


@kernel((VECTOR, VECTOR, VECTOR, VECTOR, VECTOR, FLOAT, FLOAT, FLOAT, FLOAT, MATRIX, VECTOR, VECTOR, FLOAT, FLOAT,
         FLOAT, FLOAT, FLOAT))
def dcm_feedback(com, com_velocity, com_ref, com_vel_ref, zmp_ref, omega, k_dcm, lateral, heading, support, zmp,
                 offset, k_com, k_leak, k_zmp, max_offset, dt):
    """One tick of the module docstring's law, per horizontal axis: the new offset ``Δc`` and the
    desired ZMP ``p_d`` (world frame). ``com``, ``com_velocity``: measured (their x, y); ``k_dcm =
    1 + ω_dcm / ω``; ``lateral = (ω_dcm,lat − ω_dcm) / ω``, added along the heading frame's y axis
    (0: none); ``support``: the support polygon's counter-clockwise vertices (no rows: none);
    ``zmp``: measured (empty: none). Compiled: a dozen numpy calls on 2-vectors on the tick's
    serial path cost several times the arithmetic."""
    error = np.empty(2)
    p_d = np.empty(2)
    for i in range(2):
        error[i] = (com[i] + com_velocity[i] / omega) - (com_ref[i] + com_vel_ref[i] / omega)  # ξ_meas − ξ_ref
        p_d[i] = zmp_ref[i] + k_dcm * error[i]
    if lateral != 0.0:
        ax, ay = -math.sin(heading), math.cos(heading)  # the heading frame's y axis
        s = lateral * (ax * error[0] + ay * error[1])
        p_d[0] += s * ax
        p_d[1] += s * ay
    if support.shape[0] > 0:
        p_d = clamp_to_polygon(support, p_d)
    moved = np.empty(2)
    for i in range(2):
        rate = k_com * (com_ref[i] - com[i]) - k_leak * offset[i]
        if zmp.size > 0:
            rate += k_zmp * (zmp[i] - p_d[i])
        x = offset[i] + rate * dt
        x = x if x >= -max_offset else -max_offset  # NaN stays NaN, as with np.clip
        moved[i] = x if x <= max_offset else max_offset
    return moved, p_d

