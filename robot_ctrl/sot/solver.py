"""HierarchicalQP: strict-priority stack of tasks, solved level by level after a one-KKT fast path.

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

Tried first, the fast path (:class:`~robot_ctrl.sot.kkt_fast_path.KKTFastPath`) solves the whole
stack as one KKT system when the higher levels can be met exactly within the bounds; it gives the
same solution where both apply.

A solve is :meth:`~HierarchicalQP.prepare` (bounds, kinematics, every task's rows, the KKT matrix
factorized: all that depends on ``q``) then :meth:`~HierarchicalQP.finish`, which may first
re-read the right-hand sides of tasks whose targets were set in between. A controller prepares
while the robot moves and finishes once the measured state has given it its last targets. For
that, prepare also solves the KKT system for the prepared targets and for unit changes of the
``retargetable`` tasks' rows, so that a finish whose new targets only move those rows costs a
small product instead of a solve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import quadprog
from scipy.linalg import lapack

from robot_ctrl.kernels import VECTOR, kernel
from robot_ctrl.sot.joint_limits import JointLimits, LimitViolation
from robot_ctrl.sot.kkt_fast_path import NO_BOUNDS, Elimination, KKTFastPath, bounds_lain_on, first_level_elimination
from robot_ctrl.sot.pivoted_qr import PivotedQR
from robot_ctrl.sot.task import Task

BOUND_SLACK = 1e-10  # [rad/s] relaxation of the bounds inside each QP (see solve)

_posv = lapack.dposv


class InfeasibleError(RuntimeError):
    """The QP of a level has no solution, or the configuration lies outside the hard joint limits.
    ``level`` is the failing level's index."""

    def __init__(self, level: int, message: str):
        super().__init__(f"IK level {level}: {message}")
        self.level = level


@dataclass(frozen=True)
class _Layout:
    """Where the active tasks' rows lie, all stacked in priority order in one buffer that each
    prepare overwrites: each level's rows, each task's level and rows in it, and how the fast path
    eliminates the first level. It changes only when a task is switched on or off."""

    tasks: list[list[Task]]  # the active tasks of each non-empty level
    levels: list[slice]
    spans: dict[Task, tuple[int, slice]]
    writes: list[tuple[Task, np.ndarray, np.ndarray]]  # each active task and its rows' (A, b) in the buffer
    stacked: list[tuple[np.ndarray, np.ndarray]]  # each level's (A, b), views of the buffer
    higher: tuple[np.ndarray, np.ndarray]  # all levels but the last, one view
    elimination: Elimination

    @classmethod
    def of(cls, levels: list[list[Task]], active: list[Task], model: pin.Model, data: pin.Data,
           q: np.ndarray) -> _Layout:
        """``levels``: every task by level; ``active``: the active ones; the first level's rows at
        ``q`` (``data`` prepared as for a solve) decide its elimination."""
        tasks = [on for on in ([t for t in level if t in active] for level in levels) if on]
        size = sum(t.size for t in active)
        A_all, b_all = np.zeros((size, model.nv)), np.zeros(size)
        slices, spans, writes, start = [], {}, [], 0
        for k, level in enumerate(tasks):
            first = start
            for task in level:
                spans[task] = (k, slice(start - first, start - first + task.size))
                writes.append((task, A_all[start:start + task.size], b_all[start:start + task.size]))
                start += task.size
            slices.append(slice(first, start))
        for task, A, b in writes[:len(tasks[0])]:
            task.write_rows(model, data, q, A, b)
        base = model.joints[1] if model.njoints > 1 else None
        base_nv = base.nv if base is not None and base.shortname() == "JointModelFreeFlyer" else 0
        m = slices[-1].start
        return cls(tasks, slices, spans, writes, [(A_all[level], b_all[level]) for level in slices],
                   (A_all[:m], b_all[:m]), first_level_elimination(A_all[slices[0]], base_nv))


@dataclass
class _Prepared:
    """A solve up to the point where the tasks' targets enter (see :meth:`HierarchicalQP.prepare`)."""

    model: pin.Model
    data: pin.Data
    q: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    layout: _Layout
    fast: KKTFastPath | None  # when the KKT matrix factorized


class HierarchicalQP:
    def __init__(self, levels: list[list[Task]], limits: JointLimits, regularization: float = 1e-5,
                 rank_tol: float = 1e-8):
        self.levels = levels
        self._tasks = [task for level in levels for task in level]
        self.limits = limits
        self.mu = regularization
        self.rank_tol = rank_tol
        self._prepared: _Prepared | None = None
        # The bounds that held the last solution (indices into the limits' dofs, upper side): the fast
        # path's first guess of the active set, which moves little from one tick to the next.
        self._active = NO_BOUNDS
        self._layouts: dict[tuple, _Layout] = {}  # by nv and the active tasks (a task's number of rows is fixed)

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
        try:
            lo, hi = self.limits.bounds(q, dt, None if previous is None else previous[self.limits.v_index])
        except LimitViolation as exc:
            raise InfeasibleError(0, str(exc)) from exc
        pin.computeJointJacobians(model, data, q)  # frame tasks update their frames' placements
        layout = self._layout(model, data, q, [t for t in self._tasks if t.active])
        # Every task writes its rows into the layout's buffer; each level, and the higher levels
        # together, are views of it.
        for task, A, b in layout.writes:
            task.write_rows(model, data, q, A, b)
        self._prepared = _Prepared(model, data, q, lo, hi, layout, self._fast_path(layout, retargetable, lo, hi))

    def finish(self, retargeted: tuple[Task, ...] = (),
               tighter: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Second half of :meth:`solve`, after ``retargeted`` tasks (active ones of the prepared
        stack) got new targets: their rows are read again, at the prepared configuration.
        ``tighter``: bounds ``(lo, hi)`` on the limits' dofs known only now (from a measured state),
        intersected with the prepared ones; where they disagree, the prepared (position) bounds win."""
        p, self._prepared = self._prepared, None
        if p is None:
            raise RuntimeError("HierarchicalQP.finish without prepare")
        stacked = list(p.layout.stacked)
        fast = p.fast
        w = None if fast is None else fast.w0
        f = None if fast is None else fast.f
        for task in retargeted:
            if task not in p.layout.spans:
                raise ValueError(f"task {task.name!r} is not an active task of the prepared stack")
            k, rows = p.layout.spans[task]
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
        lo, hi, bounded = p.lo, p.hi, self.limits.v_index
        if tighter is not None:
            lo, hi = intersected_bounds(lo, hi, tighter[0], tighter[1])
        if fast is not None:
            solved = fast.solve(w, f, stacked, lo, hi)
            if solved is not None:
                v, self._active = solved
                return v
        v = np.zeros(p.model.nv)
        N = None  # basis of the directions the higher levels leave free; None = identity
        for k, (tasks, (A, b)) in enumerate(zip(p.layout.tasks, stacked)):
            AN = A if N is None else A @ N
            r = b - A @ v
            last = k == len(p.layout.tasks) - 1
            z = None
            if not last:
                qr = PivotedQR(AN, self.rank_tol)
                z = qr.min_norm_solution(r)
                if z is not None and not _meets_bounds(v[bounded], z, N, bounded, lo, hi):
                    z = self._exact_level(AN, r, N, v, lo, hi, bounded)
            if z is None:
                G = AN.T @ AN
                G.flat[:: G.shape[0] + 1] += self.mu
                a = AN.T @ r - self.mu * (v if N is None else N.T @ v)
                z = self._solve_level(k, tasks, G, a, N, v[bounded], lo, hi, bounded)
            v = v + (z if N is None else N @ z)
            if not last:
                N = qr.null_space(N)
                if N.shape[1] == 0:
                    break
        v[bounded] = np.clip(v[bounded], lo, hi)
        self._active = bounds_lain_on(v, lo, hi, bounded)
        return v

    def _layout(self, model: pin.Model, data: pin.Data, q: np.ndarray, tasks: list[Task]) -> _Layout:
        key = (model.nv, *tasks)
        layout = self._layouts.get(key)
        if layout is None:
            layout = self._layouts[key] = _Layout.of(self.levels, tasks, model, data, q)
        return layout

    def _fast_path(self, layout: _Layout, retargetable, lo, hi) -> KKTFastPath | None:
        return KKTFastPath.prepare(layout.stacked, layout.higher, layout.spans, retargetable, lo, hi,
                                   self.limits.v_index, self.mu, self._active, layout.elimination)

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

    def _solve_level(self, k, tasks, G, a, N, vb, lo, hi, bounded) -> np.ndarray:
        _, z, info = _posv(G, a)
        if info == 0 and _meets_bounds(vb, z, N, bounded, lo, hi, BOUND_SLACK):
            return z
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
        return z


def _meets_bounds(vb, z, N, bounded, lo, hi, slack: float = 0.0) -> bool:
    """Whether the bounded dofs of ``v + N z`` (``vb``: those of ``v``) lie in ``[lo − slack, hi + slack]``."""
    vz = vb + (z[bounded] if N is None else N[bounded] @ z)
    return bool(((vz >= lo - slack) & (vz <= hi + slack)).all())


@kernel((VECTOR, VECTOR, VECTOR, VECTOR))
def intersected_bounds(lo, hi, tighter_lo, tighter_hi):
    """``[lo, hi] ∩ [tighter_lo, tighter_hi]`` per dof (``lo ≤ hi``), ``[lo, hi]`` winning where the
    two do not meet: ``(min(max(lo, tl), hi), max(min(hi, th), lo))``, NaN propagated as numpy's
    ``maximum``/``minimum`` do. Compiled: it runs on the tick's serial path."""
    new_lo, new_hi = np.empty_like(lo), np.empty_like(hi)
    for j in range(lo.size):
        new_lo[j] = np.minimum(np.maximum(lo[j], tighter_lo[j]), hi[j])
        new_hi[j] = np.maximum(np.minimum(hi[j], tighter_hi[j]), lo[j])
    return new_lo, new_hi
