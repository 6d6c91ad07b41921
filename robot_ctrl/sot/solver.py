"""HierarchicalQP: strict-priority stack of tasks, one KKT system or one quadprog QP per level.

Level k solves, over the velocity ``v`` (Pinocchio tangent space, nv)::

    min_v  ½‖A_k v − b_k‖²  (+ ½ μ‖v‖² at the last level)
    s.t.   A_i v = A_i v*_i   for every higher level i   (keep what level i achieved)
           lo ≤ v_j ≤ hi      (joint position and velocity limits, at every level)

The equalities are eliminated rather than passed to the QP: with ``N`` an orthonormal basis of
the null space of the stacked higher-level matrices and ``v*`` the previous level's solution,
``v = v* + N z`` satisfies them for any ``z``. Level k is then a problem in ``z`` with bounds only,
``z = 0`` is feasible by construction, and the problems shrink as the stack descends. A
rank-revealing (column-pivoted) QR of the small projected matrix ``(A_k N)ᵀ`` gives both the
level's exact minimum-norm solution (when ``A_k N`` has full row rank) and the next ``N``. When
that solution breaks a bound, the level is met exactly by the smallest step within the bounds
that does (a QP with the level as equalities), if there is one. When there is none, or the level
is rank-deficient, or it is the last level, the level is the least-squares QP with the
regularization μ (which keeps its Hessian positive definite); quadprog is skipped when the QP's
unconstrained minimizer (a Cholesky solve) already meets every bound. The returned ``v`` is
clipped to the bounds, so limits hold exactly and higher levels hold to solver tolerance.

Fast path, tried first: when every level but the last can be met exactly within the bounds (the
usual case: feet and balance tasks are reachable), the hierarchy's solution is the minimizer of
the last level on ``{v : E v = f, lo ≤ v ≤ hi}`` (E, f the stacked higher levels). With the set
``B`` of the bounds it lies on known, that is one KKT system, ``S_B`` selecting those dofs and
``β`` their bounds::

    [G    Eᵀ  S_Bᵀ] [ v]   [a]
    [E    0   0   ] [−λ] = [f],    G = A_Lᵀ A_L + μ I,  a = A_Lᵀ b_L
    [S_B  0   0   ] [−ν]   [β]

``B`` is guessed as the bounds that held the last solution (a reaching arm stays on its bounds
for many ticks): those with a nonzero multiplier, or those a level-by-level solution lay on. The
solution is accepted when it is the optimum: the other bounds met, each ``ν_j`` of the sign that
holds its joint against its bound (the QP's KKT conditions), the higher levels met (relative
residual ≤ ``EXACT_TOL``). Otherwise a few primal-dual active-set steps (drop the
bounds of the wrong sign, add the ones broken, solve again) are tried; failing those (a higher
level out of reach, a singular system) the levels are solved one by one as above. Both give the
same solution where both apply.

A solve is :meth:`~HierarchicalQP.prepare` (bounds, kinematics, every task's rows, the KKT matrix
factorized: all that depends on ``q``) then :meth:`~HierarchicalQP.finish`, which may first
re-read the right-hand sides of tasks whose targets were set in between. A controller prepares
while the robot moves and finishes once the measured state has given it its last targets. For
that, prepare also solves the KKT system for the prepared targets and, for the higher-level tasks
named ``retargetable``, for a unit change of each of their rows: ``v = v₀ + Z δf``, so a finish
whose new targets only change those rows of ``f`` by ``δf`` costs a small product instead of a
solve (equal to the direct solve up to rounding); the same for the active bounds' values ``β``,
which bounds known only at finish (``tighter``) may change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import quadprog
from scipy.linalg import lapack

from robot_ctrl.sot.joint_limits import JointLimits, LimitViolation
from robot_ctrl.sot.task import Task

BOUND_SLACK = 1e-10  # [rad/s] relaxation of the bounds inside each QP (see solve)
EXACT_TOL = 1e-9  # relative residual of the higher levels that the fast path must reach
ACTIVE_TOL = 1e-9  # [rad/s] a solution this close to a bound lies on it (the next tick's guess)
DUAL_TOL = 1e-10  # a multiplier of the wrong sign beyond this rejects an active set
ACTIVE_SET_STEPS = 3  # changes of the active set tried at finish before the level-by-level solve

_geqp3, _orgqr, _posv, _trtrs = lapack.dgeqp3, lapack.dorgqr, lapack.dposv, lapack.dtrtrs
_gesv, _getrs = lapack.dgesv, lapack.dgetrs
_NO_BOUNDS = (np.zeros(0, dtype=int), np.zeros(0, dtype=bool))  # an empty active set: (indices, upper)
_NO_VALUES = np.zeros(0)


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


@dataclass
class _Prepared:
    """A solve up to the point where the tasks' targets enter (see :meth:`HierarchicalQP.prepare`)."""

    model: pin.Model
    data: pin.Data
    q: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    levels: list[list[Task]]
    stacked: list[tuple[np.ndarray, np.ndarray]]
    spans: dict[Task, tuple[int, slice]]  # each task's level and rows in it
    fast: _FastPath | None  # when the KKT matrix factorized


@dataclass
class _FastPath:
    """The fast path's KKT system solved at prepare, with the bounds held active (``active``, indices
    into the limits' dofs, at their upper bound where ``upper``) as equalities ``v_j = β_j``. Its
    unknowns kept, ``w = [v; y]``: the velocity and, per active bound, minus its multiplier. For a
    change ``δf`` of a retargetable task's rows of ``f``, ``w = w0 + Z[task] δf``; for a change
    ``δβ`` of the active bounds' values (bounds tightened at finish), ``w += Zb δβ``."""

    E: np.ndarray  # (m, nv) stacked higher levels
    f: np.ndarray  # (m,)
    K: np.ndarray  # (nv + m, nv + m) the KKT matrix without bound rows, for another active set
    active: np.ndarray
    upper: np.ndarray
    beta: np.ndarray  # the active bounds' values at prepare
    keep: slice | np.ndarray  # the rows of the KKT solution that make w
    w0: np.ndarray  # (nv + len(active),)
    Z: dict[Task, tuple[slice, np.ndarray]]  # the task's rows in f, and their (len(w), rows) block
    Zb: np.ndarray  # (len(w), len(active))
    lu: tuple[np.ndarray, np.ndarray]  # LU factors and pivots of the KKT matrix with the bound rows


class HierarchicalQP:
    def __init__(self, levels: list[list[Task]], limits: JointLimits, regularization: float = 1e-5,
                 rank_tol: float = 1e-8):
        self.levels = levels
        self.limits = limits
        self.mu = regularization
        self.rank_tol = rank_tol
        self.last: list[LevelResult] = []
        self._prepared: _Prepared | None = None
        # The bounds that held the last solution (indices into the limits' dofs, upper side): the fast
        # path's first guess of the active set, which moves little from one tick to the next.
        self._active = _NO_BOUNDS

    def solve(self, model: pin.Model, data: pin.Data, q: np.ndarray, dt: float,
              previous: np.ndarray | None = None) -> np.ndarray:
        """Velocity ``v`` (nv) for one step of ``dt`` seconds from configuration ``q``; ``previous``:
        the last step's velocity (nv), for the joints' acceleration limits (None: none applied)."""
        self.prepare(model, data, q, dt, previous=previous)
        return self.finish()

    def prepare(self, model: pin.Model, data: pin.Data, q: np.ndarray, dt: float,
                retargetable: tuple[Task, ...] = (), previous: np.ndarray | None = None) -> None:
        """First half of :meth:`solve`: the bounds, the kinematics at ``q`` (in ``data``, which must
        not be recomputed at another configuration before :meth:`finish`), each active task's rows
        for its current target and the fast path's KKT matrix, factorized and solved, also for
        changes of the ``retargetable`` tasks' targets (module docstring)."""
        self._prepared = None
        if not np.all(np.isfinite(q)):
            raise InfeasibleError(0, "configuration contains NaN or inf")
        try:
            lo, hi = self.limits.bounds(q, dt, None if previous is None else previous[self.limits.v_index])
        except LimitViolation as exc:
            raise InfeasibleError(0, str(exc)) from exc
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        levels = [tasks for tasks in ([t for t in level if t.active] for level in self.levels) if tasks]
        stacked, spans = [], {}
        for k, tasks in enumerate(levels):
            rows = [t.rows(model, data, q) for t in tasks]
            start = 0
            for task, (_, b) in zip(tasks, rows):
                spans[task] = (k, slice(start, start + len(b)))
                start += len(b)
            stacked.append(_stack(rows))
        self.last = [LevelResult([t.name for t in tasks], False, A, b) for tasks, (A, b) in zip(levels, stacked)]
        fast = self._fast_path(stacked, spans, retargetable, lo, hi)
        self._prepared = _Prepared(model, data, q, lo, hi, levels, stacked, spans, fast)

    def finish(self, retargeted: tuple[Task, ...] = (),
               tighter: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Second half of :meth:`solve`, after ``retargeted`` tasks (active ones of the prepared
        stack) got new targets: their rows are read again, at the prepared configuration.
        ``tighter``: bounds ``(lo, hi)`` on the limits' dofs known only now (from a measured state),
        intersected with the prepared ones; where they disagree, the prepared (position) bounds win."""
        p, self._prepared = self._prepared, None
        if p is None:
            raise RuntimeError("HierarchicalQP.finish without prepare")
        stacked = list(p.stacked)
        fast = p.fast
        w = None if fast is None else fast.w0
        f = None if fast is None else fast.f
        for task in retargeted:
            if task not in p.spans:
                raise ValueError(f"task {task.name!r} is not an active task of the prepared stack")
            k, rows = p.spans[task]
            b = stacked[k][1].copy()
            b[rows] = task.rhs(p.model, p.data, p.q)
            if w is not None:
                if task in fast.Z:
                    at, Z = fast.Z[task]
                    w = w + Z @ (b[rows] - stacked[k][1][rows])
                    f = f.copy()
                    f[at] = b[rows]
                else:
                    w = None  # not prepared for: solve the KKT system again
            stacked[k] = (stacked[k][0], b)
            self.last[k].b = b
        lo, hi, bounded = p.lo, p.hi, self.limits.v_index
        if tighter is not None:
            lo, hi = np.clip(np.maximum(lo, tighter[0]), lo, hi), np.clip(np.minimum(hi, tighter[1]), lo, hi)
        if fast is not None:
            beta = np.where(fast.upper, hi[fast.active], lo[fast.active]) if fast.active.size else _NO_VALUES
            A, b = stacked[-1]
            if w is None:
                f = np.concatenate([b for _, b in stacked[:-1]])
                w = _getrs(*fast.lu, np.concatenate([A.T @ b, f, beta]))[0][fast.keep]
            elif fast.active.size:
                w = w + fast.Zb @ (beta - fast.beta)
            v = self._accepted(w, fast.active, fast.upper, beta, fast.E, f, lo, hi)
            if v is None:
                v = self._change_active_set(w, fast, A.T @ b, f, lo, hi)
            if v is not None:
                return v
        v = np.zeros(p.model.nv)
        N = None  # basis of the directions the higher levels leave free; None = identity
        for k, (tasks, (A, b)) in enumerate(zip(p.levels, stacked)):
            AN = A if N is None else A @ N
            r = b - A @ v
            last = k == len(p.levels) - 1
            z = None
            if not last:
                qr = _PivotedQR(AN, self.rank_tol)
                z = qr.min_norm_solution(r)
                if z is not None and not _meets_bounds(v[bounded], z, N, bounded, lo, hi):
                    z = self._exact_level(AN, r, N, v, lo, hi, bounded)
                    self.last[k].used_qp = z is not None
            if z is None:
                G = AN.T @ AN
                G.flat[:: G.shape[0] + 1] += self.mu
                a = AN.T @ r - self.mu * (v if N is None else N.T @ v)
                z, self.last[k].used_qp = self._solve_level(k, tasks, G, a, N, v[bounded], lo, hi, bounded)
            v = v + (z if N is None else N @ z)
            if not last:
                N = qr.null_space(N)
                if N.shape[1] == 0:
                    break
        v[bounded] = np.clip(v[bounded], lo, hi)
        return self._remember_active(v, lo, hi)

    def _remember_active(self, v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """``v`` of the level-by-level solve, the bounds it lies on remembered as the fast path's guess."""
        vb = v[self.limits.v_index]
        at_hi = vb >= hi - ACTIVE_TOL
        active = np.flatnonzero(at_hi | (vb <= lo + ACTIVE_TOL))
        self._active = (active, at_hi[active])
        return v

    def _accepted(self, w, active, upper, beta, E, f, lo, hi) -> np.ndarray | None:
        """The velocity of the KKT solution ``w``, if it is the hierarchy's: the active bounds'
        multipliers of the right sign, the other bounds met, the higher levels met exactly. Then
        the bounds that bind (a multiplier beyond ``DUAL_TOL``) are the next tick's guess."""
        n = w.size - active.size
        v, y = w[:n], w[n:]  # y: minus the multipliers, ≥ 0 at an upper bound, ≤ 0 at a lower one
        if active.size:
            if ((y < -DUAL_TOL) & upper).any() or ((y > DUAL_TOL) & ~upper).any():
                return None
            v = v.copy()
            v[self.limits.v_index[active]] = beta  # on the bound, not a rounding beyond it
        if not self._meets_higher_levels(v, E, f, lo, hi, self.limits.v_index):
            return None
        if active.size:
            binding = np.abs(y) > DUAL_TOL
            self._active = (active[binding], upper[binding])
        else:
            self._active = _NO_BOUNDS
        return v

    def _change_active_set(self, w, fast: _FastPath, a, f, lo, hi) -> np.ndarray | None:
        """Primal-dual active-set steps from the prepared guess: drop the bounds whose multiplier
        has the wrong sign, add those the solution breaks, solve again; None after
        ``ACTIVE_SET_STEPS`` steps or on a singular system (the levels are then solved one by one)."""
        bounded, active, upper = self.limits.v_index, fast.active, fast.upper
        n = fast.K.shape[0] - fast.E.shape[0]
        for _ in range(ACTIVE_SET_STEPS):
            y = w[n:]
            stays = ~(((y < -DUAL_TOL) & upper) | ((y > DUAL_TOL) & ~upper))
            vb = w[:n][bounded]
            free = np.ones(bounded.size, dtype=bool)
            free[active] = False
            over, under = free & (vb > hi), free & (vb < lo)
            if stays.all() and not (over.any() or under.any()):
                return None
            added = np.flatnonzero(over | under)
            active = np.concatenate([active[stays], added])
            upper = np.concatenate([upper[stays], over[added]])
            beta = np.where(upper, hi[active], lo[active])
            M = _with_bound_rows(fast.K, bounded[active])
            _, _, x, info = _gesv(M, np.concatenate([a, f, beta]), overwrite_a=1, overwrite_b=1)
            if info != 0:
                return None
            w = np.concatenate([x[:n], x[fast.K.shape[0]:]])
            v = self._accepted(w, active, upper, beta, fast.E, f, lo, hi)
            if v is not None:
                return v
        return None

    def _fast_path(self, stacked, spans, retargetable, lo, hi, guess: bool = True) -> _FastPath | None:
        """The fast path's KKT matrix (module docstring), with the last solution's active bounds as
        equalities, factorized and solved for the prepared targets, for unit changes of the
        ``retargetable`` tasks' rows of ``f`` and of the active bounds' values (without them if that
        ``guess`` makes the matrix singular); None when the stack has one level or the matrix is
        singular."""
        if len(stacked) < 2:
            return None
        E = np.vstack([A for A, _ in stacked[:-1]])
        f = np.concatenate([b for _, b in stacked[:-1]])
        A, b = stacked[-1]
        n, m = A.shape[1], E.shape[0]
        K = np.zeros((n + m, n + m))
        K[:n, :n] = A.T @ A
        K.flat[: n * (n + m + 1) : n + m + 1] += self.mu  # μ on G's diagonal
        K[:n, n:] = E.T
        K[n:, :n] = E
        active, upper = self._active if guess else _NO_BOUNDS
        nb = active.size
        beta = np.where(upper, hi[active], lo[active]) if nb else _NO_VALUES
        blocks = {}  # task -> its rows in f
        for task in retargetable:
            k, rows = spans.get(task, (len(stacked) - 1, None))
            if k < len(stacked) - 1:
                start = sum(len(b) for _, b in stacked[:k])
                blocks[task] = slice(start + rows.start, start + rows.stop)
        rhs = np.zeros((n + m + nb, 1 + sum(at.stop - at.start for at in blocks.values()) + nb))
        rhs[:n, 0] = A.T @ b
        rhs[n:n + m, 0] = f
        if nb:
            rhs[n + m:, 0] = beta
        column, Z = 1, {}
        for task, at in blocks.items():
            for row in range(at.start, at.stop):
                rhs[n + row, column + row - at.start] = 1.0
            Z[task] = (at, slice(column, column + at.stop - at.start))
            column = Z[task][1].stop
        if nb:
            rhs[n + m + np.arange(nb), column + np.arange(nb)] = 1.0
            M, scratch = _with_bound_rows(K, self.limits.v_index[active]), 1
        else:
            M, scratch = K, 0
        # Factorized and solved in one call; K itself is kept (copied by LAPACK's wrapper when it is
        # M) for another active set at finish.
        lu, piv, x, info = _gesv(M, rhs, overwrite_a=scratch, overwrite_b=1)
        if info != 0:  # singular: with the guessed bounds, or without any
            return self._fast_path(stacked, spans, retargetable, lo, hi, guess=False) if nb else None
        keep = slice(0, n) if nb == 0 else np.concatenate([np.arange(n), np.arange(n + m, n + m + nb)])
        x = x[keep]
        return _FastPath(E, f, K, active, upper, beta, keep, x[:, 0],
                         {task: (at, x[:, cols]) for task, (at, cols) in Z.items()}, x[:, column:], (lu, piv))

    @staticmethod
    def _meets_higher_levels(v, E, f, lo, hi, bounded) -> bool:
        """The fast path's acceptance: ``v`` meets the bounds and ``E v = f`` to ``EXACT_TOL``."""
        vb = v[bounded]
        if not ((vb >= lo).all() and (vb <= hi).all()):
            return False
        r = E @ v - f
        return math.sqrt(r @ r) <= EXACT_TOL * (1.0 + math.sqrt(f @ f))

    @staticmethod
    def _exact_level(AN, r, N, v, lo, hi, bounded) -> np.ndarray | None:
        """A level met exactly within the bounds when its minimum-norm step breaks one: the
        smallest ``v + N z`` with ``A N z = r`` and the bounds (a QP with equalities); None when
        no step within the bounds meets it (the level is then solved as a least-squares QP)."""
        nz = AN.shape[1]
        Nb = np.eye(nz)[bounded] if N is None else N[bounded]
        vb = v[bounded]
        free = np.einsum("ij,ij->i", Nb, Nb) > 1e-20  # as in _solve_level
        Nb, vb = Nb[free], vb[free]
        C = np.hstack([AN.T, Nb.T, -Nb.T])
        c = np.concatenate([r, np.minimum(np.concatenate([lo[free] - vb, vb - hi[free]]), 0.0) - BOUND_SLACK])
        a = -(v if N is None else N.T @ v)
        try:
            return quadprog.solve_qp(np.eye(nz), a, C, c, AN.shape[0])[0]
        except ValueError:
            return None

    def _solve_level(self, k, tasks, G, a, N, vb, lo, hi, bounded) -> tuple[np.ndarray, bool]:
        _, z, info = _posv(G, a)
        if info == 0 and _meets_bounds(vb, z, N, bounded, lo, hi, BOUND_SLACK):
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


def _with_bound_rows(K: np.ndarray, dofs: np.ndarray) -> np.ndarray:
    """A new KKT matrix: ``K`` bordered by the equalities ``v_j = β_j`` for the velocity indices ``dofs``."""
    s, nb = K.shape[0], dofs.size
    M = np.zeros((s + nb, s + nb))
    M[:s, :s] = K
    M[s + np.arange(nb), dofs] = 1.0
    M[dofs, s + np.arange(nb)] = 1.0
    return M


def _meets_bounds(vb, z, N, bounded, lo, hi, slack: float = 0.0) -> bool:
    """Whether the bounded dofs of ``v + N z`` (``vb``: those of ``v``) lie in ``[lo − slack, hi + slack]``."""
    vz = vb + (z[bounded] if N is None else N[bounded] @ z)
    return bool(((vz >= lo - slack) & (vz <= hi + slack)).all())


def _stack(rows: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """One level's ``(A, b)`` from its tasks' rows."""
    if len(rows) == 1:
        return rows[0]
    return np.vstack([r[0] for r in rows]), np.concatenate([r[1] for r in rows])


class _PivotedQR:
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
