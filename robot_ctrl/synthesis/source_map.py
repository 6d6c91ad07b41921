"""Learned maps from the oscillator's phase plane to source values (thesis eqs. 3.14-3.15).

A periodic source ``s(t)`` sampled at ``T`` points over one period is associated with the points
``c_j = (cos 2πj/T, sin 2πj/T)`` of the oscillator's limit cycle (the unit circle: the Hopf cycle
is already circular, so the scaling Θ of eq. 3.15 is the identity). The map is RBF kernel
(ridge) regression::

    f(z) = Σ_j a_j exp(−‖z − c_j‖² / (2σ²)),     a = (K + λI)⁻¹ s,  K_ij = exp(−‖c_i − c_j‖² / (2σ²))

A delay τ (in samples) becomes a rotation of the state by ``φ = −2π τ / T`` (eq. 3.15), so
``s(t − τ) ≈ f(R(φ) x(t))`` with no delay line. The thesis uses support vector regression with a
Gaussian kernel; kernel ridge regression is the same model class with a closed-form fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_ctrl.kernels import FLOAT, FORTRAN_MATRIX, MATRIX, kernel


@dataclass(frozen=True)
class SourceMap:
    centers: np.ndarray  # (M, 2) points on the unit circle
    coefficients: np.ndarray  # (K, M), one row per source
    sigma: float

    @classmethod
    def fit(cls, sources: np.ndarray, width: float = 1.5, ridge: float = 1e-6) -> "SourceMap":
        """Fit every row of ``sources`` (K, T): samples over one period."""
        T = sources.shape[1]
        angles = 2 * np.pi * np.arange(T) / T
        centers = np.stack([np.cos(angles), np.sin(angles)], axis=1)
        sigma = width * 2 * np.sin(np.pi / T)  # a few times the spacing of the centers
        K = _kernel(centers, centers, sigma)
        coefficients = np.linalg.solve(K + ridge * np.eye(T), sources.T).T
        return cls(centers, coefficients, sigma)

    def __call__(self, z: np.ndarray) -> np.ndarray:
        """Values (..., K) at phase-plane points ``z`` (..., 2)."""
        return _kernel(z, self.centers, self.sigma) @ self.coefficients.T

    def delayed(self, x: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        """``s_k(t − τ_nk)`` for every channel n and source k: rotate the oscillator states ``x``
        (K, 2), one per source, by ``rotations`` (N, K) [rad] and evaluate source k: (N, K)."""
        return _delayed(np.asarray(x, dtype=float), np.asarray(rotations, dtype=float), self.centers,
                        self.coefficients, self.sigma)


@kernel((MATRIX, MATRIX, MATRIX, FORTRAN_MATRIX, FLOAT))
def _delayed(x, rotations, centers, coefficients, sigma):
    """:meth:`SourceMap.delayed`, compiled: the synthesis evaluates it on every control tick and
    through every preview, N × K × M kernel terms.

    The centers c_j lie on the unit circle: with ψ = θ + φ the rotated state's angle and r its
    radius, −‖R(φ)x − c_j‖² / 2σ² = (r / σ²) (cos ψ, sin ψ)·c_j − (r² + 1) / 2σ², one trigonometric
    pair per (channel, source) rather than a cosine per center."""
    n_channels, n_sources = rotations.shape
    out = np.empty((n_channels, n_sources))
    inverse = 1.0 / (sigma * sigma)
    for k in range(n_sources):
        r = math.hypot(x[k, 0], x[k, 1])
        theta, scale, offset = math.atan2(x[k, 1], x[k, 0]), r * inverse, (r * r + 1.0) * 0.5 * inverse
        for n in range(n_channels):
            psi = theta + rotations[n, k]
            a, b = math.cos(psi) * scale, math.sin(psi) * scale
            total = 0.0
            for j in range(centers.shape[0]):
                total += math.exp(a * centers[j, 0] + b * centers[j, 1] - offset) * coefficients[k, j]
            out[n, k] = total
    return out


def delay_rotations(delays: np.ndarray, T: int) -> np.ndarray:
    """φ = −2π τ / T [rad] for delays in samples of a period of T samples."""
    return -2 * np.pi * np.asarray(delays) / T


def _kernel(a: np.ndarray, b: np.ndarray, sigma: float) -> np.ndarray:
    d2 = ((a[..., :, None, :] - b[None, :, :]) ** 2).sum(axis=-1)
    return np.exp(-d2 / (2 * sigma**2))
