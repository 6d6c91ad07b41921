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

The system is factorized and solved at prepare, also for a unit change of each row of ``f`` that
a ``retargetable`` task owns and of each active bound's value: ``w = w₀ + Z δf + Z_β δβ``, so a
finish whose new targets only move those rows (the stabilizer's CoM), or whose measured state
only tightens those bounds, costs a small product instead of a solve (equal to the direct solve
up to rounding).
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
    M: np.ndarray  # the KKT matrix with the bound rows, to solve again for other targets

    @classmethod
    def prepare(cls, stacked, higher, spans, retargetable, lo, hi, bounded, mu: float,
                guess: ActiveSet) -> KKTFastPath | None:
        """The KKT matrix of the levels ``stacked`` (their ``(A, b)``; ``higher``: all but the last
        stacked into one ``(E, f)``; ``spans``: each task's level and rows), with the ``guess`` of
        active bounds as equalities (without them if that makes the matrix singular), factorized
        and solved for the prepared targets, for unit changes of the ``retargetable`` tasks' rows
        of ``f`` and of the active bounds' values; None when the stack has one level or the matrix
        is singular."""
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
            M, x = kkt_solution(E, f, A, b, mu, bounded[active] if nb else _NO_ROWS, beta,
                                np.array(unit_rows, dtype=np.int64) if unit_rows else _NO_ROWS)
        except np.linalg.LinAlgError:  # singular: with the guessed bounds, or without any
            return cls.prepare(stacked, higher, spans, retargetable, lo, hi, bounded, mu, NO_BOUNDS) if nb else None
        return cls(E, f, A, mu, bounded, active, upper, beta, x[:, 0],
                   {task: (at, x[:, cols]) for task, (at, cols) in Z.items()}, x[:, column:], M)

    def solve(self, w: np.ndarray | None, f: np.ndarray, stacked, lo, hi) -> tuple[np.ndarray, ActiveSet] | None:
        """The velocity for the final targets and bounds, and the bounds that bind it (the next
        tick's guess); None when it is not the hierarchy's solution. ``w``: the prepared unknowns
        moved by the retargeted rows, None to solve the factorized system again for ``stacked``;
        ``f``: the higher levels' right-hand side as it stands."""
        beta = np.where(self.upper, hi[self.active], lo[self.active]) if self.active.size else _NO_VALUES
        A, b = stacked[-1]
        if w is None:
            f = np.concatenate([b for _, b in stacked[:-1]])
            n, m = A.shape[1], f.size
            w = np.linalg.solve(self.M, np.concatenate([A.T @ b, f, beta]))
            w = np.concatenate([w[:n], w[n + m:]])
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
                w = kkt_solution(self.E, f, self.A, b, self.mu, bounded[active], beta, _NO_ROWS)[1][:, 0]
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


@kernel((MATRIX, VECTOR, MATRIX, VECTOR, FLOAT, INDICES, VECTOR, INDICES))
def kkt_solution(E, f, A, b, mu, dofs, beta, unit_rows):
    """The KKT matrix ``M`` of the module docstring, ``S_B`` selecting the velocity indices
    ``dofs``, and its solution ``x`` for the right-hand sides ``[Aᵀb; f; β]``, then a unit column
    for each row of ``f`` in ``unit_rows``, then one for each bound; of ``x``, the rows of ``v``
    and of the bounds' multipliers (those of the higher levels' are not needed). Raises
    ``LinAlgError`` when ``M`` is singular. Compiled: in numpy, the calls would cost more than the
    arithmetic."""
    n, m, nb, r = A.shape[1], E.shape[0], dofs.size, unit_rows.size
    s = n + m + nb
    M = np.zeros((s, s))
    M[:n, :n] = A.T @ A
    for i in range(n):
        M[i, i] += mu
    M[n:n + m, :n] = E
    M[:n, n:n + m] = E.T
    for k in range(nb):
        M[n + m + k, dofs[k]] = 1.0
        M[dofs[k], n + m + k] = 1.0
    rhs = np.zeros((s, 1 + r + nb))
    rhs[:n, 0] = A.T @ b
    rhs[n:n + m, 0] = f
    rhs[n + m:, 0] = beta
    for k in range(r):
        rhs[n + unit_rows[k], 1 + k] = 1.0
    for k in range(nb):
        rhs[n + m + k, 1 + r + k] = 1.0
    x = np.linalg.solve(M, rhs)
    kept = np.empty((n + nb, x.shape[1]))
    kept[:n] = x[:n]
    kept[n:] = x[n + m:]
    return M, kept
