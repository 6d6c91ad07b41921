"""KKTFastPath: the whole stack of tasks as one KKT system, tried before the level-by-level solve.

When every level but the last can be met exactly within the bounds (the usual case: feet and
balance tasks are reachable), the hierarchy's solution is the minimizer of the last level on
``{v : E v = f, lo ≤ v ≤ hi}`` (E, f the stacked higher levels). With the set ``B`` of the bounds
it lies on known, that is one KKT system, ``S_B`` selecting those dofs and ``β`` their bounds::

    [G    Eᵀ  S_Bᵀ] [ v]   [a]
    [E    0   0   ] [−λ] = [f],    G = A_Lᵀ A_L + μ I,  a = A_Lᵀ b_L
    [S_B  0   0   ] [−ν]   [β]

``B`` is guessed as the bounds that held the last solution (a reaching arm stays on its bounds
for many ticks): those with a nonzero multiplier, or those a level-by-level solution lay on. The
solution is accepted when it is the optimum: the other bounds met, each ``ν_j`` of the sign that
holds its joint against its bound (the QP's KKT conditions), the higher levels met (relative
residual ≤ ``EXACT_TOL``). Otherwise a few primal-dual active-set steps (drop the bounds of the
wrong sign, add the ones broken, solve again) are tried; failing those (a higher level out of
reach, a singular system) :class:`~robot_ctrl.sot.solver.HierarchicalQP` solves the levels one by
one. Both give the same solution where both apply.

The system is solved at prepare, also for a unit change of each row of ``f`` that a
``retargetable`` task owns and of each active bound's value: ``w = w₀ + Z δf + Z_β δβ``, so a
finish whose new targets only move those rows (the stabilizer's CoM), or whose measured state
only tightens those bounds, costs a small product instead of a solve (equal to the direct solve
up to rounding).

The first level (the feet) is eliminated before the solve, which leaves a system with m₁ fewer
unknowns and m₁ fewer multipliers (32 + bounds instead of 56 + bounds for Talos). With ``E₁``
its m₁ rows, ``P`` the m₁ columns it determines (the legs' joints, ``E₁[:, P]`` invertible), ``C``
the floating base's columns and ``F`` the others (which ``E₁`` does not touch)::

    E₁ v = f₁  ⇔  v_P = t_P − X v_C,    [X | t_P] = E₁[:, P]⁻¹ [E₁[:, C] | f₁]

so ``v = T y + t`` with ``y = [v_C; v_F]``, and the KKT system above is solved in ``y``: Hessian
``Tᵀ G T``, gradient ``Tᵀ(a − G t)``, the other levels' and the bounds' rows times ``T`` (a bound
on a leg joint becomes a row of ``−X``). Its solution is the same ``v``, and the bounds' multipliers
are the same, since ``E₁ T = 0``. Where ``E₁[:, P]`` is not square, or singular, the full system
is solved.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_ctrl.kernels import FLOAT, INDICES, MATRIX, VECTOR, kernel
from robot_ctrl.sot.task import Task

EXACT_TOL = 1e-9  # relative residual of the higher levels that the fast path must reach
ACTIVE_TOL = 1e-9  # [rad/s] a solution this close to a bound lies on it (the next tick's guess)
DUAL_TOL = 1e-10  # a multiplier of the wrong sign beyond this rejects an active set
ACTIVE_SET_STEPS = 3  # changes of the active set tried at finish before the level-by-level solve

#: Bounds held active: indices into the limits' dofs, and whether each is its upper bound.
ActiveSet = tuple[np.ndarray, np.ndarray]
NO_BOUNDS: ActiveSet = (np.zeros(0, dtype=int), np.zeros(0, dtype=bool))
_NO_VALUES = np.zeros(0)
_NO_ROWS = np.zeros(0, dtype=np.int64)
#: The first level's elimination (module docstring): the velocity indices ``P``, ``C`` and ``F``.
Elimination = tuple[np.ndarray, np.ndarray, np.ndarray]


def no_elimination(nv: int) -> Elimination:
    """Nothing eliminated: every column free, the full system."""
    return _NO_ROWS, _NO_ROWS, np.arange(nv, dtype=np.int64)


def first_level_elimination(first: np.ndarray, base_nv: int) -> Elimination:
    """The columns ``P``, ``C``, ``F`` that eliminate the first level's rows ``first`` (m₁, nv):
    ``P`` the columns beyond the floating base's ``base_nv`` that it touches, when there are m₁ of
    them; :func:`no_elimination` otherwise."""
    touched = np.abs(first).sum(axis=0) > 0
    touched[:base_nv] = False
    eliminated = np.flatnonzero(touched)
    if eliminated.size != first.shape[0]:
        return no_elimination(first.shape[1])
    others = np.flatnonzero(~touched)
    return eliminated, others[others < base_nv], others[others >= base_nv]



@dataclass
class KKTFastPath:
    """The KKT system solved at prepare, with the bounds ``active`` (at their upper bound where
    ``upper``) held as equalities ``v_j = β_j``. Its unknowns kept, ``w = [v; y]``: the velocity
    and, per active bound, minus its multiplier. For a change ``δf`` of a retargetable task's rows
    of ``f``, ``w = w0 + Z[task] δf``; for a change ``δβ`` of the active bounds' values (bounds
    tightened at finish), ``w += Zb δβ``."""

    E: np.ndarray  # (m, nv) stacked higher levels
    f: np.ndarray  # (m,)
    A: np.ndarray  # (p, nv) the last level, for another active set
    mu: float
    bounded: np.ndarray  # the velocity indices of the limits' dofs
    active: np.ndarray
    upper: np.ndarray
    beta: np.ndarray  # the active bounds' values at prepare
    w0: np.ndarray  # (nv + len(active),)
    Z: dict[Task, tuple[slice, np.ndarray]]  # the task's rows in f, and their (len(w), rows) block
    Zb: np.ndarray  # (len(w), len(active))
    elimination: Elimination  # of the first level, as solved

    @classmethod
    def prepare(cls, stacked, higher, spans, retargetable, lo, hi, bounded, mu: float,
                guess: ActiveSet, elimination: Elimination) -> KKTFastPath | None:
        """The KKT matrix of the levels ``stacked`` (their ``(A, b)``; ``higher``: all but the last
        stacked into one ``(E, f)``; ``spans``: each task's level and rows), with the ``guess`` of
        active bounds as equalities (without them if that makes the matrix singular), factorized
        and solved for the prepared targets, for unit changes of the ``retargetable`` tasks' rows
        of ``f`` and of the active bounds' values, with the first level eliminated by
        ``elimination`` (solved in full if that block is singular); None when the stack has one
        level or the matrix is singular."""
        if len(stacked) < 2:
            return None
        E, f = higher
        A, b = stacked[-1]
        active, upper = guess
        nb = active.size
        beta = np.where(upper, hi[active], lo[active]) if nb else _NO_VALUES
        Z, unit_rows, column = {}, [], 1  # task -> its rows in f, and their columns in the right-hand sides
        for task in retargetable:
            k, rows = spans.get(task, (len(stacked) - 1, None))
            if k < len(stacked) - 1:
                start = sum(len(b) for _, b in stacked[:k])
                at = slice(start + rows.start, start + rows.stop)
                Z[task] = (at, slice(column, column + at.stop - at.start))
                unit_rows.extend(range(at.start, at.stop))
                column = Z[task][1].stop
        try:
            x = kkt_solution(E, f, A, b, mu, bounded[active] if nb else _NO_ROWS, beta,
                             np.array(unit_rows, dtype=np.int64) if unit_rows else _NO_ROWS, *elimination)
        except np.linalg.LinAlgError:  # singular: the eliminated block, the guessed bounds, or the system
            full = no_elimination(A.shape[1])
            if elimination[0].size:
                return cls.prepare(stacked, higher, spans, retargetable, lo, hi, bounded, mu, guess, full)
            if not nb:
                return None
            return cls.prepare(stacked, higher, spans, retargetable, lo, hi, bounded, mu, NO_BOUNDS, full)
        return cls(E, f, A, mu, bounded, active, upper, beta, x[:, 0],
                   {task: (at, x[:, cols]) for task, (at, cols) in Z.items()}, x[:, column:], elimination)

    def solve(self, w: np.ndarray | None, f: np.ndarray, stacked, lo, hi) -> tuple[np.ndarray, ActiveSet] | None:
        """The velocity for the final targets and bounds, and the bounds that bind it (the next
        tick's guess); None when it is not the hierarchy's solution. ``w``: the prepared unknowns
        moved by the retargeted rows, None to solve the system again for ``stacked``; ``f``: the
        higher levels' right-hand side as it stands."""
        beta = np.where(self.upper, hi[self.active], lo[self.active]) if self.active.size else _NO_VALUES
        A, b = stacked[-1]
        if w is None:
            f = np.concatenate([b for _, b in stacked[:-1]])
            try:
                w = kkt_solution(self.E, f, A, b, self.mu, self.bounded[self.active], beta, _NO_ROWS,
                                 *self.elimination)[:, 0]
            except np.linalg.LinAlgError:
                return None
        elif self.active.size:
            w = w + self.Zb @ (beta - self.beta)
        solved = self._accepted(w, self.active, self.upper, beta, f, lo, hi)
        return solved if solved is not None else self._change_active_set(w, b, f, lo, hi)

    def _accepted(self, w, active, upper, beta, f, lo, hi) -> tuple[np.ndarray, ActiveSet] | None:
        """The velocity of the KKT solution ``w`` and its binding bounds (a multiplier beyond
        ``DUAL_TOL``), if it is the hierarchy's: the active bounds' multipliers of the right sign,
        the other bounds met, the higher levels met exactly."""
        n = w.size - active.size
        v, y = w[:n], w[n:]  # y: minus the multipliers, ≥ 0 at an upper bound, ≤ 0 at a lower one
        if active.size:
            if ((y < -DUAL_TOL) & upper).any() or ((y > DUAL_TOL) & ~upper).any():
                return None
            v = v.copy()
            v[self.bounded[active]] = beta  # on the bound, not a rounding beyond it
        if not meets_higher_levels(v, self.E, f, lo, hi, self.bounded):
            return None
        if not active.size:
            return v, NO_BOUNDS
        binding = np.abs(y) > DUAL_TOL
        return v, (active[binding], upper[binding])

    def _change_active_set(self, w, b, f, lo, hi) -> tuple[np.ndarray, ActiveSet] | None:
        """Primal-dual active-set steps from the prepared guess: drop the bounds whose multiplier
        has the wrong sign, add those the solution breaks, solve again; None after
        ``ACTIVE_SET_STEPS`` steps or on a singular system."""
        bounded, active, upper = self.bounded, self.active, self.upper
        n = self.A.shape[1]
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
            try:
                w = kkt_solution(self.E, f, self.A, b, self.mu, bounded[active], beta, _NO_ROWS,
                                 *self.elimination)[:, 0]
            except np.linalg.LinAlgError:
                return None
            solved = self._accepted(w, active, upper, beta, f, lo, hi)
            if solved is not None:
                return solved
        return None


@kernel((VECTOR, MATRIX, VECTOR, VECTOR, VECTOR, INDICES))
def meets_higher_levels(v, E, f, lo, hi, bounded) -> bool:
    """The fast path's acceptance: ``v`` meets the bounds and ``E v = f`` to ``EXACT_TOL``
    (relative). Compiled, as :func:`kkt_solution`."""
    for k in range(bounded.size):
        if not lo[k] <= v[bounded[k]] <= hi[k]:
            return False
    r = E @ v - f
    return math.sqrt(r @ r) <= EXACT_TOL * (1.0 + math.sqrt(f @ f))


def bounds_lain_on(v: np.ndarray, lo: np.ndarray, hi: np.ndarray, bounded: np.ndarray) -> ActiveSet:
    """The bounds a (level-by-level) solution ``v`` lies on, within ``ACTIVE_TOL``: the fast path's
    next guess."""
    vb = v[bounded]
    at_hi = vb >= hi - ACTIVE_TOL
    active = np.flatnonzero(at_hi | (vb <= lo + ACTIVE_TOL))
    return active, at_hi[active]


@kernel((MATRIX, VECTOR, MATRIX, VECTOR, FLOAT, INDICES, VECTOR, INDICES, INDICES, INDICES, INDICES))
def kkt_solution(E, f, A, b, mu, dofs, beta, unit_rows, eliminated, coupled, free):
    """The solution ``x`` of the KKT system of the module docstring, ``S_B`` selecting the velocity
    indices ``dofs``, for the right-hand sides ``[Aᵀb; f; β]``, then a unit column for each row
    of ``f`` in ``unit_rows``, then one for each bound; of ``x``, the rows of ``v`` and of the
    bounds' multipliers (those of the higher levels' are not needed). The first level is
    eliminated by the columns ``eliminated``, ``coupled``, ``free`` (``P``, ``C``, ``F``): the
    unknowns ``y = [v_C; v_F]``, ``v_P = t_P − X v_C``; with ``P`` and ``C`` empty
    (:func:`no_elimination`) it is the full system. Raises ``LinAlgError`` when a matrix it
    factorizes is singular (:func:`lu_solve`). Compiled: in numpy, the calls would cost more than
    the arithmetic."""
    n, m, nb, r = A.shape[1], E.shape[0], dofs.size, unit_rows.size
    m1, nc, nf = eliminated.size, coupled.size, free.size
    k, m2, p, cols = nc + nf, m - m1, A.shape[0], 1 + r + nb
    at = np.empty(n, dtype=np.int64)  # each dof's index in y, or −1 − its index in P
    for i in range(nc):
        at[coupled[i]] = i
    for i in range(nf):
        at[free[i]] = nc + i
    for i in range(m1):
        at[eliminated[i]] = -1 - i
    # [X | t_P] = E₁[:, P]⁻¹ [E₁[:, C] | f₁ and its unit columns]
    B = np.empty((m1, m1))
    rhs1 = np.zeros((m1, nc + cols))
    for i in range(m1):
        for j in range(m1):
            B[i, j] = E[i, eliminated[j]]
        for j in range(nc):
            rhs1[i, j] = E[i, coupled[j]]
        rhs1[i, nc] = f[i]
    for q in range(r):
        if unit_rows[q] < m1:
            rhs1[unit_rows[q], nc + 1 + q] = 1.0
    solved = lu_solve(B, rhs1) if m1 else rhs1  # [X | t_P]: X = solved[:, :nc], t_P = solved[:, nc:]
    # The last level's and the other higher levels' rows: W = [A; E₂] T, and Wt = [A; E₂]_P t_P.
    # Written as loops: they skip the zeros of the rows on P, and compile in a fraction of the time
    # that numpy's products and slice assignments of every layout take.
    W = np.empty((p + m2, k))
    Wt = np.zeros((p + m2, cols))
    for i in range(p + m2):
        row = A[i] if i < p else E[m1 + i - p]
        for j in range(nc):
            W[i, j] = row[coupled[j]]
        for j in range(nf):
            W[i, nc + j] = row[free[j]]
        for j in range(m1):
            w = row[eliminated[j]]
            if w != 0.0:
                for c in range(nc):
                    W[i, c] -= w * solved[j, c]
                for c in range(cols):
                    Wt[i, c] += w * solved[j, nc + c]
    AT = W[:p]
    s = k + m2 + nb
    M = np.zeros((s, s))
    rhs = np.zeros((s, cols))
    # Tᵀ G T = (A T)ᵀ (A T) + μ (I + Xᵀ X on C); Tᵀ(a − G t) = (A T)ᵀ (b − A_P t_P) + μ Xᵀ t_P.
    gram = AT.T @ AT
    for a in range(k):
        for c in range(k):
            M[a, c] = gram[a, c]
        M[a, a] += mu
    for j in range(m1):
        for a in range(nc):
            x = mu * solved[j, a]
            for c in range(nc):
                M[a, c] += x * solved[j, c]
            for c in range(cols):
                rhs[a, c] += x * solved[j, nc + c]
    for i in range(p):
        for c in range(k):
            x = AT[i, c]
            if x != 0.0:
                rhs[c, 0] += x * (b[i] - Wt[i, 0])
                for q in range(1, cols):
                    rhs[c, q] -= x * Wt[i, q]
    for i in range(m2):
        for c in range(k):
            M[k + i, c] = M[c, k + i] = W[p + i, c]
        rhs[k + i, 0] = f[m1 + i] - Wt[p + i, 0]
        for q in range(1, cols):
            rhs[k + i, q] = -Wt[p + i, q]
    for q in range(r):
        if unit_rows[q] >= m1:
            rhs[k + unit_rows[q] - m1, 1 + q] += 1.0
    for q in range(nb):
        d, row = at[dofs[q]], k + m2 + q
        if d >= 0:
            M[row, d] = 1.0
            M[d, row] = 1.0
        else:  # a leg joint: v_j = t_j − X_j v_C
            for j in range(nc):
                M[row, j] = M[j, row] = -solved[-1 - d, j]
            for c in range(cols):
                rhs[row, c] -= solved[-1 - d, nc + c]
        rhs[row, 0] += beta[q]
        rhs[row, 1 + r + q] += 1.0
    y = lu_solve(M, rhs)
    kept = np.empty((n + nb, cols))
    for j in range(n):
        d = at[j]
        for c in range(cols):
            if d >= 0:
                kept[j, c] = y[d, c]
            else:
                x = solved[-1 - d, nc + c]
                for i in range(nc):
                    x -= solved[-1 - d, i] * y[i, c]
                kept[j, c] = x
    for q in range(nb):
        for c in range(cols):
            kept[n + q, c] = y[k + m2 + q, c]
    return kept


@kernel()
def lu_solve(A, B):
    """``X`` with ``A X = B`` (``A`` square, ``B`` its columns of right-hand sides), by Gaussian
    elimination with partial pivoting (LAPACK's ``dgesv`` without its blocking); raises
    ``LinAlgError`` when a pivot is zero or not finite. Written out for :func:`kkt_solution`: at
    its sizes LAPACK's call (copies into Fortran order, checks) costs more than the arithmetic,
    and the elimination skips the zeros that its KKT matrices are mostly made of."""
    n, m = A.shape[0], B.shape[1]
    U, X = A.copy(), B.copy()
    for k in range(n):
        pivot, big = k, abs(U[k, k])
        for i in range(k + 1, n):
            if abs(U[i, k]) > big:
                pivot, big = i, abs(U[i, k])
        if not big > 0.0:
            raise np.linalg.LinAlgError("singular matrix")
        if pivot != k:
            for j in range(n):
                U[k, j], U[pivot, j] = U[pivot, j], U[k, j]
            for j in range(m):
                X[k, j], X[pivot, j] = X[pivot, j], X[k, j]
        for i in range(k + 1, n):
            factor = U[i, k] / U[k, k]
            if factor != 0.0:
                for j in range(k + 1, n):
                    U[i, j] -= factor * U[k, j]
                for j in range(m):
                    X[i, j] -= factor * X[k, j]
    for k in range(n - 1, -1, -1):
        for j in range(m):
            x = X[k, j]
            for i in range(k + 1, n):
                x -= U[k, i] * X[i, j]
            X[k, j] = x / U[k, k]
    return X
