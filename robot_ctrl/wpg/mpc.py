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

from dataclasses import dataclass, field

import casadi as ca
import daqp
import numpy as np

from robot_ctrl.geometry import rotation
from robot_ctrl.kernels import MATRIX, STACK, VECTOR, kernel
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

    @classmethod
    def of(cls, H: list[np.ndarray], h: list[np.ndarray], anchors: list[FootRef], zmp_from: list[FootRef],
           zmp_to: list[FootRef], s: list[float]) -> SampleSupports:
        """From each sample's polygon ``(H, h)`` (``MAX_EDGES`` rows) anchored at ``anchors``, and its
        reference ZMP at the fraction ``s`` of the way from ``zmp_from`` to ``zmp_to``."""
        s = np.array(s)[:, None]
        # np.array of a list of equal arrays: numpy's np.stack costs three times as much here.
        ref_S = (1 - s)[:, :, None] * np.array([a.S for a in zmp_from]) + s[:, :, None] * np.array([b.S for b in zmp_to])
        ref_offset = (1 - s) * np.array([a.offset for a in zmp_from]) + s * np.array([b.offset for b in zmp_to])
        return cls(np.array(H), np.array(h), np.array([a.S for a in anchors]), np.array([a.offset for a in anchors]),
                   ref_S, ref_offset)


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
        self._Mvu = np.zeros((2 * N, 2 * N))
        self._Mvu[:N, :N] = self._Mvu[N:, N:] = self.m.Pvu
        self._Mzu = np.zeros((2 * N, 2 * N))
        self._Mzu[:N, :N] = self._Mzu[N:, N:] = self.m.Pzu
        self._H_const = np.zeros((self.nw, self.nw))
        self._H_const[: 2 * N, : 2 * N] = (p.w_velocity * self._Mvu.T @ self._Mvu
                                           + p.w_zmp * self._Mzu.T @ self._Mzu + p.w_jerk * np.eye(2 * N))
        self._H_const[2 * N :, 2 * N :] = p.w_footstep * np.eye(4)

    def solve(self, prob: MpcProblem) -> MpcSolution:
        self._set_sample_time(prob.sample_time or self.p.sample_time)
        H, g, A, lba, uba = self.assemble(prob)
        w = self._solve_direct(H, g, A, lba, uba) if self.solver is None else self._solve_casadi(H, g, A, lba, uba)
        Aw = A @ w
        violation = max((Aw - uba).max(), (lba - Aw).max())
        if violation > 1e-5:
            raise MpcInfeasible(f"walking QP solution violates its constraints by {violation:.2e}")
        N = self.N
        if self.solver is not None:  # warm start of a CasADi plugin for the next sample: the jerks shifted by one
            self._x0 = np.concatenate([w[1:N], w[N - 1 : N], w[N + 1 : 2 * N], w[2 * N - 1 : 2 * N], w[2 * N :]])
        Ux, Uy, F = w[:N], w[N : 2 * N], w[2 * N :]
        m = self.m
        zmp = np.array([m.Pzs @ prob.com_x + m.Pzu @ Ux, m.Pzs @ prob.com_y + m.Pzu @ Uy]).T
        com = np.array([m.Pps @ prob.com_x + m.Ppu @ Ux, m.Pps @ prob.com_y + m.Ppu @ Uy]).T
        return MpcSolution(Ux, Uy, F, zmp, com)

    def _solve_direct(self, H, g, A, lba, uba) -> np.ndarray:
        used = np.isfinite(lba) | np.isfinite(uba)  # a support with fewer edges leaves rows unbounded
        sense = np.where(lba[used] == uba[used], _DAQP_EQUALITY, 0).astype(np.intc)
        w, _, exitflag, info = daqp.solve(H, g, A[used], uba[used], lba[used], sense)
        self.last_stats = {"success": exitflag in _DAQP_OPTIMAL, "return_status": f"daqp exit flag {exitflag}",
                           "iterations": info["iterations"]}
        if exitflag not in _DAQP_OPTIMAL or not np.all(np.isfinite(w)):
            raise MpcInfeasible(f"walking QP failed: daqp exit flag {exitflag}")
        return w

    def _solve_casadi(self, H, g, A, lba, uba) -> np.ndarray:
        # CasADi converts Python lists faster than numpy arrays.
        res = self.solver(h=ca.DM(self._sp_h, H.ravel(order="F").tolist()), g=g.tolist(),
                          a=ca.DM(self._sp_a, A.ravel(order="F").tolist()), lba=lba.tolist(), uba=uba.tolist(),
                          x0=self._x0.tolist(), lam_a0=self._lam_a0.tolist(), lam_x0=self._lam_x0.tolist())
        self.last_stats = self.solver.stats()
        w = np.asarray(res["x"]).ravel()
        if not self.last_stats.get("success", False) or not np.all(np.isfinite(w)):
            raise MpcInfeasible(f"walking QP failed: {self.last_stats.get('return_status')}")
        self._lam_a0 = np.asarray(res["lam_a"]).ravel()
        self._lam_x0 = np.asarray(res["lam_x"]).ravel()
        return w

    def assemble(self, prob: MpcProblem):
        """Dense QP ``min ½ wᵀHw + gᵀw  s.t. lba ≤ A w ≤ uba`` of one sample."""
        p, m, N, nu = self.p, self.m, self.N, 2 * self.N
        zs = np.stack([m.Pzs @ prob.com_x, m.Pzs @ prob.com_y], axis=1)  # (N, 2) ZMP drift without jerk
        # ZMP residual Z − Z_ref(F) = [Mzu, −S_ref] w + bz and velocity residual Ẋ − Ẋ_ref = [Mvu, 0] w + bv,
        # x rows then y rows.
        sup = prob.supports
        S_ref = np.concatenate([sup.zmp_ref_S[:, 0], sup.zmp_ref_S[:, 1]])  # (2N, 4)
        off_ref = sup.zmp_ref_offset
        bz = (zs - off_ref).T.ravel()
        bv = np.concatenate([m.Pvs @ prob.com_x, m.Pvs @ prob.com_y]) - prob.velocity_ref.T.ravel()
        H = self._H_const.copy()
        H[:nu, nu:] = -p.w_zmp * self._Mzu.T @ S_ref
        H[nu:, :nu] = H[:nu, nu:].T
        H[nu:, nu:] += p.w_zmp * S_ref.T @ S_ref
        g = np.empty(self.nw)
        g[:nu] = p.w_velocity * self._Mvu.T @ bv + p.w_zmp * self._Mzu.T @ bz
        g[nu:] = -p.w_zmp * S_ref.T @ bz - p.w_footstep * prob.footstep_nominal

        A = np.zeros((self.nc, self.nw))
        lba = np.full(self.nc, -np.inf)
        uba = np.full(self.nc, np.inf)
        # ZMP rows, MAX_EDGES per sample (unused rows stay zero and unbounded): H_j (Z_j − a_j − S_j F) ≤ h_j.
        _zmp_rows(sup.H, sup.h, m.Pzu, sup.anchor_S, sup.anchor_offset, zs, A, uba)
        row = rows = MAX_EDGES * N
        for r in prob.reach:
            Rt = rotation(r.previous.yaw).T
            A[row : row + 2, nu:] = Rt @ (_select(r.index) - r.previous.S)
            rhs = Rt @ r.previous.offset
            lba[row : row + 2] = [r.box[0] + rhs[0], r.box[2] + rhs[1]]
            uba[row : row + 2] = [r.box[1] + rhs[0], r.box[3] + rhs[1]]
            row += 2
        row = rows + 8
        for index, ref in prob.fixed.items():
            A[row : row + 2, nu:] = _select(index) - ref.S
            lba[row : row + 2] = uba[row : row + 2] = ref.offset
            row += 2
        return H, g, A, lba, uba


@kernel((STACK, MATRIX, MATRIX, STACK, MATRIX, MATRIX, MATRIX, VECTOR))
def _zmp_rows(Hs, hs, Pzu, S_anchor, off_anchor, zs, A, uba) -> None:
    """The ZMP rows of ``A`` and ``uba`` (the first ``MAX_EDGES N``), row ``(j, e)`` for edge ``e``
    of sample ``j``: ``H_je [Pzu_j Ux, Pzu_j Uy] − H_je S_j F ≤ h_je + H_je (a_j − z_j)`` (``z_j``
    the ZMP drift ``zs``, ``a_j`` the anchor offset). Compiled: numpy's broadcasting and reshapes
    cost more than these few thousand products."""
    N, edges = Hs.shape[0], Hs.shape[1]
    for j in range(N):
        for e in range(edges):
            r = j * edges + e
            hx, hy = Hs[j, e, 0], Hs[j, e, 1]
            for i in range(N):
                A[r, i] = hx * Pzu[j, i]
                A[r, N + i] = hy * Pzu[j, i]
            for c in range(4):
                A[r, 2 * N + c] = -(hx * S_anchor[j, 0, c] + hy * S_anchor[j, 1, c])
            uba[r] = hs[j, e] + (hx * (off_anchor[j, 0] - zs[j, 0]) + hy * (off_anchor[j, 1] - zs[j, 1]))


def _select(index: int) -> np.ndarray:
    """2×4 selection of footstep ``index`` in F."""
    sel = np.zeros((2, 4))
    sel[0, 2 * index] = sel[1, 2 * index + 1] = 1.0
    return sel
