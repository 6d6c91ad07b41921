"""CouplingGraph: who is coupled to whom, as a graph Laplacian (thesis A.1, Table 4.1).

``L_ii = Σ_j A_ij``, ``L_ij = −A_ij`` for an adjacency (weight) matrix ``A ≥ 0`` with zero diagonal;
``A_ij`` is the weight with which agent i listens to agent j. Asymmetric and weighted graphs are
accepted; the contraction conditions use the symmetric part ``L_s = (L + Lᵀ)/2`` projected onto
the complement of the synchronization manifold (``V L_s Vᵀ`` with V an orthonormal basis of 1⊥).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

TOPOLOGIES = ("all", "ring", "chain", "star")
RELATIVE_TOLERANCE = 1e-12  # of the largest |L_ij|: symmetry, links, signs
DENSE_LIMIT = 5000  # agents: above, a named graph is never made a dense N × N matrix


@dataclass(frozen=True, eq=False)
class CouplingGraph:
    """The Laplacian of a given graph (``matrix``, dense), or of a named topology: sparse for the
    ring, chain and star, nothing for all-to-all (``(L x)_i = w (N x_i − Σ_j x_j)``), and every
    spectral quantity in closed form (Table 4.1), so that a named graph of 100,000 agents costs
    O(N)."""

    matrix: np.ndarray | sparse.csr_array | None
    topology: str | None = None  # named topology, or None for a given matrix
    weight: float = 1.0  # the uniform link weight of a named topology
    size: int = 0  # N

    @classmethod
    def named(cls, topology: str, n: int, weight: float = 1.0) -> "CouplingGraph":
        """All-to-all, ring, chain (path) or star (agent 0 in the centre), every link of ``weight`` > 0.
        For N = 2 every one of them is the single link between the two agents."""
        if topology not in TOPOLOGIES:
            raise ValueError(f"graph {topology!r} is not one of {', '.join(TOPOLOGIES)}")
        if not isinstance(n, (int, np.integer)) or n < 2:
            raise ValueError(f"n = {n!r} must be an integer ≥ 2")
        if not (np.isfinite(weight) and weight > 0):
            raise ValueError(f"weight = {weight!r} must be > 0")
        n = int(n)
        if topology == "all":
            return cls(None, topology, float(weight), n)
        if topology == "star":
            rows, cols = np.zeros(n - 1, int), np.arange(1, n)
        else:
            rows, cols = np.arange(n - 1), np.arange(1, n)
            if topology == "ring" and n > 2:
                rows, cols = np.append(rows, 0), np.append(cols, n - 1)
        A = sparse.coo_array((np.full(len(rows), float(weight)), (rows, cols)), shape=(n, n))
        A = (A + A.T).tocsr()
        return cls(laplacian_of(A), topology, float(weight), n)

    @classmethod
    def from_adjacency(cls, adjacency) -> "CouplingGraph":
        A = np.asarray(adjacency, dtype=float)
        if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] < 2:
            raise ValueError(f"adjacency must be a square matrix of size ≥ 2, got shape {A.shape}")
        if not np.all(np.isfinite(A)) or np.any(A < 0):
            raise ValueError("adjacency entries must be finite and ≥ 0 (link weights)")
        if np.any(np.diag(A) != 0):
            raise ValueError("adjacency must have a zero diagonal (no self-links)")
        return cls(laplacian_of(A), size=A.shape[0])

    @classmethod
    def from_laplacian(cls, laplacian) -> "CouplingGraph":
        L = np.asarray(laplacian, dtype=float)
        if L.ndim != 2 or L.shape[0] != L.shape[1] or L.shape[0] < 2:
            raise ValueError(f"laplacian must be a square matrix of size ≥ 2, got shape {L.shape}")
        if not np.all(np.isfinite(L)):
            raise ValueError("laplacian entries must be finite")
        off = L - np.diag(np.diag(L))
        if np.any(off > RELATIVE_TOLERANCE * np.abs(L).max()):
            raise ValueError("laplacian off-diagonal entries must be ≤ 0 (they are minus the link weights)")
        if np.any(np.abs(L.sum(axis=1)) > 1e-9 * max(1.0, np.abs(L).max())):
            raise ValueError("laplacian rows must sum to zero (L_ii = Σ_j A_ij)")
        return cls(L, size=L.shape[0])

    @property
    def n(self) -> int:
        return self.size

    @cached_property
    def laplacian(self) -> np.ndarray:
        """The Laplacian as a dense (N, N) array; refused above ``DENSE_LIMIT`` agents."""
        if isinstance(self.matrix, np.ndarray):
            return self.matrix
        if self.n > DENSE_LIMIT:
            raise ValueError(f"a dense Laplacian of {self.n} agents ({8 * self.n ** 2 / 1e9:.3g} GB) is not made: "
                             f"above {DENSE_LIMIT} agents only what a named graph gives in closed form or sparse "
                             "applies")
        if self.matrix is None:  # all-to-all
            return self.weight * (self.n * np.eye(self.n) - np.ones((self.n, self.n)))
        return self.matrix.toarray()

    def apply(self, values: np.ndarray) -> np.ndarray:
        """``L @ values`` along the first axis (agents), O(N) for every named topology."""
        if self.matrix is None:  # all-to-all: (L x)_i = w (N x_i − Σ_j x_j)
            return self.weight * (self.n * values - values.sum(axis=0, keepdims=True))
        return self.matrix @ values

    @property
    def scale(self) -> float:
        """The largest |L_ij|: what the tolerances are relative to (a graph and its rescaled copy
        with the gain rescaled inversely are the same dynamics, and must be judged alike)."""
        if self.topology is not None:  # the largest degree times the weight
            return self.weight * {"all": self.n - 1, "star": self.n - 1}.get(self.topology, min(2, self.n - 1))
        return float(np.abs(self.laplacian).max())

    @property
    def symmetric(self) -> bool:
        if self.topology is not None:
            return True
        return bool(np.abs(self.laplacian - self.laplacian.T).max() <= RELATIVE_TOLERANCE * self.scale)

    @cached_property
    def projected_eigenvalues(self) -> np.ndarray:
        """Eigenvalues (ascending) of ``V L_s Vᵀ``, V an orthonormal basis of the complement of 1."""
        V = complement_basis(self.n)
        Ls = (self.laplacian + self.laplacian.T) / 2
        return np.linalg.eigvalsh(V @ Ls @ V.T)

    @property
    def connected(self) -> bool:
        """Connected when links are taken in both directions (a single component)."""
        if self.topology is not None:
            return True
        links = sparse.csr_array(-(self.laplacian + self.laplacian.T) > RELATIVE_TOLERANCE * self.scale)
        return csgraph.connected_components(links, directed=False)[0] == 1

    @property
    def lambda_plus(self) -> float:
        """λ⁺: smallest eigenvalue of the projected symmetric Laplacian (the smallest non-zero one of
        ``L_s`` for a connected symmetric graph; 0 for a disconnected one)."""
        if self.topology is not None:
            return self.closed_form_lambda_plus()
        return float(self.projected_eigenvalues[0])

    @property
    def lambda_top(self) -> float:
        """The largest eigenvalue of the projected symmetric Laplacian: what a negative gain meets."""
        if self.topology is not None:
            return self.closed_form_lambda_top()
        return float(self.projected_eigenvalues[-1])

    def extreme_eigenvalue(self, gain: float) -> float:
        """The projected symmetric Laplacian's eigenvalue λ that minimizes ``gain · λ``: λ⁺ for a
        gain ≥ 0, the largest one for a negative gain (``min_λ gain λ`` is what a diffusive
        coupling ``−gain L`` guarantees)."""
        return self.lambda_plus if gain >= 0 else self.lambda_top

    @property
    def lambda_max(self) -> float:
        """Largest eigenvalue of ``L_s`` (a named graph's: its projected largest, L's other eigenvalue
        being 0)."""
        if self.topology is not None:
            return self.closed_form_lambda_top()
        return float(np.linalg.eigvalsh((self.laplacian + self.laplacian.T) / 2)[-1])

    @property
    def norm2(self) -> float:
        """``‖L‖₂``: λ_max for a symmetric graph."""
        return self.lambda_max if self.symmetric else float(np.linalg.norm(self.laplacian, 2))

    def closed_form_lambda_plus(self) -> float | None:
        """λ⁺ of thesis Table 4.1 for the named topologies, times their link weight, else None. For
        N = 2 each topology is one link (λ⁺ = 2 w); Table 4.1's ring and star forms hold from N = 3."""
        n, w = self.n, self.weight
        if self.topology is None:
            return None
        if n == 2:
            return 2.0 * w
        return w * {"all": float(n), "star": 1.0, "chain": 2 * (1 - np.cos(np.pi / n)),
                    "ring": 2 * (1 - np.cos(2 * np.pi / n))}[self.topology]

    def closed_form_lambda_top(self) -> float | None:
        """The largest eigenvalue of the named topologies' projected Laplacian, times their link
        weight (all and star: N w; chain 2 w (1 − cos(π (N − 1)/N)); ring 2 w (1 − cos(2π ⌊N/2⌋/N))), else None."""
        n, w = self.n, self.weight
        if self.topology is None:
            return None
        if n == 2:
            return 2.0 * w
        return w * {"all": float(n), "star": float(n), "chain": 2 * (1 - np.cos(np.pi * (n - 1) / n)),
                    "ring": 2 * (1 - np.cos(2 * np.pi * (n // 2) / n))}[self.topology]


def laplacian_of(adjacency):
    """``diag(A 1) − A``, dense or sparse as ``adjacency`` is."""
    if sparse.issparse(adjacency):
        return (sparse.diags_array(np.asarray(adjacency.sum(axis=1)).ravel()) - adjacency).tocsr()
    return np.diag(adjacency.sum(axis=1)) - adjacency


def complement_basis(n: int) -> np.ndarray:
    """Orthonormal rows V ((n − 1) × n) spanning the complement of the vector of ones."""
    Q, _ = np.linalg.qr(np.column_stack([np.ones(n), np.eye(n)[:, : n - 1]]))
    return Q[:, 1:].T
