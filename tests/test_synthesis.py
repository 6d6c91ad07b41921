"""Anechoic demixing (SISA, thesis 3.3.3) on synthetic mixtures with known sources and delays."""

import numpy as np
import pytest

from robot_ctrl.synthesis.sisa import AnechoicMixture, quality, sisa

T = 100


def synthetic(rng, n_sources=3, joints=6, trials=4, noise=0.01):
    t = np.arange(T)

    def source():
        s = sum(rng.normal() / h * np.cos(2 * np.pi * h * t / T + rng.uniform(0, 2 * np.pi)) for h in range(1, 5))
        return (s - s.mean()) / s.std()

    S = np.stack([source() for _ in range(n_sources)])
    delays = rng.integers(0, T, (joints, n_sources))  # per joint, fixed across trials
    rows = []
    for _ in range(trials):
        for j in range(joints):
            w = rng.uniform(0.5, 2.0, n_sources) * rng.choice([-1, 1], n_sources)
            rows.append(sum(w[k] * np.roll(S[k], delays[j, k]) for k in range(n_sources)))
    X = np.array(rows)
    return X - X.mean(axis=1, keepdims=True) + noise * rng.normal(size=X.shape), S


def test_reconstruction_applies_weights_and_circular_delays():
    rng = np.random.default_rng(3)
    S = rng.normal(size=(2, T))
    mixture = AnechoicMixture(S, np.array([[1.0, -2.0]]), np.array([[5.0, 17.0]]))
    np.testing.assert_allclose(mixture.reconstruct()[0], np.roll(S[0], 5) - 2.0 * np.roll(S[1], 17), atol=1e-9)


def test_sisa_fits_an_anechoic_mixture_far_better_than_pca():
    X, S = synthetic(np.random.default_rng(0))
    model = sisa(X, 3)
    q = quality(X, model.reconstruct())
    singular = np.linalg.svd(X, compute_uv=False)
    q_pca = 1 - np.sum(singular[3:] ** 2) / np.sum(singular**2)
    assert q > 0.99 and q_pca < 0.85
    explained = 1 - np.cumsum(singular**2)[:-1] / np.sum(singular**2)  # residual after k + 1 components
    assert np.argmax(1 - explained >= q) + 1 >= 7  # PCA needs at least 7 components to match 3 shifted sources
    # One source matches a true one up to shift and sign (the decomposition is not unique, thesis 3.3.3).
    best = max(np.abs(np.fft.irfft(np.fft.rfft(S[k]) * np.conj(np.fft.rfft(r)), n=T)).max() / T
               for k in range(3) for r in model.sources)
    assert best > 0.9


def test_sisa_checks_its_input():
    with pytest.raises(ValueError, match="n_sources = 0"):
        sisa(np.zeros((3, T)), 0)
    with pytest.raises(ValueError, match="finite"):
        sisa(np.full((3, T), np.nan), 2)


def test_delay_clustering_shares_one_delay_per_joint_and_still_fits():
    joints, trials = 6, 4
    X, S = synthetic(np.random.default_rng(0), joints=joints, trials=trials)
    groups = np.tile(np.arange(joints), trials)
    model = sisa(X, 3, groups=groups)
    singular = np.linalg.svd(X, compute_uv=False)
    # Fewer free parameters than the unconstrained fit (> 0.99 above), still far better than PCA.
    assert quality(X, model.reconstruct()) > 0.97 > 0.85 > 1 - np.sum(singular[3:] ** 2) / np.sum(singular**2)
    for j in range(joints):
        assert np.ptp(model.delays[groups == j], axis=0).max() == 0.0


def test_delay_clustering_rejects_mislabelled_groups():
    X, _ = synthetic(np.random.default_rng(0))
    with pytest.raises(ValueError, match="one label per row"):
        sisa(X, 2, groups=np.zeros(3))
