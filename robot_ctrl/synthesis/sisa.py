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

Delay clustering (optional, ``groups``): rows with the same group label (e.g. the trials of one
joint angle) share one delay per source. The thesis clusters the rows' own delays after each
τ-update (1-D PCA of the points ``±exp(2πi f τ / T)``, f the dominant harmonic). We choose the shared
delay directly instead: the one maximizing ``Σ_n c_n[d]²`` over the group, where ``c_n`` is row n's
cross-correlation above; with free per-row weights that is the least-squares optimum. Reason: on
synthetic mixtures whose delays truly are shared, the circular averaging lost 3-15 % of Q
(the half-period ambiguity is only a sign flip for a pure harmonic), the joint choice loses nothing.
The stepwise estimation with a non-periodic source is :mod:`robot_ctrl.synthesis.stepwise`.
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


def sisa(X: np.ndarray, n_sources: int, groups: np.ndarray | None = None, external: int = 8, internal: int = 4,
         final: int = 6) -> AnechoicMixture:
    """Fit ``n_sources`` periodic sources to the rows of ``X`` (N, T), mean-free per row (one period).
    ``groups`` (N,) integer labels: rows with equal labels share their delays (delay clustering)."""
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
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (N,):
            raise ValueError(f"groups must have one label per row of X ({N}), got shape {groups.shape}")

    def internal_cycle(S_f, W):
        for _ in range(internal):
            S_f = _s_update(X_f, W, tau, T)
            W = _w_update(X_f, S_f, tau, T)
        return S_f, W

    for _ in range(external):
        S_f, W = internal_cycle(S_f, W)
        tau = _tau_update(X, S_f, W, tau, T, groups)
        W = _w_update(X_f, S_f, tau, T)
    for _ in range(final):
        S_f = _s_update(X_f, W, tau, T)
        W = _w_update(X_f, S_f, tau, T)
    # Normalize each source to unit RMS (the weights carry the scale).
    S = np.fft.irfft(S_f, n=T, axis=1)
    scale = np.sqrt(np.mean(S**2, axis=1))
    scale[scale == 0] = 1.0
    return AnechoicMixture(S / scale[:, None], W * scale[None, :], tau)


def fit_weights(X: np.ndarray, sources: np.ndarray, delays: np.ndarray) -> np.ndarray:
    """Least-squares weights (N, K) of fixed ``sources`` (K, T) shifted by ``delays`` (N, K) for the rows of X."""
    T = X.shape[1]
    return _w_update(np.fft.rfft(X, axis=1), np.fft.rfft(sources, axis=1), delays, T)


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


def _tau_update(X, S_f, W, tau, T, groups=None):
    N, K = W.shape
    tau = tau.copy()
    S = np.fft.irfft(S_f, n=T, axis=1)
    for k in range(K):
        others = [j for j in range(K) if j != k]
        corr = np.empty((N, T))
        for n in range(N):
            if others:
                shifted = np.fft.irfft(_shifted_spectra(S_f[others], tau[n : n + 1, others], T)[0], n=T, axis=1)
                coef = np.linalg.lstsq(shifted.T, X[n], rcond=None)[0]
                residual = X[n] - coef @ shifted
            else:
                residual = X[n]
            # Circular cross-correlation c[d] = Σ_t r[t] S_k[t − d]; the best delay maximizes |c|.
            corr[n] = np.fft.irfft(np.fft.rfft(residual) * np.conj(np.fft.rfft(S[k])), n=T)
        if groups is None:
            tau[:, k] = np.argmax(np.abs(corr), axis=1)
        else:  # one delay per group: the largest error reduction Σ_n c_n[d]² with free per-row weights
            for g in np.unique(groups):
                rows = groups == g
                tau[rows, k] = float(np.argmax(np.sum(corr[rows] ** 2, axis=0)))
    return tau
