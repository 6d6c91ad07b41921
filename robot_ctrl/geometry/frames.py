"""Planar frames on the floor: headings, 2D rotations, the two sides of a biped, gravity.

Right-handed world frame, z up; a heading (yaw) is the angle of a frame's x axis projected on the
floor, counter-clockwise from the world x axis [rad].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

#: A side of a biped (a foot, a hand, a gripper). Plain strings, so that they name MuJoCo bodies,
#: config keys and report fields as they are.
Side = Literal["left", "right"]
SIDES: tuple[Side, Side] = ("left", "right")
GRAVITY = 9.81  # [m/s²], magnitude, along −z


def other(side: Side) -> Side:
    """The other side: ``other("left") == "right"``."""
    return "right" if side == "left" else "left"


def left_sign(side: Side) -> float:
    """+1 for the left side, −1 for the right: the sign of its lateral (y) offset in the body frame."""
    return 1.0 if side == "left" else -1.0


def wrap_angle(angle: float) -> float:
    """``angle`` [rad] wrapped to (−π, π]."""
    return float(np.arctan2(np.sin(angle), np.cos(angle)))


def mean_yaw(yaws) -> float:
    """Circular mean of headings [rad]: ``atan2(Σ sin ψ, Σ cos ψ)`` (the feet's mean heading). In
    floats: it runs a few times a tick on two headings, where numpy's calls cost more than the sums."""
    s = c = 0.0
    for yaw in yaws:
        s, c = s + math.sin(yaw), c + math.cos(yaw)
    return math.atan2(s, c)


def yaw_of(rotation_matrix: np.ndarray) -> float:
    """Heading [rad] of a 3×3 rotation (its x axis projected on the floor)."""
    return float(np.arctan2(rotation_matrix[1, 0], rotation_matrix[0, 0]))


def rotation(yaw: float) -> np.ndarray:
    """2×2 rotation by ``yaw`` [rad]: ``R(ψ) = [[cos ψ, −sin ψ], [sin ψ, cos ψ]]``."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class PlanarMove:
    """A rigid move of the floor plane: a turn by ``turn`` [rad] about ``pivot`` (2,) [m], then a
    translation by ``delta`` (2,) [m], world frame: ``p' = pivot + R(turn) (p − pivot) + delta``;
    directions (velocities) turn, ``v' = R(turn) v``; headings add, ``ψ' = ψ + turn``."""

    delta: np.ndarray = field(default_factory=lambda: np.zeros(2))
    turn: float = 0.0
    pivot: np.ndarray = field(default_factory=lambda: np.zeros(2))

    @property
    def R(self) -> np.ndarray:
        return rotation(self.turn)

    def point(self, p: np.ndarray) -> np.ndarray:
        """Moved point(s) ``p`` (..., 2)."""
        return self.pivot + (np.asarray(p) - self.pivot) @ self.R.T + self.delta

    def direction(self, v: np.ndarray) -> np.ndarray:
        """Turned vector(s) ``v`` (..., 2): velocities, accelerations, polynomial coefficients."""
        return np.asarray(v) @ self.R.T


def relative_pose(pose: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Planar ``pose`` (x, y, yaw), world frame, expressed in the frame of ``origin`` (x, y, yaw):
    ``(R(ψ₀)ᵀ (p − p₀), wrap(ψ − ψ₀))``."""
    xy = rotation(origin[2]).T @ (np.asarray(pose[:2]) - origin[:2])
    return np.array([xy[0], xy[1], wrap_angle(pose[2] - origin[2])])


def absolute_pose(local: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Planar pose ``local`` (x, y, yaw) of the frame ``origin`` (x, y, yaw) in the world, the inverse of
    :func:`relative_pose`: ``(p₀ + R(ψ₀) p, ψ₀ + ψ)``."""
    return np.array([*(np.asarray(origin[:2]) + rotation(origin[2]) @ np.asarray(local[:2])), origin[2] + local[2]])


def base_pose_xy_yaw(base_pos: np.ndarray, base_quat_xyzw: np.ndarray) -> np.ndarray:
    """Planar pose (x, y, yaw) of a base from its world position and quaternion (x, y, z, w)."""
    x, y, z, w = np.asarray(base_quat_xyzw, dtype=float).tolist()  # floats: numpy's scalars cost more per operation
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.array([base_pos[0], base_pos[1], yaw])
