"""What the walking pattern generator gives the stages after it: the gait phase, the plan at one
control instant, the plan over the MPC's horizon (what the dynamic filter previews), and each
touch-down. Plain values, world frame, SI units; the floor is z = 0."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from robot_ctrl.geometry import SIDES, Side
from robot_ctrl.wpg.footstep import Footstep


class GaitPhase(str, Enum):
    """``STAND`` (double support, indefinitely) → ``TRANSFER`` (double support that moves the ZMP
    onto the first stance foot) → ``SINGLE`` support (the other foot swings) ↔ ``DOUBLE`` support
    after each touch-down."""

    STAND = "stand"
    TRANSFER = "transfer"
    SINGLE = "single"
    DOUBLE = "double"

    @property
    def stepping(self) -> bool:
        """A step is under way (single support, or the double support between two steps)."""
        return self in (GaitPhase.SINGLE, GaitPhase.DOUBLE)


@dataclass(frozen=True)
class SolePlan:
    """A sole's planned pose and velocity (world frame; the sole frame's origin, z = 0 on the floor)."""

    position: np.ndarray  # (3,) [m]
    yaw: float  # [rad]
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # (3,) [m/s]
    yaw_rate: float = 0.0  # [rad/s]


@dataclass(frozen=True)
class WalkReference:
    """The walking plan at one control instant (world frame)."""

    t: float  # [s]
    com: np.ndarray  # (2,) [m]
    com_velocity: np.ndarray  # (2,) [m/s]
    com_acceleration: np.ndarray  # (2,) [m/s²]
    zmp: np.ndarray  # (2,) ZMP of the cart-table model [m]
    feet: dict[Side, SolePlan]  # side -> the sole's plan
    in_contact: dict[Side, bool]
    phase: GaitPhase


@dataclass(frozen=True)
class PreviewSample:
    """The plan at one horizon sample (world frame)."""

    t: float  # [s] after the start of the solved sample (physical time)
    com: np.ndarray  # (2,) [m]
    zmp: np.ndarray  # (2,) cart-table ZMP [m]
    feet: dict[Side, SolePlan]  # side -> the sole's pose (its velocity is not previewed)
    single_support: bool


@dataclass(frozen=True)
class PlanPreview:
    """The plan the MPC just solved, at its horizon's sample boundaries: what the dynamic filter
    corrects. ``samples[j]`` is ``j`` samples after ``t0``."""

    t0: float  # [s] start of the solved sample (controller time)
    sample_duration: float  # [s] physical duration of one sample
    samples: tuple[PreviewSample, ...]

    def __reduce__(self):
        # Pickled as five arrays rather than as dataclasses holding a hundred small arrays, which cost
        # several times as much to pickle and unpickle: the dynamic filter's worker gets a plan every sample.
        if not all(tuple(sample.feet) in _SIDE_ORDERS for sample in self.samples):
            return PlanPreview, (self.t0, self.sample_duration, self.samples)
        soles = [sample.feet[side] for sample in self.samples for side in SIDES]
        feet = np.hstack([np.array([sole.position for sole in soles]), np.array([[sole.yaw] for sole in soles]),
                          np.array([sole.velocity for sole in soles]), np.array([[sole.yaw_rate] for sole in soles])])
        arrays = (np.array([sample.t for sample in self.samples]), np.array([sample.com for sample in self.samples]),
                  np.array([sample.zmp for sample in self.samples]), feet.reshape(len(self.samples), len(SIDES), 8),
                  np.array([sample.single_support for sample in self.samples]))
        return _preview_from_arrays, (self.t0, self.sample_duration, *arrays)


_SIDE_ORDERS = (SIDES, SIDES[::-1])


def _preview_from_arrays(t0: float, sample_duration: float, t: np.ndarray, com: np.ndarray, zmp: np.ndarray,
                         feet: np.ndarray, single_support: np.ndarray) -> PlanPreview:
    """The :class:`PlanPreview` that ``PlanPreview.__reduce__`` packed: ``feet`` (samples, side,
    [x, y, z, yaw, vx, vy, vz, yaw rate]) in the order left, right."""
    return PlanPreview(t0, sample_duration, tuple(
        PreviewSample(float(t[j]), com[j], zmp[j],
                      {side: SolePlan(f[:3], float(f[3]), f[4:7], float(f[7])) for side, f in zip(SIDES, feet[j])},
                      bool(single_support[j]))
        for j in range(t.size)))


@dataclass
class Touchdown:
    """A footstep when it lands: the plan's target; the controller adds where the foot really was."""

    t: float  # [s]
    planned: Footstep
    realized: Footstep | None = None
