"""Stepwise estimation of the walk-and-reach mixture model (thesis 3.3.3, Fig. 3.12).

Each action of each trial is resampled to ``T + 1`` points over its duration (both boundaries) and
modelled per channel ``n`` as::

    x_n(t) = m_n + w0_n s0(t) + Σ_k W[n, k] s_k(t − τ[n, k]),    s0(t) = cos(π t / T),  t = 0..T

1. Non-periodic part: ``w0 = (x(0) − x(T)) / 2`` makes the residual ``x − w0 s0`` take equal values
   at both ends, i.e. periodic; ``m`` is its mean. What is left is one period for SISA.
2. Action 1: SISA with ``n_first`` periodic sources, delays clustered per channel (equal for a
   joint across all trials).
3. Actions 2 and 3: the first sources keep their delays; their weights are re-estimated, their
   contribution is subtracted, and ``n_extra`` more sources are learned from the residuals of both
   actions (delays again one per channel, shared by actions 2 and 3).
4. Final weights per action and trial: action 1 with the first sources, actions 2 and 3 with all.

The delays do not depend on the action or the trial, so online blending only has to morph the
weights and means (thesis 3.4.1). ``quality_table`` compares the per-action approximation quality
with PCA at the same number of temporal sources.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.synthesis.demonstrations import DemonstrationSet
from robot_ctrl.synthesis.sisa import AnechoicMixture, fit_weights, quality, sisa

N_ACTIONS = 3


def nonperiodic_source(T: int) -> np.ndarray:
    """s0(t) = cos(π t / T), t = 0..T: 1 at the start of an action, −1 at its end."""
    return np.cos(np.pi * np.arange(T + 1) / T)


def resample_actions(demos: DemonstrationSet, T: int) -> np.ndarray:
    """(actions, trials, channels, T + 1): every action on a normalized time grid."""
    out = np.empty((N_ACTIONS, len(demos.trials), len(demos.channels), T + 1))
    grid = np.linspace(0.0, 1.0, T + 1)
    for i, trial in enumerate(demos.trials):
        for a in range(N_ACTIONS):
            x = trial.action(a)
            src = np.linspace(0.0, 1.0, len(x))
            out[a, i] = np.array([np.interp(grid, src, x[:, c]) for c in range(x.shape[1])])
    return out


@dataclass(frozen=True)
class StepwiseModel:
    """Sources and delays shared by all actions, weights and means per action and trial."""

    sources: np.ndarray  # (K, T) unit RMS; the first ``n_first`` serve every action
    delays: np.ndarray  # (channels, K) [samples of T]
    n_first: int
    means: np.ndarray  # (actions, trials, channels)
    w0: np.ndarray  # (actions, trials, channels) non-periodic weights
    weights: np.ndarray  # (actions, trials, channels, K); zero for the extra sources in action 1

    @property
    def T(self) -> int:
        return self.sources.shape[1]

    def reconstruct(self, action: int) -> np.ndarray:
        """(trials, channels, T + 1) model trajectories of one action."""
        n_trials, C = self.means.shape[1:]
        mix = AnechoicMixture(self.sources, self.weights[action].reshape(-1, self.sources.shape[0]),
                              np.tile(self.delays, (n_trials, 1)))
        periodic = mix.reconstruct().reshape(n_trials, C, self.T)
        periodic = np.concatenate([periodic, periodic[..., :1]], axis=-1)
        return self.means[action][..., None] + self.w0[action][..., None] * nonperiodic_source(self.T) + periodic


def learn_stepwise(X: np.ndarray, n_first: int = 3, n_extra: int = 2) -> StepwiseModel:
    """Fit the model to ``X`` (actions, trials, channels, T + 1) from :func:`resample_actions`."""
    n_actions, n_trials, C, T1 = X.shape
    T = T1 - 1
    w0 = (X[..., 0] - X[..., -1]) / 2
    residual = X - w0[..., None] * nonperiodic_source(T)
    periodic = residual[..., :T]
    means = periodic.mean(axis=-1)
    P = (periodic - means[..., None]).reshape(n_actions, n_trials * C, T)
    groups = np.tile(np.arange(C), n_trials)

    first = sisa(P[0], n_first, groups=groups)
    tau_first = first.delays[:C]
    later = []
    for a in (1, 2):
        W = fit_weights(P[a], first.sources, first.delays)
        later.append(P[a] - AnechoicMixture(first.sources, W, first.delays).reconstruct())
    extra = sisa(np.concatenate(later), n_extra, groups=np.tile(groups, 2))
    sources = np.concatenate([first.sources, extra.sources])
    delays = np.concatenate([tau_first, extra.delays[:C]], axis=1)
    K = n_first + n_extra
    weights = np.zeros((n_actions, n_trials * C, K))
    weights[0, :, :n_first] = fit_weights(P[0], first.sources, first.delays)
    for a in (1, 2):
        weights[a] = fit_weights(P[a], sources, np.tile(delays, (n_trials, 1)))
    return StepwiseModel(sources, delays, n_first, means, w0, weights.reshape(n_actions, n_trials, C, K))


def _pca_quality(X: np.ndarray) -> np.ndarray:
    """Q of the best rank-n approximation of X (rows = trajectories, columns = time) for n = 1, 2, ...:
    ``1 − Σ_{i>n} σ_i² / Σ σ_i²`` (Eckart-Young)."""
    energy = np.linalg.svd(X, compute_uv=False) ** 2
    return 1.0 - (energy.sum() - np.cumsum(energy)) / energy.sum()


def quality_table(X: np.ndarray, model: StepwiseModel) -> list[dict]:
    """Per action: Q of the model and of PCA with the same number of temporal sources (s0 counted),
    and the number of PCA components needed to match the model. Trajectories are made mean-free
    per row over the action's samples 0..T-1 (Q measures how the model explains the motion, not
    the offsets)."""
    rows = []
    for a in range(X.shape[0]):
        Xa = X[a][..., :-1].reshape(-1, model.T)
        Xh = model.reconstruct(a)[..., :-1].reshape(-1, model.T)
        mean = Xa.mean(axis=1, keepdims=True)
        q = quality(Xa - mean, Xh - mean)
        n = 1 + (model.n_first if a == 0 else model.sources.shape[0])
        pca = _pca_quality(Xa - mean)
        needed = 1 + int(np.argmax(pca >= q)) if pca[-1] >= q else model.T
        rows.append({"action": a + 1, "sources": n, "Q_anechoic": q, "Q_pca": pca[n - 1], "pca_needed": needed})
    return rows
