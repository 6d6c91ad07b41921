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

TOPOLOGIES = ("all", "ring", "chain", "star")
RELATIVE_TOLERANCE = 1e-12  # of the largest |L_ij|: symmetry, links, signs


@dataclass(frozen=True, eq=False)
class CouplingGraph:
    laplacian: np.ndarray  # (N, N)
    topology: str | None = None  # named topology, or None for a given matrix
    weight: float = 1.0  # the uniform link weight of a named topology

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
        A = np.zeros((n, n))
        if topology == "all":
            A[:] = 1.0
        elif topology in ("ring", "chain"):
            for i in range(n - 1):
                A[i, i + 1] = A[i + 1, i] = 1.0
            if topology == "ring" and n > 2:
                A[0, n - 1] = A[n - 1, 0] = 1.0
        else:
            A[0, 1:] = A[1:, 0] = 1.0
        np.fill_diagonal(A, 0.0)
        return cls(laplacian_of(weight * A), topology, float(weight))

    @classmethod
    def from_adjacency(cls, adjacency) -> "CouplingGraph":
        A = np.asarray(adjacency, dtype=float)
        if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] < 2:
            raise ValueError(f"adjacency must be a square matrix of size ≥ 2, got shape {A.shape}")
        if not np.all(np.isfinite(A)) or np.any(A < 0):
            raise ValueError("adjacency entries must be finite and ≥ 0 (link weights)")
        if np.any(np.diag(A) != 0):
            raise ValueError("adjacency must have a zero diagonal (no self-links)")
        return cls(laplacian_of(A))

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
        return cls(L)

    @property
    def n(self) -> int:
        return self.laplacian.shape[0]

    @property
    def scale(self) -> float:
        """The largest |L_ij|: what the tolerances are relative to (a graph and its rescaled copy
        with the gain rescaled inversely are the same dynamics, and must be judged alike)."""
        return float(np.abs(self.laplacian).max())

    @property
    def symmetric(self) -> bool:
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
        A = (-(self.laplacian + self.laplacian.T) > RELATIVE_TOLERANCE * self.scale).astype(float)
        seen, frontier = {0}, [0]
        while frontier:
            i = frontier.pop()
            for j in np.flatnonzero(A[i]):
                if j not in seen:
                    seen.add(int(j))
                    frontier.append(int(j))
        return len(seen) == self.n

    @property
    def lambda_plus(self) -> float:
        """λ⁺: smallest eigenvalue of the projected symmetric Laplacian (the smallest non-zero one of
        ``L_s`` for a connected symmetric graph; 0 for a disconnected one)."""
        return float(self.projected_eigenvalues[0])

    @property
    def lambda_top(self) -> float:
        """The largest eigenvalue of the projected symmetric Laplacian: what a negative gain meets."""
        return float(self.projected_eigenvalues[-1])

    def extreme_eigenvalue(self, gain: float) -> float:
        """The projected symmetric Laplacian's eigenvalue λ that minimizes ``gain · λ``: λ⁺ for a
        gain ≥ 0, the largest one for a negative gain (``min_λ gain λ`` is what a diffusive
        coupling ``−gain L`` guarantees)."""
        if self.topology is not None:
            return self.closed_form_lambda_plus() if gain >= 0 else self.closed_form_lambda_top()
        return self.lambda_plus if gain >= 0 else self.lambda_top

    @property
    def lambda_max(self) -> float:
        """Largest eigenvalue of ``L_s``."""
        return float(np.linalg.eigvalsh((self.laplacian + self.laplacian.T) / 2)[-1])

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


def laplacian_of(adjacency: np.ndarray) -> np.ndarray:
    return np.diag(adjacency.sum(axis=1)) - adjacency


def complement_basis(n: int) -> np.ndarray:
    """Orthonormal rows V ((n − 1) × n) spanning the complement of the vector of ones."""
    Q, _ = np.linalg.qr(np.column_stack([np.ones(n), np.eye(n)[:, : n - 1]]))
    return Q[:, 1:].T
