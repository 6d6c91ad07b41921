"""Minimum-jerk interpolation (Flash & Hogan 1985): bell-shaped velocity, zero velocity and
acceleration at both ends."""

from __future__ import annotations

import numpy as np


def minimum_jerk(t: float, duration: float) -> tuple[float, float]:
    """Progress ``s(t) = 10τ³ − 15τ⁴ + 6τ⁵`` with ``τ = t / T`` clipped to [0, 1], and ``ds/dt`` [1/s]."""
    tau = min(max(t / duration, 0.0), 1.0)
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    ds = 30.0 * tau**2 * (1.0 - tau) ** 2 / duration
    return s, ds


def interpolate(start: np.ndarray, end: np.ndarray, t: float, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-jerk point between ``start`` and ``end``: position and velocity at time ``t``."""
    s, ds = minimum_jerk(t, duration)
    delta = np.asarray(end) - np.asarray(start)
    return start + s * delta, ds * delta
