"""PivotedQR: the rank-revealing QR a level of the stack of tasks is solved with (minimum-norm
solution, null space for the levels below)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

_geqp3, _orgqr, _trtrs = lapack.dgeqp3, lapack.dorgqr, lapack.dtrtrs


class PivotedQR:
    """Column-pivoted QR ``(A N)ᵀ Π = Q R`` of one level's projected matrix (rank-revealing)."""

    def __init__(self, AN: np.ndarray, tol: float):
        m, n = AN.shape
        qr, self.perm, tau, _, _ = _geqp3(np.asfortranarray(AN.T))
        k = min(n, m)
        diag = np.abs(np.diag(qr[:k, :k]))
        self.rank = int(np.sum(diag > tol * max(1.0, diag[0] if diag.size else 0.0)))
        self.rows = m
        self.R = qr[:k, :k]
        full = np.zeros((n, n), order="F")
        full[:, :k] = qr[:, :k]
        self.Q, _, _ = _orgqr(full, tau)

    def min_norm_solution(self, r: np.ndarray) -> np.ndarray | None:
        """Minimum-norm ``z`` with ``A N z = r``, None unless ``A N`` has full row rank:
        ``A N = Π Rᵀ Qᵀ`` gives ``z = Q R⁻ᵀ Πᵀ r``."""
        if self.rank < self.rows:
            return None
        y, info = _trtrs(self.R, r[self.perm - 1][:, None], trans=1)  # LAPACK's pivots are 1-based
        return self.Q[:, : self.rows] @ y[:, 0] if info == 0 else None

    def null_space(self, N: np.ndarray | None) -> np.ndarray:
        """Basis of ``{N z : A N z = 0}``."""
        basis = self.Q[:, self.rank :]
        return basis if N is None else N @ basis
