"""Andronov-Hopf oscillators: the leading oscillator that times the synthesis and its followers.

Normal form (thesis eq. 3.16), state ``x = (x1, x2)``, ``r² = x1² + x2²``, frequency ω [rad/s]::

    ẋ1 = (1 − r²) x1 − ω x2
    ẋ2 = (1 − r²) x2 + ω x1

Every nonzero state converges to the unit circle (ṙ = (1 − r²) r), on which the phase
``φ = atan2(x2, x1)`` grows at ω. Followers are coupled to the leader in a star (thesis 3.3.4)::

    ẋ_i = f(x_i) + κ (x_leader − x_i)

which synchronizes them with the leader for any κ > 0 (contraction: the coupling adds −κ to the
symmetric part of a Jacobian whose largest eigenvalue on the cycle is 0; thesis Table 4.1, star).
Integration: classical RK4. Compiled (numba): the synthesis steps its oscillators on every control
tick and through every preview, where numpy's per-call cost on a (6, 2) state is most of the work.
"""

from __future__ import annotations

import numpy as np

from robot_ctrl.kernels import FLOAT, MATRIX, kernel


@kernel()
def hopf(x: np.ndarray, omega: float) -> np.ndarray:
    """ẋ for states ``x`` (n, 2), each an oscillator of frequency ``omega`` [rad/s]."""
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        x1, x2 = x[i, 0], x[i, 1]
        g = 1.0 - (x1 * x1 + x2 * x2)
        out[i, 0] = g * x1 - omega * x2
        out[i, 1] = g * x2 + omega * x1
    return out


@kernel()
def star_coupled(x: np.ndarray, omega: float, coupling: float) -> np.ndarray:
    """ẋ of a leader (row 0) and followers (rows 1..) coupled to it with gain ``coupling`` [1/s]."""
    dx = hopf(x, omega)
    for i in range(1, x.shape[0]):
        dx[i, 0] += coupling * (x[0, 0] - x[i, 0])
        dx[i, 1] += coupling * (x[0, 1] - x[i, 1])
    return dx


@kernel((MATRIX, FLOAT, FLOAT, FLOAT))
def star_step(x: np.ndarray, omega: float, coupling: float, dt: float) -> np.ndarray:
    """One classical Runge-Kutta step of ``ẋ = star_coupled(x, omega, coupling)`` over ``dt`` [s]."""
    k1 = star_coupled(x, omega, coupling)
    k2 = star_coupled(x + 0.5 * dt * k1, omega, coupling)
    k3 = star_coupled(x + 0.5 * dt * k2, omega, coupling)
    k4 = star_coupled(x + dt * k3, omega, coupling)
    return x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def phase(x: np.ndarray) -> np.ndarray:
    """φ = atan2(x2, x1) wrapped into [0, 2π)."""
    return np.mod(np.arctan2(x[..., 1], x[..., 0]), 2 * np.pi)
