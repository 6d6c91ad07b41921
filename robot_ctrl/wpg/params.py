"""WalkParams: timing, geometry and weights of the walking pattern generator (SI units).

The defaults are Talos's; a robot config's ``walking:`` section gives the fields its robot needs
otherwise (:meth:`WalkParams.of_robot`).

The robot-dependent fields (``com_height``, ``foot_length``, ``foot_width``, ``step_width``) may be
left as None: the walking controller derives them from the robot at its start posture
(:meth:`WalkParams.for_robot`), and refuses values given that contradict it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Any, Mapping

#: Fields the controller derives from the robot when they are not given.
ROBOT_FIELDS = ("com_height", "foot_length", "foot_width", "step_width")
#: A given com_height or step_width may differ this much from the robot's [m].
MEASURED_TOLERANCE = 0.01


@dataclass(frozen=True)
class WalkParams:
    """The walking pattern generator's parameters, immutable: MPC sample time [s] and horizon
    (samples), step timing [s], the cart-table model's CoM height and the soles' size [m] (derived
    from the robot when unset), reach, weights and the QP solver. ``WalkParams(single_support=0.5)``."""

    sample_time: float = 0.1  # [s] MPC sampling T
    horizon: int = 16  # samples (1.6 s)
    single_support: float = 0.7  # [s]
    double_support: float = 0.1  # [s]
    start_transfer: float = 0.8  # [s] double support that moves the ZMP onto the first stance foot
    com_height: float | None = None  # [m] constant CoM height of the cart-table model (above the soles)
    foot_length: float | None = None  # [m] sole rectangle the ZMP is kept in
    foot_width: float | None = None
    zmp_margin: float = 0.025  # [m] kept between the ZMP and the sole's edges
    step_width: float | None = None  # [m] nominal lateral distance between the sole frames
    reach_x: tuple[float, float] = (-0.2, 0.3)  # [m] next foot in the stance foot's frame, forward
    reach_y: tuple[float, float] = (0.0, 0.15)  # [m] lateral, beyond step_width (outward +); narrower steps let the knees touch when turning
    max_yaw_step: float = 0.3  # [rad] yaw change of one footstep
    swing_apex: float = 0.05  # [m] swing-foot apex height
    swing_freeze: float = 0.2  # [s] the landing target stops following the MPC this long before landing
    # Cost weights (Herdt et al. 2010): CoM velocity tracking, ZMP centring, jerk, footstep regularization.
    w_velocity: float = 1.0
    w_zmp: float = 10.0
    w_jerk: float = 1e-4
    w_footstep: float = 30.0
    solver: str = "daqp"  # daqp called directly, or a CasADi conic plugin (see robot_ctrl.wpg.mpc)

    @property
    def step_period(self) -> float:
        return self.single_support + self.double_support

    def __post_init__(self):
        checks = {
            "sample_time": (1e-3, 1.0), "horizon": (2, 100), "single_support": (0.05, 5.0),
            "double_support": (0.0, 5.0), "start_transfer": (0.05, 5.0), "com_height": (0.1, 3.0),
            "foot_length": (0.02, 1.0), "foot_width": (0.02, 1.0), "step_width": (0.02, 1.0),
            "max_yaw_step": (0.0, 1.5), "swing_apex": (0.0, 0.5), "zmp_margin": (0.0, 0.2),
        }
        for f in fields(self):
            if f.name in ROBOT_FIELDS and getattr(self, f.name) is None:
                continue
            if f.name in checks:
                lo, hi = checks[f.name]
                value = getattr(self, f.name)
                if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
                    raise ValueError(f"WalkParams.{f.name} = {value!r} is outside the allowed range [{lo}, {hi}]")
        for name in ("single_support", "double_support", "start_transfer"):
            ratio = getattr(self, name) / self.sample_time
            if abs(ratio - round(ratio)) > 1e-9:
                raise ValueError(f"WalkParams.{name} = {getattr(self, name)} s must be a multiple of "
                                 f"sample_time = {self.sample_time} s")
        if self.resolved and 2 * self.zmp_margin >= min(self.foot_length, self.foot_width):
            raise ValueError(f"WalkParams.zmp_margin = {self.zmp_margin} m leaves no room inside the sole")

    @classmethod
    def of_robot(cls, walking: Mapping[str, Any], **given: Any) -> "WalkParams":
        """The defaults, with a robot config's ``walking:`` fields over them (a robot's size calls for
        its own step timing, reach and ZMP margin) and the ``given`` fields over those."""
        names = {f.name for f in fields(cls)}
        for name in walking:
            if name not in names or name in ROBOT_FIELDS:
                allowed = ", ".join(sorted(names - set(ROBOT_FIELDS)))
                raise ValueError(f"robot config walking.{name} is not a walking parameter a config sets "
                                 f"(allowed: {allowed}; {', '.join(ROBOT_FIELDS)} come from the robot itself)")
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in walking.items()}
        return cls(**{**values, **given})

    @property
    def resolved(self) -> bool:
        """Every robot-dependent field has a value."""
        return all(getattr(self, name) is not None for name in ROBOT_FIELDS)

    def for_robot(self, com_height: float, foot_length: float, foot_width: float, step_width: float) -> "WalkParams":
        """These parameters with the robot's values where none were given. A given ``com_height`` or
        ``step_width`` must match the robot's start posture (the controller holds that CoM height
        and plans from those feet) within ``MEASURED_TOLERANCE``; a given sole may not be larger
        than the robot's."""
        measured = {"com_height": com_height, "foot_length": foot_length, "foot_width": foot_width,
                    "step_width": step_width}
        for name, value in measured.items():
            given = getattr(self, name)
            if given is None:
                continue
            if name in ("foot_length", "foot_width"):
                if given > value + 1e-9:
                    raise ValueError(f"WalkParams.{name} = {given} m is larger than the robot's sole ({value:.3f} m)")
            elif abs(given - value) > MEASURED_TOLERANCE:
                raise ValueError(f"WalkParams.{name} = {given} m contradicts the robot's start posture "
                                 f"({value:.3f} m, tolerance {MEASURED_TOLERANCE} m): leave it unset to derive it")
        return dataclasses.replace(self, **{k: v for k, v in measured.items() if getattr(self, k) is None})
