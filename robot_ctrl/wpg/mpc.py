"""WalkingMPC: the linear MPC of Herdt et al. (2010) with automatic footstep placement.

Decision vector ``w = [Ux (N), Uy (N), F (4)]``: CoM jerks over the horizon and the positions of
the next two footsteps ``F = [F1x, F1y, F2x, F2y]`` (world frame). Foot yaws are fixed before the
QP from the integrated yaw-rate reference (bounded per step), which keeps the problem a QP; this
is the decoupling Herdt et al. use, and the orientation part of Naveau et al. (2017) is reduced to
it. With the LIP predictions ``Ẋ = Pvs x̂ + Pvu U``, ``Z = Pzs x̂ + Pzu U`` (see ``lipm``)::

    min  α/2 ‖Ẋ − Ẋ_ref‖² + β/2 ‖Z − Z_ref(F)‖² + γ/2 ‖U‖² + ε/2 ‖F − F_nom‖²
    s.t. H_j (Z_j − a_j(F)) ≤ h_j           ZMP in the support polygon at every sample j
         R_pᵀ (F_i − p_i(F)) ∈ reach box     each footstep reachable from the previous foot
         F_i = b_i(F) where a footstep is fixed (stopping beside the other foot, or beyond the horizon)

Supports, references and anchors are affine in F (``FootRef``), so everything is linear.

QP solver: daqp (Arnström et al. 2022), a dual active-set solver for small dense QPs, called
directly through its Python binding with the numpy arrays and only the constraint rows in use:
CasADi's ``conic`` interface to the same solver cost more than the solve itself (converting the
dense H and A to CasADi matrices, then the call; docs/walking.md). ``WalkParams.solver`` selects a
CasADi ``conic`` plugin instead (``casadi-daqp``, ``qpoases``, ``osqp``, ``hpipm``), as
``benchmarks/bench_wpg.py --solvers`` does to compare them; daqp was chosen among them (the same
median as qpOASES, the lower p99, no licence banner; osqp's ADMM tolerance let the ZMP constraints
be violated, hpipm's interface rejected the dense constraint pattern).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import daqp
import numpy as np

from robot_ctrl.kernels import FLOAT, MATRIX, STACK, VECTOR, kernel
from robot_ctrl.wpg.footstep import FootRef
from robot_ctrl.wpg.lipm import horizon_matrices
from robot_ctrl.wpg.params import WalkParams
from robot_ctrl.wpg.segments import MAX_EDGES

DIRECT = "daqp"  # WalkParams.solver that calls daqp directly; any other names a CasADi conic plugin
_DAQP_EQUALITY = 5  # daqp's constraint sense for an equality row: active and immutable
_DAQP_OPTIMAL = (1, 2)  # daqp exit flags of an optimal solution (2: optimal, soft constraints violated)
_PLUGIN_OPTIONS = {
    "qpoases": {"printLevel": "none", "error_on_fail": False},
    "hpipm": {"hpipm": {"iter_max": 100}, "error_on_fail": False},
    "osqp": {"osqp": {"verbose": False, "eps_abs": 1e-6, "eps_rel": 1e-6, "max_iter": 4000}, "error_on_fail": False},
    "daqp": {"error_on_fail": False},
}


class MpcInfeasible(RuntimeError):
    """The walking QP has no solution for the given state and references."""


@dataclass
class SampleSupports:
    """The ZMP constraints and references of the horizon's ``N`` samples (world frame), as arrays:
    at sample ``j``, ``H[j] (z − anchor_j(F)) ≤ h[j]`` (rows beyond the polygon's edges: zero
    normals, ``h = ∞``), and the reference ZMP ``zmp_ref_j(F)``; each point affine in the footsteps,
    ``offset + S F`` (as a :class:`FootRef`)."""

    H: np.ndarray  # (N, MAX_EDGES, 2) outward normals
    h: np.ndarray  # (N, MAX_EDGES)
    anchor_S: np.ndarray  # (N, 2, 4)
    anchor_offset: np.ndarray  # (N, 2)
    zmp_ref_S: np.ndarray  # (N, 2, 4)
    zmp_ref_offset: np.ndarray  # (N, 2)


@dataclass
class Reach:
    """Footstep ``index`` must lie in ``box`` = (x_min, x_max, y_min, y_max) of ``previous``'s frame."""

    index: int
    previous: FootRef
    box: tuple[float, float, float, float]


@dataclass
class MpcProblem:
    """Everything one MPC solve needs (built by the pattern generator)."""

    com_x: np.ndarray  # (3,) [x, ẋ, ẍ]
    com_y: np.ndarray
    velocity_ref: np.ndarray  # (N, 2) world frame [m/s]
    supports: SampleSupports
    reach: list[Reach]
    fixed: dict[int, FootRef] = field(default_factory=dict)  # footstep index -> where it must be
    footstep_nominal: np.ndarray = field(default_factory=lambda: np.zeros(4))
    sample_time: float | None = None  # [s] physical sample length; None: WalkParams.sample_time


@dataclass(frozen=True)
class MpcSolution:
    jerk_x: np.ndarray  # (N,)
    jerk_y: np.ndarray
    footsteps: np.ndarray  # (4,) F
    zmp: np.ndarray  # (N, 2) predicted ZMP
    com: np.ndarray  # (N, 2) predicted CoM position


class WalkingMPC:
    def __init__(self, params: WalkParams):
        self.p = params
        N = params.horizon
        self.N = N
        self.nw = 2 * N + 4
        self.nc = MAX_EDGES * N + 8 + 4
        self._sp_h, self._sp_a = ca.Sparsity.dense(self.nw, self.nw), ca.Sparsity.dense(self.nc, self.nw)
        if params.solver == DIRECT:
            self.solver = None
        else:
            plugin = params.solver.removeprefix("casadi-")
            self.solver = ca.conic("wpg", plugin, {"h": self._sp_h, "a": self._sp_a}, _PLUGIN_OPTIONS.get(plugin, {}))
        self.sample_time = None
        self._set_sample_time(params.sample_time)
        self._x0 = np.zeros(self.nw)
        self._lam_a0 = np.zeros(self.nc)
        self._lam_x0 = np.zeros(self.nw)
        self.last_stats: dict = {}

    def _set_sample_time(self, T: float) -> None:
        """Prediction matrices and the constant cost parts for samples of ``T`` seconds."""
        if T == self.sample_time:
            return
        p, N = self.p, self.N
        self.sample_time = T
        self.m = horizon_matrices(T, N, p.com_height)
        # Constant parts of the cost: jerk-to-velocity and jerk-to-ZMP maps of both axes.
        Mvu, Mzu = np.zeros((2 * N, 2 * N)), np.zeros((2 * N, 2 * N))
        Mvu[:N, :N] = Mvu[N:, N:] = self.m.Pvu
        Mzu[:N, :N] = Mzu[N:, N:] = self.m.Pzu
        self._H_const = np.zeros((self.nw, self.nw))
        self._H_const[: 2 * N, : 2 * N] = p.w_velocity * Mvu.T @ Mvu + p.w_zmp * Mzu.T @ Mzu + p.w_jerk * np.eye(2 * N)
        self._H_const[2 * N :, 2 * N :] = p.w_footstep * np.eye(4)

    def solve(self, prob: MpcProblem) -> MpcSolution:
        self._set_sample_time(prob.sample_time or self.p.sample_time)
        H, g, A, lower, upper, sense, rows = self.assemble(prob)
        if self.solver is None:
            w = self._solve_direct(H, g, A, lower, upper, sense)
        else:
            w = self._solve_casadi(H, g, A, lower, upper, rows)
        violation = _violation(A, w, lower, upper)
        if violation > 1e-5:
            raise MpcInfeasible(f"walking QP solution violates its constraints by {violation:.2e}")
        N = self.N
        if self.solver is not None:  # warm start of a CasADi plugin for the next sample: the jerks shifted by one
            self._x0 = np.concatenate([w[1:N], w[N - 1 : N], w[N + 1 : 2 * N], w[2 * N - 1 : 2 * N], w[2 * N :]])
        m = self.m
        zmp = _predicted(m.Pzs, m.Pzu, prob.com_x, prob.com_y, w)
        com = _predicted(m.Pps, m.Ppu, prob.com_x, prob.com_y, w)
        return MpcSolution(w[:N], w[N : 2 * N], w[2 * N :], zmp, com)

    def _solve_direct(self, H, g, A, lower, upper, sense) -> np.ndarray:
        w, _, exitflag, info = daqp.solve(H, g, A, upper, lower, sense)
        self.last_stats = {"success": exitflag in _DAQP_OPTIMAL, "return_status": f"daqp exit flag {exitflag}",
                           "iterations": info["iterations"]}
        if exitflag not in _DAQP_OPTIMAL or not np.all(np.isfinite(w)):
            raise MpcInfeasible(f"walking QP failed: daqp exit flag {exitflag}")
        return w

    def _solve_casadi(self, H, g, A, lower, upper, rows) -> np.ndarray:
        # The plugin's constraint matrix has a fixed shape (nc rows): the rows in use go to their places.
        A_all, lba, uba = np.zeros((self.nc, self.nw)), np.full(self.nc, -np.inf), np.full(self.nc, np.inf)
        A_all[rows], lba[rows], uba[rows] = A, lower, upper
        # CasADi converts Python lists faster than numpy arrays.
        res = self.solver(h=ca.DM(self._sp_h, H.ravel(order="F").tolist()), g=g.tolist(),
                          a=ca.DM(self._sp_a, A_all.ravel(order="F").tolist()), lba=lba.tolist(), uba=uba.tolist(),
                          x0=self._x0.tolist(), lam_a0=self._lam_a0.tolist(), lam_x0=self._lam_x0.tolist())
        self.last_stats = self.solver.stats()
        w = np.asarray(res["x"]).ravel()
        if not self.last_stats.get("success", False) or not np.all(np.isfinite(w)):
            raise MpcInfeasible(f"walking QP failed: {self.last_stats.get('return_status')}")
        self._lam_a0 = np.asarray(res["lam_a"]).ravel()
        self._lam_x0 = np.asarray(res["lam_x"]).ravel()
        return w

    def assemble(self, prob: MpcProblem):
        """Dense QP ``min ½ wᵀHw + gᵀw  s.t. lower ≤ A w ≤ upper`` of one sample: ``(H, g, A, lower,
        upper, sense, rows)`` with only the constraint rows in use (a support of fewer than
        ``MAX_EDGES`` edges leaves rows out), ``sense`` daqp's for each (equality for a fixed
        footstep) and ``rows`` their places among the ``nc`` rows of the whole layout (``_qp``)."""
        p, m, sup = self.p, self.m, prob.supports
        reach = np.empty((len(prob.reach), 16))
        for row, r in zip(reach, prob.reach):
            row[0], row[1], row[2:4] = r.index, r.previous.yaw, r.previous.offset
            row[4:8], row[8:] = r.box, r.previous.S.ravel()
        fixed = np.empty((len(prob.fixed), 11))
        for row, (index, ref) in zip(fixed, prob.fixed.items()):
            row[0], row[1:3], row[3:] = index, ref.offset, ref.S.ravel()
        return _qp(self._H_const, m.Pzs, m.Pzu, m.Pvs, m.Pvu, prob.com_x, prob.com_y, prob.velocity_ref, sup.H, sup.h,
                   sup.anchor_S, sup.anchor_offset, sup.zmp_ref_S, sup.zmp_ref_offset, prob.footstep_nominal, reach,
                   fixed, p.w_velocity, p.w_zmp, p.w_footstep)


@kernel((MATRIX, MATRIX, MATRIX, MATRIX, MATRIX, VECTOR, VECTOR, MATRIX, STACK, MATRIX, STACK, MATRIX, STACK, MATRIX,
         VECTOR, MATRIX, MATRIX, FLOAT, FLOAT, FLOAT))
def _qp(H_const, Pzs, Pzu, Pvs, Pvu, com_x, com_y, velocity_ref, Hs, hs, anchor_S, anchor_offset, ref_S, ref_offset,
        nominal, reach, fixed, w_velocity, w_zmp, w_footstep):
    """The QP of the module docstring for :meth:`WalkingMPC.assemble`. Per axis ``a`` (x rows, then
    y rows), the ZMP residual ``Z − Z_ref(F) = Pzu U_a − S_ref,a F + bz_a`` with ``bz_a = Pzs x̂_a −
    offset_ref,a`` and the velocity residual ``Ẋ − Ẋ_ref = Pvu U_a + bv_a`` with ``bv_a = Pvs x̂_a −
    Ẋ_ref,a``; ``H_const`` holds the jerk-only and footstep-only parts. Constraint rows, in use only:

    - ZMP, edge ``e`` of sample ``j`` (``h_je`` finite): ``H_je [Pzu_j U_x, Pzu_j U_y] − H_je S_j F ≤
      h_je + H_je (a_j − z_j)``, ``z_j`` the ZMP drift ``Pzs x̂``, ``a_j`` the anchor offset (row
      ``MAX_EDGES j + e`` of the layout);
    - reach, per row of ``reach`` (index, yaw, offset (2), box (4), S (8) of the previous foot):
      ``box_lo + Rᵀ p ≤ Rᵀ (F_i − S F) ≤ box_hi + Rᵀ p``, ``R`` the previous foot's yaw and ``p`` its
      offset (rows ``MAX_EDGES N + 2 r``);
    - fixed, per row of ``fixed`` (index, offset (2), S (8)): ``F_i − S F = offset``, equalities (rows
      ``MAX_EDGES N + 8 + 2 k``).

    Compiled: numpy's calls on these few dozen rows cost more than the arithmetic."""
    N = Pzu.shape[0]
    nu, nw = 2 * N, 2 * N + 4
    com = (com_x, com_y)
    zs, bz, bv = np.empty((2, N)), np.empty((2, N)), np.empty((2, N))  # zs: the ZMP drift Pzs x̂ without jerk
    for a in range(2):
        for j in range(N):
            zs[a, j] = Pzs[j, 0] * com[a][0] + Pzs[j, 1] * com[a][1] + Pzs[j, 2] * com[a][2]
            bz[a, j] = zs[a, j] - ref_offset[j, a]
            bv[a, j] = Pvs[j, 0] * com[a][0] + Pvs[j, 1] * com[a][1] + Pvs[j, 2] * com[a][2] - velocity_ref[j, a]
    H = H_const.copy()
    g = np.empty(nw)
    for a in range(2):
        for i in range(N):
            gi = 0.0
            for j in range(N):
                gi += w_velocity * Pvu[j, i] * bv[a, j] + w_zmp * Pzu[j, i] * bz[a, j]
            g[a * N + i] = gi
            for c in range(4):
                hic = 0.0
                for j in range(N):
                    hic -= w_zmp * Pzu[j, i] * ref_S[j, a, c]
                H[a * N + i, nu + c] = H[nu + c, a * N + i] = hic
    for c in range(4):
        gc = -w_footstep * nominal[c]
        for d in range(4):
            hcd = 0.0
            for a in range(2):
                for j in range(N):
                    hcd += w_zmp * ref_S[j, a, c] * ref_S[j, a, d]
            H[nu + c, nu + d] += hcd
        for a in range(2):
            for j in range(N):
                gc -= w_zmp * ref_S[j, a, c] * bz[a, j]
        g[nu + c] = gc

    nc = MAX_EDGES * N + 8 + 4
    A, lower, upper = np.zeros((nc, nw)), np.full(nc, -np.inf), np.full(nc, np.inf)
    sense, rows = np.zeros(nc, dtype=np.int32), np.empty(nc, dtype=np.int64)
    m = 0
    for j in range(N):
        for e in range(Hs.shape[1]):
            if not math.isfinite(hs[j, e]):
                continue
            hx, hy = Hs[j, e, 0], Hs[j, e, 1]
            for i in range(N):
                A[m, i] = hx * Pzu[j, i]
                A[m, N + i] = hy * Pzu[j, i]
            for c in range(4):
                A[m, nu + c] = -(hx * anchor_S[j, 0, c] + hy * anchor_S[j, 1, c])
            upper[m] = hs[j, e] + (hx * (anchor_offset[j, 0] - zs[0, j]) + hy * (anchor_offset[j, 1] - zs[1, j]))
            rows[m] = MAX_EDGES * j + e
            m += 1
    for r in range(reach.shape[0]):
        index, cos, sin = int(reach[r, 0]), math.cos(reach[r, 1]), math.sin(reach[r, 1])
        Rt = ((cos, sin), (-sin, cos))
        for b in range(2):
            for c in range(4):
                A[m + b, nu + c] = (Rt[b][0] * ((1.0 if c == 2 * index else 0.0) - reach[r, 8 + c])
                                    + Rt[b][1] * ((1.0 if c == 2 * index + 1 else 0.0) - reach[r, 12 + c]))
            rhs = Rt[b][0] * reach[r, 2] + Rt[b][1] * reach[r, 3]
            lower[m + b], upper[m + b] = reach[r, 4 + 2 * b] + rhs, reach[r, 5 + 2 * b] + rhs
            rows[m + b] = MAX_EDGES * N + 2 * r + b
        m += 2
    for k in range(fixed.shape[0]):
        index = int(fixed[k, 0])
        for b in range(2):
            for c in range(4):
                A[m + b, nu + c] = (1.0 if c == 2 * index + b else 0.0) - fixed[k, 3 + 4 * b + c]
            lower[m + b] = upper[m + b] = fixed[k, 1 + b]
            sense[m + b] = _DAQP_EQUALITY
            rows[m + b] = MAX_EDGES * N + 8 + 2 * k + b
        m += 2
    return H, g, A[:m].copy(), lower[:m].copy(), upper[:m].copy(), sense[:m].copy(), rows[:m].copy()


@kernel((MATRIX, VECTOR, VECTOR, VECTOR))
def _violation(A, w, lower, upper) -> float:
    """How far ``A w`` lies outside ``[lower, upper]`` at most (≤ 0 within)."""
    worst = -np.inf
    for r in range(A.shape[0]):
        Aw = 0.0
        for c in range(w.size):
            Aw += A[r, c] * w[c]
        worst = max(worst, Aw - upper[r], lower[r] - Aw)
    return worst


@kernel((MATRIX, MATRIX, VECTOR, VECTOR, VECTOR))
def _predicted(Ps, Pu, com_x, com_y, w):
    """``[Ps x̂_x + Pu U_x, Ps x̂_y + Pu U_y]`` (N, 2): a predicted trajectory of both axes, ``U_x``
    and ``U_y`` the first ``2 N`` entries of ``w``."""
    N = Pu.shape[0]
    out = np.empty((N, 2))
    for a, com in enumerate((com_x, com_y)):
        for j in range(N):
            x = Ps[j, 0] * com[0] + Ps[j, 1] * com[1] + Ps[j, 2] * com[2]
            for i in range(N):
                x += Pu[j, i] * w[a * N + i]
            out[j, a] = x
    return out
