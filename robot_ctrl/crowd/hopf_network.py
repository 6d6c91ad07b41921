"""HopfNetwork: Andronov-Hopf oscillators with diffusive coupling, many runs at once (thesis 4.3).

Each agent i has the state ``x_i = (x, y)`` with ``ẋ_i = f(x_i) + k Σ_j A_ij (x_j − x_i)`` and
``f`` the Andronov-Hopf oscillator of eq. 4.14 (limit cycle r = 1, frequency ω). Integrated with
RK4 for ``runs`` independent initial conditions in one vectorized array (runs, N, 2).
"""

from __future__ import annotations

import numpy as np

from robot_ctrl.crowd.coupling_graph import CouplingGraph


def hopf_field(state: np.ndarray, omega: float) -> np.ndarray:
    """f(x) of eq. 4.14 for states (..., 2)."""
    x, y = state[..., 0], state[..., 1]
    radial = 1.0 - (x * x + y * y)
    return np.stack([radial * x - omega * y, radial * y + omega * x], axis=-1)


def simulate(graph: CouplingGraph, k: float, duration: float, dt: float | None = None, omega: float = 2 * np.pi,
             runs: int = 100, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Phases (steps + 1, runs, N) and times (steps + 1,) of coupled oscillators from random states:
    phases uniform on the circle, radii uniform in [0.5, 1.5]. Without ``dt`` the step is
    ``min(0.01, 1 / (|k| λ_max + ω + 2))`` s, inside RK4's stability region for the coupling."""
    if dt is None:
        dt = min(0.01, 1.0 / (abs(k) * graph.lambda_max + omega + 2.0))
    rng = np.random.default_rng(seed)
    n = graph.n
    radius = rng.uniform(0.5, 1.5, (runs, n))
    angle = rng.uniform(-np.pi, np.pi, (runs, n))
    state = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)
    L = graph.laplacian

    def rate(s):
        return hopf_field(s, omega) - k * np.einsum("ij,rjc->ric", L, s)

    steps = int(round(duration / dt))
    phases = np.empty((steps + 1, runs, n))
    phases[0] = np.arctan2(state[..., 1], state[..., 0])
    for i in range(steps):
        k1 = rate(state)
        k2 = rate(state + 0.5 * dt * k1)
        k3 = rate(state + 0.5 * dt * k2)
        k4 = rate(state + dt * k3)
        state = state + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        phases[i + 1] = np.arctan2(state[..., 1], state[..., 0])
    return phases, np.arange(steps + 1) * dt
