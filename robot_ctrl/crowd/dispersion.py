"""Angular dispersion and the empirical convergence rate (thesis 4.3.6).

``R̂ = (1 − |Σ_j exp(i φ_j)| / N)^½`` measures how far the phases are from synchrony; averaged
over runs with random initial conditions it decays as ``exp(−λ t)`` after an offset time. The
empirical rate λ is minus the slope of ``log R̂`` fitted by least squares over the decay regime.
"""

from __future__ import annotations

import numpy as np


def angular_dispersion(phases: np.ndarray) -> np.ndarray:
    """R̂ over the last axis (agents) of ``phases`` [rad]."""
    mean = np.abs(np.exp(1j * phases).mean(axis=-1))
    return np.sqrt(np.clip(1.0 - mean, 0.0, None))


def empirical_rate(times: np.ndarray, dispersion: np.ndarray, upper: float = 0.1, lower: float = 1e-5) -> float | None:
    """−d log R̂/dt fitted where ``lower < R̂ < upper`` (the exponential regime, below the offset
    plateau and above numerical precision); None if fewer than 10 samples fall there."""
    window = (dispersion < upper) & (dispersion > lower)
    if window.sum() < 10:
        return None
    slope = np.polyfit(times[window], np.log(dispersion[window]), 1)[0]
    return float(-slope)
