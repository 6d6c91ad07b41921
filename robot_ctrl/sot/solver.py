"""HierarchicalQP: strict-priority stack of tasks, one quadprog QP per level.

Level k solves, over the velocity ``v`` (Pinocchio tangent space, nv)::

    min_v  ½‖A_k v − b_k‖² + ½ μ‖v‖²
    s.t.   A_i v = A_i v*_i   for every higher level i   (keep what level i achieved)
           lo ≤ v_j ≤ hi      (joint position and velocity limits, at every level)

The equalities are eliminated rather than passed to the QP: with ``N`` an orthonormal basis of
the null space of the stacked higher-level matrices (from an SVD, so rank deficiency is handled)
and ``v*`` the previous level's solution, ``v = v* + N z`` satisfies them for any ``z``. Level k
is then a QP in ``z`` with bounds only, and ``z = 0`` is feasible by construction; the QPs shrink
as the stack descends. μ is a small regularization that keeps the Hessian positive definite.
The returned ``v`` is clipped to the bounds, so limits hold exactly and the higher levels' values
hold to solver tolerance (≈ BOUND_SLACK).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import quadprog

from robot_ctrl.sot.joint_limits import JointLimits, LimitViolation
from robot_ctrl.sot.task import Task


BOUND_SLACK = 1e-10  # [rad/s] relaxation of the bounds inside each QP (see solve)


class InfeasibleError(RuntimeError):
    """The QP of a level has no solution, or the configuration lies outside the hard joint limits.
    ``level`` is the failing level's index."""

    def __init__(self, level: int, message: str):
        super().__init__(f"IK level {level}: {message}")
        self.level = level


@dataclass
class LevelResult:
    names: list[str]
    residual: float  # ‖A v − b‖ achieved at this level


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
        nv = model.nv
        bounded = self.limits.v_index
        v = np.zeros(nv)
        N = np.eye(nv)  # basis of the directions the higher levels leave free
        higher = np.zeros((0, nv))
        self.last = []
        active_levels = [[t for t in level if t.active] for level in self.levels]
        active_levels = [level for level in active_levels if level]
        for k, tasks in enumerate(active_levels):
            rows = [t.rows(model, data, q) for t in tasks]
            A = np.vstack([r[0] for r in rows])
            b = np.concatenate([r[1] for r in rows])
            AN = A @ N
            # quadprog: min ½ zᵀGz − aᵀz  s.t.  Cᵀz ≥ c, here the bounds on v = v + N z.
            G = AN.T @ AN + self.mu * np.eye(N.shape[1])
            a = AN.T @ (b - A @ v) - self.mu * (N.T @ v)
            # A dof that the higher levels fix (zero row of N) already meets its bounds and cannot move:
            # its near-zero rows would only make the QP degenerate.
            Nb = N[bounded]
            free = np.einsum("ij,ij->i", Nb, Nb) > 1e-20
            Nb = Nb[free]
            vb = v[bounded][free]
            C = np.hstack([Nb.T, -Nb.T])
            c = np.concatenate([lo[free] - vb, vb - hi[free]])
            try:
                # z = 0 is feasible (c ≤ 0 up to rounding). Relaxing by BOUND_SLACK breaks ties between
                # coincident active bounds, on which quadprog's dual active set otherwise reports
                # inconsistency; the final clip restores the exact bounds.
                z = quadprog.solve_qp(G, a, C, np.minimum(c, 0.0) - BOUND_SLACK)[0]
            except ValueError as exc:
                raise InfeasibleError(k, f"{exc} (tasks {[t.name for t in tasks]})") from exc
            v = v + N @ z
            self.last.append(LevelResult([t.name for t in tasks], float(np.linalg.norm(A @ v - b))))
            if k < len(active_levels) - 1:
                higher = np.vstack([higher, A])
                N = _null_space(higher, self.rank_tol)
                if N.shape[1] == 0:
                    break
        v[bounded] = np.clip(v[bounded], lo, hi)
        return v


def _null_space(A: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis (columns) of the null space of ``A``, by SVD with a relative rank tolerance."""
    _, s, Vt = np.linalg.svd(A)
    rank = int(np.sum(s > tol * max(1.0, s[0] if s.size else 0.0)))
    return Vt[rank:].T
