"""HierarchicalQP: strict-priority stack of tasks, one quadprog QP per level.

Level k solves, over the velocity ``v`` (Pinocchio tangent space, nv)::

    min_v  ½‖A_k v − b_k‖² + ½ μ‖v‖²
    s.t.   A_i v = A_i v*_i   for every higher level i   (keep what level i achieved)
           lo ≤ v_j ≤ hi      (joint position and velocity limits, at every level)

The equalities are eliminated rather than passed to the QP: with ``N`` an orthonormal basis of
the null space of the stacked higher-level matrices and ``v*`` the previous level's solution,
``v = v* + N z`` satisfies them for any ``z``. Level k is then a QP in ``z`` with bounds only,
``z = 0`` is feasible by construction, and the QPs shrink as the stack descends. ``N`` is updated
level by level from a rank-revealing (column-pivoted) QR of the small projected matrix
``(A_k N)ᵀ``, so rank-deficient levels are handled. When the unconstrained minimizer (a Cholesky
solve) already satisfies every bound, it is the QP's solution and quadprog is skipped.
μ is a small regularization that keeps the Hessian positive definite. The returned ``v`` is
clipped to the bounds, so limits hold exactly and higher levels hold to solver tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import quadprog
from scipy.linalg import lapack

from robot_ctrl.sot.joint_limits import JointLimits, LimitViolation
from robot_ctrl.sot.task import Task

BOUND_SLACK = 1e-10  # [rad/s] relaxation of the bounds inside each QP (see solve)

_geqp3, _orgqr, _posv = lapack.dgeqp3, lapack.dorgqr, lapack.dposv


class InfeasibleError(RuntimeError):
    """The QP of a level has no solution, or the configuration lies outside the hard joint limits.
    ``level`` is the failing level's index."""

    def __init__(self, level: int, message: str):
        super().__init__(f"IK level {level}: {message}")
        self.level = level


@dataclass
class LevelResult:
    """Diagnostics of one level of the last solve."""

    names: list[str]
    used_qp: bool  # False when the unconstrained solution already met the bounds
    A: np.ndarray
    b: np.ndarray

    def residual(self, v: np.ndarray) -> float:
        """‖A v − b‖ of this level for the solution ``v``."""
        return float(np.linalg.norm(self.A @ v - self.b))


class HierarchicalQP:
    def __init__(self, levels: list[list[Task]], limits: JointLimits, regularization: float = 1e-5,
                 rank_tol: float = 1e-8):
        self.levels = levels
        self.limits = limits
        self.mu = regularization
        self.rank_tol = rank_tol
        self.last: list[LevelResult] = []

    def solve(self, model: pin.Model, data: pin.Data, q: np.ndarray, dt: float) -> np.ndarray:
        """Velocity ``v`` (nv) for one step of ``dt`` seconds from configuration ``q``."""
        if not np.all(np.isfinite(q)):
            raise InfeasibleError(0, "configuration contains NaN or inf")
        try:
            lo, hi = self.limits.bounds(q, dt)
        except LimitViolation as exc:
            raise InfeasibleError(0, str(exc)) from exc
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        bounded = self.limits.v_index
        v = np.zeros(model.nv)
        N = None  # basis of the directions the higher levels leave free; None = identity
        self.last = []
        levels = [tasks for tasks in ([t for t in level if t.active] for level in self.levels) if tasks]
        for k, tasks in enumerate(levels):
            rows = [t.rows(model, data, q) for t in tasks]
            A = np.vstack([r[0] for r in rows]) if len(rows) > 1 else rows[0][0]
            b = np.concatenate([r[1] for r in rows]) if len(rows) > 1 else rows[0][1]
            AN = A if N is None else A @ N
            G = AN.T @ AN
            G.flat[:: G.shape[0] + 1] += self.mu
            a = AN.T @ (b - A @ v) - self.mu * (v if N is None else N.T @ v)
            z, used_qp = self._solve_level(k, tasks, G, a, N, v[bounded], lo, hi, bounded)
            v = v + (z if N is None else N @ z)
            self.last.append(LevelResult([t.name for t in tasks], used_qp, A, b))
            if k < len(levels) - 1:
                N = _null_space_update(N, AN, self.rank_tol)
                if N.shape[1] == 0:
                    break
        v[bounded] = np.clip(v[bounded], lo, hi)
        return v

    def _solve_level(self, k, tasks, G, a, N, vb, lo, hi, bounded) -> tuple[np.ndarray, bool]:
        _, z, info = _posv(G, a)
        if info == 0:
            vz = vb + (z[bounded] if N is None else N[bounded] @ z)
            if ((vz >= lo - BOUND_SLACK) & (vz <= hi + BOUND_SLACK)).all():
                return z, False
        Nb = np.eye(G.shape[0])[bounded] if N is None else N[bounded]
        # A dof that the higher levels fix (zero row of N) already meets its bounds and cannot move:
        # its near-zero rows would only make the QP degenerate.
        free = np.einsum("ij,ij->i", Nb, Nb) > 1e-20
        Nb, vb = Nb[free], vb[free]
        C = np.hstack([Nb.T, -Nb.T])
        c = np.concatenate([lo[free] - vb, vb - hi[free]])
        try:
            # z = 0 is feasible (c ≤ 0 up to rounding). Relaxing by BOUND_SLACK breaks ties between
            # coincident active bounds, on which quadprog's dual active set otherwise reports
            # inconsistency; the final clip restores the exact bounds.
            z = quadprog.solve_qp(G, a, C, np.minimum(c, 0.0) - BOUND_SLACK)[0]
        except ValueError as exc:
            raise InfeasibleError(k, f"{exc} (tasks {[t.name for t in tasks]})") from exc
        return z, True


def _null_space_update(N: np.ndarray | None, AN: np.ndarray, tol: float) -> np.ndarray:
    """Basis of ``{N z : A N z = 0}`` from a column-pivoted QR of ``(A N)ᵀ`` (rank-revealing)."""
    r, m = AN.shape[1], AN.shape[0]
    qr, _, tau, _, info = _geqp3(np.asfortranarray(AN.T))
    diag = np.abs(np.diag(qr[: min(r, m), : min(r, m)]))
    rank = int(np.sum(diag > tol * max(1.0, diag[0] if diag.size else 0.0)))
    full = np.zeros((r, r), order="F")
    full[:, : min(r, m)] = qr[:, : min(r, m)]
    Q, _, info = _orgqr(full, tau)
    basis = Q[:, rank:]
    return basis if N is None else N @ basis
