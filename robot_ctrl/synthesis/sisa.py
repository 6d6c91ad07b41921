"""Anechoic demixing by Shift Invariant Subspace Analysis (thesis 3.3.3).

Model (eq. 3.8), for N mean-free trajectories sampled at T points over one period::

    X[n, t] = Σ_k W[n, k] S[k, t − τ[n, k]] + η[n, t]        (circular shifts)

and in the frequency domain (eq. 3.9), with ``X̃`` the DFT along t::

    X̃[n, f] = Σ_k W[n, k] S̃[k, f] exp(−2πi f τ[n, k] / T)

The algorithm (thesis, after Mørup et al.): initialize the sources with sinusoidal harmonics and
their weights and delays by regression; then repeat an external cycle of

- an internal cycle alternating the S-update ``S̃_f = (W̃⁽ᶠ⁾)⁺ X̃_f`` per frequency and the W-update
  ``W[n, :] = X̃[n, :] (S̃⁽ⁿ⁾)⁺`` per trajectory (real least squares on the shifted sources),
- the τ-update: for each source, leave it out, fit the others, and take the delay of the largest
  circular cross-correlation between the residual and the left-out source,
- a final W-update;

and finish with a few internal cycles. Quality: ``Q = 1 − ‖X − X̂‖²_F / ‖X‖²_F``.

Not yet here: the thesis's delay clustering (delays shared across the trials of a joint) and the
stepwise estimation with a non-periodic source; the issue on synthesis tracks them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AnechoicMixture:
    sources: np.ndarray  # (K, T)
    weights: np.ndarray  # (N, K)
    delays: np.ndarray  # (N, K) [samples], may be fractional

    def reconstruct(self) -> np.ndarray:
        """X̂ (N, T)."""
        T = self.sources.shape[1]
        shifted = _shifted_spectra(np.fft.rfft(self.sources, axis=1), self.delays, T)  # (N, K, F)
        return np.fft.irfft((self.weights[:, :, None] * shifted).sum(axis=1), n=T, axis=1)


def quality(X: np.ndarray, X_hat: np.ndarray) -> float:
    """Q = 1 − ‖X − X̂‖²_F / ‖X‖²_F."""
    return float(1.0 - np.sum((X - X_hat) ** 2) / np.sum(X**2))


def _shifted_spectra(S_f: np.ndarray, delays: np.ndarray, T: int) -> np.ndarray:
    """S̃[k, f] exp(−2πi f τ[n, k] / T) for every trajectory: (N, K, F)."""
    f = np.arange(S_f.shape[1])
    return S_f[None, :, :] * np.exp(-2j * np.pi * f[None, None, :] * delays[:, :, None] / T)


def sisa(X: np.ndarray, n_sources: int, external: int = 8, internal: int = 4, final: int = 6) -> AnechoicMixture:
    """Fit ``n_sources`` periodic sources to the rows of ``X`` (N, T), mean-free per row (one period)."""
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or not np.all(np.isfinite(X)):
        raise ValueError("X must be a finite (trajectories, samples) array")
    N, T = X.shape
    if not 1 <= n_sources <= T // 2:
        raise ValueError(f"n_sources = {n_sources} must be in [1, {T // 2}]")
    X_f = np.fft.rfft(X, axis=1)
    t = np.arange(T)
    # Initialization: harmonics k = 1..K, weights and delays from the regression on cos and sin.
    S = np.stack([np.cos(2 * np.pi * (k + 1) * t / T) for k in range(n_sources)])
    W = np.zeros((N, n_sources))
    tau = np.zeros((N, n_sources))
    for k in range(n_sources):
        basis = np.stack([np.cos(2 * np.pi * (k + 1) * t / T), np.sin(2 * np.pi * (k + 1) * t / T)], axis=1)
        coef = np.linalg.lstsq(basis, X.T, rcond=None)[0]  # (2, N)
        W[:, k] = np.hypot(coef[0], coef[1])
        tau[:, k] = np.arctan2(coef[1], coef[0]) * T / (2 * np.pi * (k + 1))
    S_f = np.fft.rfft(S, axis=1)

    def internal_cycle(S_f, W):
        for _ in range(internal):
            S_f = _s_update(X_f, W, tau, T)
            W = _w_update(X_f, S_f, tau, T)
        return S_f, W

    for _ in range(external):
        S_f, W = internal_cycle(S_f, W)
        tau = _tau_update(X, S_f, W, tau, T)
        W = _w_update(X_f, S_f, tau, T)
    for _ in range(final):
        S_f = _s_update(X_f, W, tau, T)
        W = _w_update(X_f, S_f, tau, T)
    # Normalize each source to unit RMS (the weights carry the scale).
    S = np.fft.irfft(S_f, n=T, axis=1)
    scale = np.sqrt(np.mean(S**2, axis=1))
    scale[scale == 0] = 1.0
    return AnechoicMixture(S / scale[:, None], W * scale[None, :], tau)


def _s_update(X_f, W, tau, T):
    N, K = W.shape
    F = X_f.shape[1]
    S_f = np.zeros((K, F), dtype=complex)
    for f in range(1, F):  # f = 0 is the mean, removed
        Wf = W * np.exp(-2j * np.pi * f * tau / T)
        S_f[:, f] = np.linalg.lstsq(Wf, X_f[:, f], rcond=None)[0]
    if T % 2 == 0:
        S_f[:, -1] = S_f[:, -1].real  # Nyquist bin of a real signal
    return S_f


def _w_update(X_f, S_f, tau, T):
    shifted = _shifted_spectra(S_f, tau, T)  # (N, K, F)
    W = np.empty(tau.shape)
    weight = np.full(S_f.shape[1], 2.0)  # rfft bins stand for f and −f, except 0 and Nyquist
    weight[0] = 1.0
    if T % 2 == 0:
        weight[-1] = 1.0
    w = np.sqrt(weight)
    for n in range(tau.shape[0]):
        A = shifted[n].T * w[:, None]  # (F, K)
        b = X_f[n] * w
        W[n] = np.linalg.lstsq(np.vstack([A.real, A.imag]), np.concatenate([b.real, b.imag]), rcond=None)[0]
    return W


def _tau_update(X, S_f, W, tau, T):
    N, K = W.shape
    tau = tau.copy()
    S = np.fft.irfft(S_f, n=T, axis=1)
    for n in range(N):
        for k in range(K):
            others = [j for j in range(K) if j != k]
            shifted = np.fft.irfft(_shifted_spectra(S_f[others], tau[n : n + 1, others], T)[0], n=T, axis=1)
            if others:
                coef = np.linalg.lstsq(shifted.T, X[n], rcond=None)[0]
                residual = X[n] - coef @ shifted
            else:
                residual = X[n]
            # Circular cross-correlation c[d] = Σ_t r[t] S_k[t − d]; the best delay maximizes |c|.
            corr = np.fft.irfft(np.fft.rfft(residual) * np.conj(np.fft.rfft(S[k])), n=T)
            tau[n, k] = float(np.argmax(np.abs(corr)))
    return tau
