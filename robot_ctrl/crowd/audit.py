"""Auditing the certificates on random graphs: how far each certified rate lies below the
condition's worst case (``robot-ctrl crowd audit``).

For each random connected weighted graph (symmetric or not) the step-frequency and step-length
certificates are compared with the worst case over every corner of the gait-profile box (exact for
N ≤ 12, ``crowd.worst_case``) or, above, over 4096 random corners (an upper bound on the true rate,
so the printed ratio overstates how close a bound is); the sine (Schöner-Dose) certificate with
the best of 200 random angle sets of spread ≤ Δ (an upper bound on its true worst-case rate).
A ratio above 1 would be an optimistic certificate.
"""

from __future__ import annotations

import numpy as np

from robot_ctrl.crowd.certificates import CouplingConfig, certify
from robot_ctrl.crowd.coupling_graph import CouplingGraph
from robot_ctrl.crowd.worst_case import EXACT_UP_TO, projected_symmetric_max, vertices


def random_adjacency(rng: np.random.Generator, n: int, symmetric: bool) -> np.ndarray:
    """Connected (a random spanning path), link weights in [0.1, 3]."""
    A = (rng.random((n, n)) < rng.uniform(0.2, 0.9)) * rng.uniform(0.1, 3.0, (n, n))
    order = rng.permutation(n)
    for a, b in zip(order, order[1:]):
        A[a, b] = A[a, b] or rng.uniform(0.1, 3.0)
    np.fill_diagonal(A, 0.0)
    return np.maximum(A, A.T) if symmetric else A


def _profile_truth(L: np.ndarray, gain: float, low: float, high: float, side: str, rng) -> float:
    n = L.shape[0]
    G = vertices(n, low, high) if n <= EXACT_UP_TO else rng.choice([low, high], (4096, n))
    J = -gain * (L[None] * G[:, None, :] if side == "right" else G[:, :, None] * L[None])
    return -float(projected_symmetric_max(J).max())


def _sine_truth(A: np.ndarray, k: float, spread: float, rng) -> float:
    psi = rng.uniform(-spread / 2, spread / 2, (200, A.shape[0]))
    psi[:100] = np.where(psi[:100] > 0, spread / 2, -spread / 2)  # the extremes too
    W = A[None] * np.cos(psi[:, :, None] - psi[:, None, :])
    L = W.sum(axis=2)[:, :, None] * np.eye(A.shape[0])[None] - W
    return -float(projected_symmetric_max(-k * L).max())


def audit(graphs: int = 1000, sizes: tuple[int, int] = (2, 12), seed: int = 0) -> dict[str, dict]:
    """Per certificate: graphs where it holds, share exact, certified/worst-case rate (median, min,
    max) and the count of optimistic ones (certified above the worst case)."""
    rng = np.random.default_rng(seed)
    ratios: dict[str, list[float]] = {"step_frequency": [], "step_length": [], "schoener_dose": []}
    exact = {name: 0 for name in ratios}
    for trial in range(graphs):
        n = int(rng.integers(sizes[0], sizes[1] + 1))
        A = random_adjacency(rng, n, symmetric=bool(trial % 2))
        graph = CouplingGraph.from_adjacency(A)
        g = rng.uniform(0.1, 2.0, int(rng.integers(2, 6)))
        m_d, m_z, k, spread = *rng.uniform(0.1, 2.0, 3), float(rng.uniform(0.2, 1.4))
        found = {c.name: c for c in certify(CouplingConfig(graph, m_d=m_d, m_z=m_z, k_sine=k, g=g,
                                                           heading_spread=spread))}
        truths = {"step_frequency": _profile_truth(graph.laplacian, m_d, g.min(), g.max(), "right", rng),
                  "step_length": _profile_truth(graph.laplacian, m_z, g.min(), g.max(), "left", rng),
                  "schoener_dose": _sine_truth(A, k, spread, rng)}
        for name, truth in truths.items():
            c = found[name]
            if c.holds and truth > 0:
                ratios[name].append(c.rate / truth)
                exact[name] += c.exact
    return {name: {"holds": len(r), "exact": exact[name], "median": float(np.median(r)) if r else None,
                   "min": float(np.min(r)) if r else None, "max": float(np.max(r)) if r else None,
                   "optimistic": int(np.sum(np.asarray(r) > 1 + 1e-9))} for name, r in ratios.items()}
