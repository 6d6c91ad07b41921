"""Footstep and FootRef: where a foot is, or will be as an affine function of the MPC's footstep
variables ``F = [F1x, F1y, F2x, F2y]`` (world frame, m)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.geometry import SIDES, PlanarMove, Side, left_sign, other, rotation


@dataclass(frozen=True)
class Footstep:
    """A sole frame on the floor: position (x, y) [m] and yaw [rad] in the world frame."""

    side: Side
    x: float
    y: float
    yaw: float

    @property
    def xy(self) -> np.ndarray:
        return np.array([self.x, self.y])

    def moved(self, move: PlanarMove) -> "Footstep":
        """This footstep moved rigidly in the plane (world frame)."""
        x, y = move.point(self.xy)
        return Footstep(self.side, float(x), float(y), self.yaw + move.turn)


def stance_at(pose, feet_offset: dict[Side, np.ndarray]) -> tuple[Footstep, ...]:
    """Both feet (in ``SIDES`` order) round the planar ``pose`` (x, y, yaw; world), each at its
    ``feet_offset`` (x, y) [m] in the pose's frame, turned as the pose is: where a robot stops."""
    return tuple(Footstep(s, *(pose[:2] + rotation(pose[2]) @ feet_offset[s]), float(pose[2])) for s in SIDES)


@dataclass(frozen=True)
class FootRef:
    """A foot whose position is ``offset + S F`` (S: 2×4 selection of the footstep variables)."""

    side: Side
    yaw: float
    offset: np.ndarray  # (2,)
    S: np.ndarray  # (2, 4)

    @classmethod
    def known(cls, step: Footstep) -> "FootRef":
        return cls(step.side, step.yaw, step.xy, np.zeros((2, 4)))

    @classmethod
    def variable(cls, index: int, side: Side, yaw: float) -> "FootRef":
        S = np.zeros((2, 4))
        S[0, 2 * index] = S[1, 2 * index + 1] = 1.0
        return cls(side, yaw, np.zeros(2), S)

    def beside(self, width: float) -> "FootRef":
        """The other foot placed parallel to this one, ``width`` apart (feet side by side)."""
        sign = -left_sign(self.side)
        return FootRef(other(self.side), self.yaw, self.offset + rotation(self.yaw) @ [0.0, sign * width], self.S)

    def position(self, F: np.ndarray) -> np.ndarray:
        return self.offset + self.S @ F

    def step(self, F: np.ndarray) -> Footstep:
        x, y = self.position(F)
        return Footstep(self.side, float(x), float(y), self.yaw)
