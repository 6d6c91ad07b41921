"""Linear inverted pendulum (cart-table model) with piecewise-constant CoM jerk.

Per horizontal axis the state is ``x̂ = [x, ẋ, ẍ]`` (world frame, m, m/s, m/s²). Over one
sample of length T with jerk ``u``::

    x̂⁺ = A(T) x̂ + B(T) u,   A = [[1, T, T²/2], [0, 1, T], [0, 0, 1]],   B = [T³/6, T²/2, T]

and the ZMP of the cart-table model at constant CoM height h is ``z = x − (h/g) ẍ``.
Over a horizon of N samples (Kajita 2003, Wieber 2006) the stacked positions, velocities and
ZMPs are affine in the jerks ``U = [u_0 … u_{N−1}]``::

    X = Pps x̂ + Ppu U,   Ẋ = Pvs x̂ + Pvu U,   Z = Pzs x̂ + Pzu U
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.geometry import GRAVITY


def transition(T: float) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` of one jerk-driven sample of length ``T`` [s]."""
    A = np.array([[1.0, T, T * T / 2.0], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    B = np.array([T**3 / 6.0, T * T / 2.0, T])
    return A, B


@dataclass(frozen=True)
class HorizonMatrices:
    """Condensed prediction matrices over N samples (rows are samples 1..N)."""

    Pps: np.ndarray
    Ppu: np.ndarray
    Pvs: np.ndarray
    Pvu: np.ndarray
    Pzs: np.ndarray
    Pzu: np.ndarray


def horizon_matrices(T: float, N: int, com_height: float, g: float = GRAVITY) -> HorizonMatrices:
    A, B = transition(T)
    zmp_row = np.array([1.0, 0.0, -com_height / g])
    S = np.zeros((N, 3, 3))  # A^j, j = 1..N
    U = np.zeros((N, N, 3))  # contribution of u_i to the state at sample j: A^(j−i) B
    AkB = np.zeros((N, 3))  # A^k B, k = 0..N−1
    power = np.eye(3)
    for j in range(N):
        AkB[j] = power @ B
        power = A @ power
        S[j] = power
    for j in range(N):
        U[j, : j + 1] = AkB[j::-1]
    # Contiguous copies: the walking MPC's compiled assembly takes them as they are.
    return HorizonMatrices(*(np.ascontiguousarray(P) for P in (
        S[:, 0, :], U[:, :, 0], S[:, 1, :], U[:, :, 1], np.einsum("k,jkl->jl", zmp_row, S), U @ zmp_row)))


def natural_frequency(com_height: float, g: float = GRAVITY) -> float:
    """``ω = sqrt(g / h)`` [1/s] of the pendulum at constant CoM height ``h`` [m]."""
    return float(np.sqrt(g / com_height))


def dcm(com: np.ndarray, com_velocity: np.ndarray, omega: float) -> np.ndarray:
    """Divergent component of motion ``ξ = c + ċ/ω`` [m] of the CoM position ``c`` and velocity
    ``ċ`` (same frame), ``ω = sqrt(g / h)``."""
    return np.asarray(com) + np.asarray(com_velocity) / omega


def com_at(state: np.ndarray, jerk: float, tau: float) -> np.ndarray:
    """State ``[x, ẋ, ẍ]`` at time ``tau`` into a sample with constant ``jerk``."""
    x, v, a = state.tolist()
    j, t2 = float(jerk), tau * tau / 2.0
    # A(tau) x̂ + B(tau) u written out: it runs on every control tick (WalkingPatternGenerator.sample).
    return np.array([x + tau * v + t2 * a + tau**3 / 6.0 * j, v + tau * a + t2 * j, a + tau * j])
