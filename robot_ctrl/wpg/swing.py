"""SwingTrajectory: the swing foot from lift-off to touch-down, re-targeted smoothly mid-swing.

In the plane and in yaw the foot follows a quintic from its current state ``(p, ṗ, p̈)`` to the
landing point with zero velocity and acceleration; when the MPC moves the landing point, a new
quintic starts from the old one's state, so position, velocity and acceleration stay continuous.
Height is a bump ``z = 16 apex σ²(1 − σ)²`` with ``σ = t / duration``: apex at mid-swing, zero
vertical velocity at lift-off and touch-down. The sole stays flat. World frame, floor z = 0.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from robot_ctrl.geometry import PlanarMove, wrap_angle
from robot_ctrl.wpg.footstep import Footstep


class SwingPoint(NamedTuple):
    """A swinging foot's sole at one instant, world frame."""

    position: np.ndarray  # (3,) [m]
    yaw: float  # [rad]
    velocity: np.ndarray  # (3,) [m/s]
    yaw_rate: float  # [rad/s]


def quintic_coefficients(duration: float, p0: np.ndarray, v0: np.ndarray, a0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Coefficients c (6, d) of ``p(t) = Σ c_k t^k`` with p(0) = p0, ṗ(0) = v0, p̈(0) = a0,
    p(T) = p1, ṗ(T) = p̈(T) = 0."""
    T = duration
    c0, c1, c2 = p0, v0, a0 / 2.0
    # The end conditions on c3, c4, c5, p(T) − (c0 + c1 T + c2 T²) = h, ṗ(T) − (c1 + 2 c2 T) = d,
    # p̈(T) − 2 c2 = e (h, d, e below), solved in closed form.
    h, d, e = p1 - (c0 + c1 * T + c2 * T**2), -(c1 + 2 * c2 * T), -2 * c2
    c3 = (10 * h - 4 * d * T + e * T**2 / 2) / T**3
    c4 = (-15 * h + 7 * d * T - e * T**2) / T**4
    c5 = (6 * h - 3 * d * T + e * T**2 / 2) / T**5
    return np.array([c0, c1, c2, c3, c4, c5])


def _evaluate(c: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    powers = t ** np.arange(6)
    p = powers @ c
    v = (np.arange(1, 6) * powers[:5]) @ c[1:]
    a = (np.arange(2, 6) * np.arange(1, 5) * powers[:4]) @ c[2:]
    return p, v, a


class SwingTrajectory:
    def __init__(self, lift: Footstep, duration: float, apex: float):
        self.lift = lift
        self.landing = lift
        self.duration = duration
        self.apex = apex
        self._t0 = 0.0
        start = np.array([lift.x, lift.y, lift.yaw])
        self._c = quintic_coefficients(duration, start, np.zeros(3), np.zeros(3), start)

    def retarget(self, t: float, landing: Footstep) -> None:
        """Aim at ``landing`` from time ``t`` [s] into the swing, continuing from the current state."""
        if t >= self.duration - 1e-9:
            return
        p, v, a = _evaluate(self._c, t - self._t0)
        yaw = p[2] + wrap_angle(landing.yaw - p[2])
        self._c = quintic_coefficients(self.duration - t, p, v, a, np.array([landing.x, landing.y, yaw]))
        self._t0 = t
        self.landing = landing

    def shift(self, move: PlanarMove) -> None:
        """Move the whole trajectory rigidly in the plane (world frame)."""
        c = self._c.copy()
        c[1:, :2] = move.direction(c[1:, :2])  # the polynomial's higher coefficients turn, ...
        c[0, :2] = move.point(c[0, :2])  # ... its constant one moves
        c[0, 2] += move.turn
        self._c = c
        self.lift = self.lift.moved(move)
        self.landing = self.landing.moved(move)

    def at(self, t: float) -> SwingPoint:
        """The sole at ``t`` seconds into the swing."""
        t = min(max(t, 0.0), self.duration)
        p, v, _ = _evaluate(self._c, t - self._t0)
        sigma = t / self.duration
        z = 16.0 * self.apex * sigma**2 * (1.0 - sigma) ** 2
        dz = 32.0 * self.apex * sigma * (1.0 - sigma) * (1.0 - 2.0 * sigma) / self.duration
        return SwingPoint(np.array([p[0], p[1], z]), float(p[2]), np.array([v[0], v[1], dz]), float(v[2]))
