"""Worst cases of contraction conditions over a box of parameters: exact where affordable,
provably conservative above.

A condition of the form "the projected symmetrized Jacobian ``V J(p)_s Vᵀ`` is negative definite
for every p in a box" holds with rate ``−sup_p λ_max(V J(p)_s Vᵀ)``. When J is affine in p,
``λ_max`` of the (symmetric, affine in p) matrix is a convex function of p (a maximum of linear
functions ``uᵀ M(p) u`` over unit vectors u), so its supremum over the box is attained at a
vertex: enumerating the ``2^m`` vertices gives the worst case exactly (``EXACT_UP_TO`` parameters).
Above that, every parameter of these Jacobians moves a rank-two term: ``M(δ) = M₀ + Σ_i δ_i s (a_i b_iᵀ
+ b_i a_iᵀ)/2`` with |δ_i| ≤ r_i. For a unit x the perturbation is ``s Σ δ_i (a_iᵀx)(b_iᵀx) ≤ |s| Σ r_i
|a_iᵀx| |b_iᵀx| ≤ |s|/2 Σ r_i (t_i (a_iᵀx)² + (b_iᵀx)²/t_i)`` for any t > 0 (the arithmetic-geometric
mean inequality), so ``λ_max(M₀ + |s|/2 Σ r_i (t_i a_i a_iᵀ + b_i b_iᵀ/t_i))`` bounds the supremum for
every t: a bound that is never optimistic (``[bound]``, our derivation), minimized over t (convex in
log t). On the graphs up to 12 agents where both are computed it is within 1e-3 of the exact worst
case (``tests/test_certificates_sound.py``). Above ``RELAXED_UP_TO`` agents, Weyl's inequality
``λ_max(A + B) ≤ λ_max(A) + ‖B‖₂`` around the box centre (closed forms for named graphs).

The two Jacobians of the gait couplings (conference paper eq. 2, thesis 4.4.2), with g_i ∈
[g_min, g_max] the gait profile of agent i (agents at different phases):

- step frequency, ``φ̇ = ω₀ − m (L G(φ) + c)``: ``J = −m L D_g``;
- step length, ``ż = ω g(φ)(1 − m (L z + c))``: ``J = −m D_g L``.

With ``D_g = ḡ I + D_δ``, |δ_i| ≤ Δ: ``λ_max(V J_s Vᵀ) ≤ −min_λ m ḡ λ + |m| Δ ‖L‖₂``
(``‖L D_δ‖₂ ≤ Δ ‖L‖₂``; λ over the projected symmetric Laplacian's eigenvalues: λ⁺ for m ≥ 0, the
largest for m < 0). The vertex enumeration holds for either sign (λ_max stays convex in p).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy import optimize

from robot_ctrl.crowd.coupling_graph import CouplingGraph, complement_basis

EXACT_UP_TO = 12  # parameters enumerated exactly (2^12 = 4096 vertices)
RELAXED_UP_TO = 200  # agents: above, Weyl's bound (the relaxation costs an O(N³) eigensolve per iteration)


def vertices(m: int, low: float, high: float) -> np.ndarray:
    """All ``2^m`` corners of the box [low, high]^m, one per row."""
    return np.array(list(itertools.product((low, high), repeat=m)), dtype=float).reshape(-1, m)


def projected_symmetric_max(J: np.ndarray) -> np.ndarray:
    """``λ_max(V J_s Vᵀ)`` of each matrix in a stack (..., n, n), V an orthonormal basis of 1⊥."""
    V = complement_basis(J.shape[-1])
    S = (J + np.swapaxes(J, -1, -2)) / 2
    return np.linalg.eigvalsh(V @ S @ V.T)[..., -1]


def rank_two_box_sup(base: np.ndarray, a: np.ndarray, b: np.ndarray, radius: np.ndarray, s: float) -> float:
    """An upper bound on ``sup λ_max(base + Σ_i δ_i s (a_i b_iᵀ + b_i a_iᵀ)/2)`` over |δ_i| ≤ radius_i
    (``a``, ``b``: (m, d)): ``λ_max(base + |s|/2 Σ r_i (t_i a_i a_iᵀ + b_i b_iᵀ/t_i))`` at the t that
    L-BFGS-B finds (module docstring; any t gives a bound)."""
    outer_a, outer_b = np.einsum("mi,mj->mij", a, a), np.einsum("mi,mj->mij", b, b)
    weight = abs(s) / 2 * radius

    def bound(log_t):
        t = np.exp(log_t)
        matrix = base + np.tensordot(weight * t, outer_a, 1) + np.tensordot(weight / t, outer_b, 1)
        values, vectors = np.linalg.eigh(matrix)
        top = vectors[:, -1]
        return values[-1], weight * (t * (a @ top) ** 2 - (b @ top) ** 2 / t)
    start = np.log(np.maximum(np.linalg.norm(b, axis=1), 1e-12) / np.maximum(np.linalg.norm(a, axis=1), 1e-12))
    # Any t gives a bound; t within e^±20 of the start keeps the matrix finite (an unbounded line
    # search overflowed exp to inf and eigh failed to converge).
    found = optimize.minimize(bound, start, jac=True, method="L-BFGS-B", bounds=[(x - 20.0, x + 20.0) for x in start],
                              options={"maxiter": 300})
    return float(min(bound(found.x)[0], bound(start)[0]))


def profile_coupling_rate(graph: CouplingGraph, gain: float, g_min: float, g_max: float,
                          side: str) -> tuple[float, bool]:
    """``−sup λ_max(V J_s Vᵀ)`` over g ∈ [g_min, g_max]^N for ``J = −gain L D_g`` (``side="right"``,
    step frequency) or ``J = −gain D_g L`` (``"left"``, step length), and whether it is exact."""
    if side not in ("left", "right"):
        raise ValueError(f"side = {side!r} must be 'left' or 'right'")
    if graph.n <= EXACT_UP_TO:
        laplacian = graph.laplacian
        G = vertices(graph.n, g_min, g_max)
        J = -gain * (laplacian[None] * G[:, None, :] if side == "right" else G[:, :, None] * laplacian[None])
        return -float(projected_symmetric_max(J).max()), True
    centre, radius = (g_min + g_max) / 2, (g_max - g_min) / 2
    lam = graph.extreme_eigenvalue(gain)  # min over λ of gain·centre·λ
    weyl = gain * centre * lam - abs(gain) * radius * graph.norm2
    if graph.n > RELAXED_UP_TO:
        return weyl, False
    laplacian, V = graph.laplacian, complement_basis(graph.n)
    J0 = -gain * centre * laplacian
    # ∂J/∂g_i = −gain l e_iᵀ (right: l the column i of L) or −gain e_i lᵀ (left: l the row i).
    a = (V @ laplacian).T if side == "right" else (V @ laplacian.T).T
    sup = rank_two_box_sup(V @ ((J0 + J0.T) / 2) @ V.T, a, V.T, np.full(graph.n, radius), -gain)
    return max(-sup, weyl), False


def sine_coupling_rate(adjacency: np.ndarray, gain: float, spread: float) -> tuple[float, str]:
    """``−sup λ_max(V J_s Vᵀ)`` of the sine coupling ``ψ̇_i = −k Σ_j A_ij sin(ψ_i − ψ_j)``, whose
    Jacobian is ``−k L(W)``, ``W_ij = A_ij cos(ψ_i − ψ_j)``, with every coupled cosine in
    [cos Δ, 1] (the box contains every angle set of spread ≤ Δ, so this is a bound even when the
    box's vertices are enumerated). The cosines of the pairs coupled in either direction are the
    box's parameters. Returns the rate and how it was bounded."""
    n = adjacency.shape[0]
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n) if adjacency[i, j] > 0 or adjacency[j, i] > 0]
    low = float(np.cos(spread))
    if len(pairs) <= EXACT_UP_TO:
        corners = vertices(len(pairs), low, 1.0)
        C = np.ones((len(corners), n, n))
        for column, (i, j) in enumerate(pairs):
            C[:, i, j] = C[:, j, i] = corners[:, column]
        W = adjacency[None] * C
        L = W.sum(axis=2)[:, :, None] * np.eye(n)[None] - W
        return (-float(projected_symmetric_max(-gain * L).max()),
                f"the {len(corners)} vertices of the box of coupled cosines [cos Δ, 1]")
    L = np.diag(adjacency.sum(axis=1)) - adjacency
    centre, radius = (1 + low) / 2, (1 - low) / 2
    V = complement_basis(n)
    J0 = -gain * centre * L
    # ∂L(W)/∂c_p = (A_ij e_i − A_ji e_j)(e_i − e_j)ᵀ for the pair p = {i, j}.
    u, d = np.zeros((len(pairs), n)), np.zeros((len(pairs), n))
    for p, (i, j) in enumerate(pairs):
        u[p, i], u[p, j], d[p, i], d[p, j] = adjacency[i, j], -adjacency[j, i], 1.0, -1.0
    sup = rank_two_box_sup(V @ ((J0 + J0.T) / 2) @ V.T, u @ V.T, d @ V.T, np.full(len(pairs), radius), -gain)
    return (-sup, f"relaxation over the box of the {len(pairs)} coupled cosines [cos Δ, 1] (arithmetic-geometric "
                  "mean per cosine, its multipliers minimized)")
