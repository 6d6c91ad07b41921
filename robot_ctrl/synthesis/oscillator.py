"""Andronov-Hopf oscillators: the leading oscillator that times the synthesis and its followers.

Normal form (thesis eq. 3.16), state ``x = (x1, x2)``, ``r² = x1² + x2²``, frequency ω [rad/s]::

    ẋ1 = (1 − r²) x1 − ω x2
    ẋ2 = (1 − r²) x2 + ω x1

Every nonzero state converges to the unit circle (ṙ = (1 − r²) r), on which the phase
``φ = atan2(x2, x1)`` grows at ω. Followers are coupled to the leader in a star (thesis 3.3.4)::

    ẋ_i = f(x_i) + κ (x_leader − x_i)

which synchronizes them with the leader for any κ > 0 (contraction: the coupling adds −κ to the
symmetric part of a Jacobian whose largest eigenvalue on the cycle is 0; thesis Table 4.1, star).
Integration: classical RK4.
"""

from __future__ import annotations

import numpy as np


def hopf(x: np.ndarray, omega: float | np.ndarray) -> np.ndarray:
    """ẋ for states ``x`` (..., 2); ``omega`` [rad/s] broadcast over the leading axes."""
    out = (1 - np.sum(x * x, axis=-1, keepdims=True)) * x
    out[..., 0] -= omega * x[..., 1]
    out[..., 1] += omega * x[..., 0]
    return out


def star_coupled(x: np.ndarray, omega: float, coupling: float) -> np.ndarray:
    """ẋ of a leader (row 0) and followers (rows 1..) coupled to it with gain ``coupling`` [1/s]."""
    dx = hopf(x, omega)
    dx[1:] += coupling * (x[0] - x[1:])
    return dx


def rk4_step(f, x: np.ndarray, dt: float) -> np.ndarray:
    """One classical Runge-Kutta step of ``ẋ = f(x)``."""
    k1 = f(x)
    k2 = f(x + 0.5 * dt * k1)
    k3 = f(x + 0.5 * dt * k2)
    k4 = f(x + dt * k3)
    return x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def phase(x: np.ndarray) -> np.ndarray:
    """φ = atan2(x2, x1) wrapped into [0, 2π)."""
    return np.mod(np.arctan2(x[..., 1], x[..., 0]), 2 * np.pi)
