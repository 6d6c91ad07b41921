"""Auditing the certificates on random graphs: how far each certified rate lies below the
condition's worst case (``robot-ctrl crowd audit``).

For each random connected weighted graph (symmetric or not) the step-frequency and step-length
certificates are compared with the worst case over every corner of the gait-profile box (exact for
N ≤ 12, ``crowd.worst_case``) or, above, over 4096 random corners (an upper bound on the true rate,
so the printed ratio overstates how close a bound is); the sine (Schöner-Dose) certificate with
the best of 200 random angle sets of spread ≤ Δ (an upper bound on its true worst-case rate); the
phase and Hopf certificates with the projected symmetrized Jacobian's extreme eigenvalue (exact).
Gains of both signs, symmetric and directed graphs, weights rescaled by powers of ten. A ratio
above 1, or a certificate that holds where the worst case does not, would be optimistic.
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


def _diffusive_truth(L: np.ndarray, k: float) -> float:
    """−sup λ_max of the phase coupling's projected symmetrized Jacobian −k L (the Hopf network's
    is the same shifted by 1, reached with every oscillator at r = 0)."""
    return -float(projected_symmetric_max(-k * L))


def audit(graphs: int = 1000, sizes: tuple[int, int] = (2, 12), seed: int = 0) -> dict[str, dict]:
    """Per certificate: graphs where it holds, graphs whose worst case contracts (above 12 agents
    its estimate from random corners, which may count a graph that does not), share exact,
    certified/worst-case rate (median, min, max) and the count of optimistic ones: certified above
    the worst case, or holding where the worst case does not. Every fourth graph has negative
    gains, every third is rescaled by a power of ten (with the gains rescaled inversely: the same
    dynamics)."""
    rng = np.random.default_rng(seed)
    names = ("phase_coupling", "hopf_diffusive", "step_frequency", "step_length", "schoener_dose")
    ratios: dict[str, list[float]] = {name: [] for name in names}
    exact = {name: 0 for name in names}
    optimistic = {name: 0 for name in names}
    contracting = {name: 0 for name in names}
    for trial in range(graphs):
        n = int(rng.integers(sizes[0], sizes[1] + 1))
        A = random_adjacency(rng, n, symmetric=bool(trial % 2))
        sign = -1.0 if trial % 4 == 3 else 1.0
        scale = 10.0 ** float(rng.integers(-9, 10)) if trial % 3 == 2 else 1.0
        graph = CouplingGraph.from_adjacency(scale * A)
        g = rng.uniform(0.1, 2.0, int(rng.integers(2, 6)))
        k, m_d, m_z, k_sine = sign * rng.uniform(0.1, 2.0, 4) / scale
        spread = float(rng.uniform(0.2, 1.4))
        found = {c.name: c for c in certify(CouplingConfig(graph, k=k, m_d=m_d, m_z=m_z, k_sine=k_sine, g=g,
                                                           heading_spread=spread))}
        L = graph.laplacian
        phase = _diffusive_truth(L, k)
        truths = {"phase_coupling": phase, "hopf_diffusive": phase - 1.0,
                  "step_frequency": _profile_truth(L, m_d, g.min(), g.max(), "right", rng),
                  "step_length": _profile_truth(L, m_z, g.min(), g.max(), "left", rng),
                  "schoener_dose": _sine_truth(scale * A, k_sine, spread, rng)}
        for name, truth in truths.items():
            c = found[name]
            contracting[name] += truth > 0
            if c.holds and truth <= 0:
                optimistic[name] += 1
            elif c.holds:
                ratios[name].append(c.rate / truth)
                exact[name] += c.exact
                optimistic[name] += c.rate > truth * (1 + 1e-9)
    return {name: {"holds": len(r), "contracting": contracting[name], "exact": exact[name],
                   "median": float(np.median(r)) if r else None,
                   "min": float(np.min(r)) if r else None, "max": float(np.max(r)) if r else None,
                   "optimistic": int(optimistic[name])} for name, r in ratios.items()}
