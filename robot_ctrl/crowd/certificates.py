"""Contraction certificates for coupled gaits (thesis 4.3-4.4, conference/journal papers).

Each applicable sufficient condition is returned as a :class:`Condition` with its margin
(left-hand side minus right-hand side: > 0 holds) and the guaranteed minimum convergence rate
[1/s] when it holds. Graph quantities: λ⁺ and λ_max of the symmetric Laplacian part projected on
the complement of the synchronization manifold (see ``CouplingGraph``); g(φ) the gait's speed
profile (forward speed over a cycle, normalized or not), given as samples over one cycle.

- ``hopf_diffusive`` (thesis 4.3.4, eq. 4.25, Table 4.1): Andronov-Hopf oscillators with diffusive
  state coupling ``ẋ_i = f(x_i) + k Σ_j A_ij (x_j − x_i)`` contract to synchrony if
  ``k λ⁺ > sup λ_max(∂f/∂x)_s = 1``; rate ``k λ⁺ − 1``. For named topologies λ⁺ is Table 4.1's
  closed form; otherwise the projected symmetrized Jacobian ``V (D(x) − k L⊗I₂)_s Vᵀ`` is evaluated
  on sampled oscillator states (r = 0, where λ_max(∂f/∂x)_s = 1 is attained, included).
- ``phase_coupling`` (4.3.2, scenario 1 of 4.4.2): ``φ̇ = ω − k L φ``; holds for ``k λ⁺ > 0``, rate ``k λ⁺``.
- ``leader_group`` (4.3.7, eq. 4.27): followers ``ẋ = f(x) − k L x − α (x − x̃₀)``; the thesis gives
  ``λ_min(k L + α I) > 1`` and, for all-to-all followers, ``k N + α > 1`` with rate ``k N + α``. On
  the full follower space λ_min(k L_s + α I) = α (L has the eigenvalue 0 along 1), so we certify
  ``λ_min(k L_s + α I) > 1`` with rate ``λ_min − 1`` and report the thesis's all-to-all form as a
  second line (it bounds the followers' mutual synchronization, on 1⊥).
- ``step_frequency`` (scenario 2, conference eq. 2): ``φ̇ = ω₀ 1 − m_d (L G(φ) + c)``. All-to-all:
  rate ``m_d min g λ⁺`` for m_d > 0, g > 0. General symmetric graphs: the weak condition
  ``λ⁺_min / λ⁺_max > max|g − ḡ| / ḡ`` and the strong one (thesis Theorem 6)
  ``(1 − a)²/(1 + a)² + (1 − b)²/(1 + b)² < 1``, a = λ⁺_min/λ⁺_max, b = min g / max g; other graphs:
  the projected symmetrized Jacobian ``−m_d V (L D_g)_s Vᵀ`` over sampled g values.
- ``lowpass_filter`` (journal/paper 003): with ``ż = −α z + G(φ)``, ``α > sqrt(m_d max g λ_max(L_s))``.
- ``step_length`` (scenario 3): ``ż = ω g(φ)(1 − m_z (L z + c))``; rate ``ρ_z = m_z ω min g λ⁺`` with ω the
  lowest gait frequency (``omega``, 1 by default as in the thesis); with phase coupling the overall
  rate is ``min(ρ_φ, ρ_z)``.
- ``heading_consensus`` (journal eq. 12): ``ψ̇_i = ω_i (sin(χ − ψ_i) + g_ψ)`` contracts for any
  consensus signal χ while |χ − ψ_i| < π/2 (Jacobian −ω cos(χ − ψ_i)); over a heading spread Δ < π/2
  the rate is ``m_ψ ω cos Δ``.
- ``heading_goal_region`` (thesis 4.4.3, eqs. 4.34-4.38): one agent steering to a goal direction,
  ``ψ̇ = −m_ψ sin(ψ − ψ_goal) g(ψ)`` with any g > 0, is contracting in the metric
  ``Θ = 1/(g (1 + cos(ψ − ψ_goal)))`` on the whole region |ψ − ψ_goal| < π, rate m_ψ min g (g = 1 here).
- ``schoener_dose`` (thesis 4.4.3, eq. 4.45): sine diffusive coupling ``ψ̇_i = −k Σ_j A_ij sin(ψ_i − ψ_j)``
  (headings, or gait phases coupled by their sine) is partially contracting where every coupled
  difference stays below π/2 (diagonal dominance, ‖·‖∞). Its Jacobian is ``−k L(W)``, the Laplacian
  with weights ``A_ij cos(ψ_i − ψ_j) ≥ A_ij cos Δ``; for a symmetric graph ``L(W) − cos Δ L`` is a
  Laplacian with non-negative weights, so the rate inside a spread Δ is at least ``k λ⁺ cos Δ``
  (our derivation from the thesis's Jacobian). Asymmetric graphs: the projected symmetrized
  Jacobian over sampled angle sets of spread ≤ Δ. Outside the region the potential
  U = −k Σ A_ij cos(ψ_i − ψ_j) (eq. 4.40) still decreases: convergence without a guaranteed rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from robot_ctrl.crowd.coupling_graph import CouplingGraph, complement_basis


@dataclass(frozen=True)
class Condition:
    name: str
    statement: str
    holds: bool
    margin: float
    rate: float | None  # guaranteed minimum convergence rate [1/s], None if not guaranteed
    method: str

    def to_dict(self) -> dict:
        return {"name": self.name, "statement": self.statement, "holds": bool(self.holds),
                "margin": float(self.margin), "rate": None if self.rate is None else float(self.rate),
                "method": self.method}

    def line(self) -> str:
        rate = f"rate {self.rate:.4g} 1/s" if self.rate is not None else "no rate guaranteed"
        verdict = "holds" if self.holds else "violated"
        return f"{self.name:18s} {self.statement:40s} {verdict:8s} margin {self.margin:+.4g}  {rate}  [{self.method}]"


@dataclass(frozen=True)
class CouplingConfig:
    graph: CouplingGraph
    k: float | None = None  # phase / state coupling strength
    alpha: float | None = None  # leader coupling strength
    m_d: float | None = None  # step-frequency (distance) coupling
    m_z: float | None = None  # step-length coupling
    m_psi: float | None = None  # heading coupling
    k_sine: float | None = None  # sine diffusive coupling of angles (Schöner-Dose, eq. 4.45)
    lowpass: float | None = None  # position low-pass filter constant α (with m_d)
    heading_spread: float = np.pi / 4  # [rad] largest |χ − ψ_i| (or coupled |ψ_i − ψ_j|) the sine certificates cover
    g: np.ndarray = field(default_factory=lambda: np.ones(1))  # speed profile samples over a cycle (> 0)
    omega: float = 1.0  # [rad/s] lowest gait frequency (step-length rate)
    samples: int = 200  # state samples for the numerical certificates
    seed: int = 0

    def __post_init__(self):
        for name in ("k", "alpha", "m_d", "m_z", "m_psi", "k_sine", "lowpass"):
            value = getattr(self, name)
            if value is not None and not np.isfinite(value):
                raise ValueError(f"{name} = {value} must be finite")
        g = np.asarray(self.g, dtype=float)
        if g.ndim != 1 or not np.all(np.isfinite(g)) or np.any(g <= 0):
            raise ValueError("g (speed profile) must be a 1-D array of finite values > 0")
        if not (np.isfinite(self.omega) and self.omega > 0):
            raise ValueError(f"omega = {self.omega} rad/s must be > 0")
        if not 0 < self.heading_spread < np.pi / 2:
            raise ValueError(f"heading_spread = {self.heading_spread} must be in (0, π/2) rad")


def certify(cfg: CouplingConfig) -> list[Condition]:
    """Every condition that applies to the given gains."""
    graph = cfg.graph
    out: list[Condition] = []
    if not graph.connected:
        out.append(Condition("connectivity", "coupling graph connected", False, 0.0, None,
                             "the graph has more than one component: no synchronization of the whole group"))
        return out
    lam, method = _lambda_plus(graph)
    g = np.asarray(cfg.g, dtype=float)
    if cfg.k is not None:
        out.append(_hopf(cfg, lam, method))
        margin = cfg.k * lam
        out.append(Condition("phase_coupling", "k λ⁺ > 0", margin > 0, margin, margin if margin > 0 else None, method))
    if cfg.alpha is not None:
        k = cfg.k or 0.0
        Ls = (graph.laplacian + graph.laplacian.T) / 2
        lam_min = float(np.linalg.eigvalsh(k * Ls + cfg.alpha * np.eye(graph.n))[0])
        out.append(Condition("leader_group", "λ_min(k L_s + α I) > 1", lam_min > 1, lam_min - 1,
                             lam_min - 1 if lam_min > 1 else None, "numerical eigenvalues"))
        if graph.topology == "all":
            thesis = k * graph.n + cfg.alpha
            out.append(Condition("leader_group_1perp", "k N + α > 1 (thesis, followers' synchrony)", thesis > 1,
                                 thesis - 1, thesis - 1 if thesis > 1 else None, "closed form, all-to-all"))
    if cfg.m_d is not None:
        out.extend(_step_frequency(cfg, lam, method, g))
    if cfg.m_z is not None:
        rate_z = cfg.m_z * cfg.omega * g.min() * lam
        holds = cfg.m_z > 0 and (graph.topology == "all" or _strong_symmetric(graph, g))
        rho = min(rate_z, cfg.k * lam) if (cfg.k is not None and cfg.k > 0) else rate_z
        out.append(Condition("step_length", "m_z min g λ⁺ > 0" + (" and Theorem 6" if graph.topology != "all" else ""),
                             holds, rate_z, rho if holds else None,
                             f"{method}; rate min(ρ_φ, ρ_z)" if cfg.k is not None else method))
    if cfg.m_psi is not None:
        rate = cfg.m_psi * float(np.cos(cfg.heading_spread))
        out.append(Condition("heading_consensus", f"m_ψ > 0, |χ − ψ| ≤ {np.degrees(cfg.heading_spread):.0f}° < 90°",
                             cfg.m_psi > 0, rate, rate if cfg.m_psi > 0 else None,
                             "closed form (journal eq. 12), rate m_ψ cos Δ for unit gait frequency"))
        out.append(Condition("heading_goal_region", "m_ψ > 0, |ψ − ψ_goal| < 180°", cfg.m_psi > 0, cfg.m_psi,
                             cfg.m_psi if cfg.m_psi > 0 else None,
                             "closed form (thesis 4.4.3), metric 1/(1 + cos(ψ − ψ_goal))"))
    if cfg.k_sine is not None:
        out.append(_schoener_dose(cfg, lam, method))
    return out


def _schoener_dose(cfg: CouplingConfig, lam: float, method: str) -> Condition:
    graph, k, spread = cfg.graph, cfg.k_sine, cfg.heading_spread
    statement = f"k > 0, |ψ_i − ψ_j| ≤ {np.degrees(spread):.0f}° < 90° (eq. 4.45)"
    if graph.symmetric:
        rate = k * lam * float(np.cos(spread))
        return Condition("schoener_dose", statement, rate > 0, rate, rate if rate > 0 else None,
                         f"{method}; rate k λ⁺ cos Δ")
    A = -graph.laplacian.copy()
    np.fill_diagonal(A, 0.0)
    V = complement_basis(graph.n)
    rng = np.random.default_rng(cfg.seed)
    worst = -np.inf
    for _ in range(cfg.samples):
        psi = rng.uniform(-spread / 2, spread / 2, graph.n)
        W = A * np.cos(psi[:, None] - psi[None, :])
        J = -k * (np.diag(W.sum(axis=1)) - W)
        worst = max(worst, float(np.linalg.eigvalsh(V @ ((J + J.T) / 2) @ V.T)[-1]))
    return Condition("schoener_dose", statement, worst < 0, -worst, -worst if worst < 0 else None,
                     f"numerical: {cfg.samples} sampled angle sets, projected symmetrized Jacobian")


def _lambda_plus(graph: CouplingGraph) -> tuple[float, str]:
    closed = graph.closed_form_lambda_plus()
    if closed is not None:
        return closed, f"closed form, Table 4.1 ({graph.topology})"
    return graph.lambda_plus, "numerical: λ_min(V L_s Vᵀ)"


def _hopf(cfg: CouplingConfig, lam: float, method: str) -> Condition:
    graph, k = cfg.graph, cfg.k
    if graph.topology is not None:
        margin = k * lam - 1.0
    else:
        margin = -_hopf_sampled_sup(graph, k, cfg.samples, cfg.seed)
        method = f"numerical: sup over {cfg.samples} sampled states of λ_max(V (D(x) − k L⊗I₂)_s Vᵀ)"
    return Condition("hopf_diffusive", "k λ⁺ > sup λ_max(∂f/∂x)_s = 1", margin > 0, margin,
                     margin if margin > 0 else None, method)


def hopf_jacobian(x: np.ndarray, y: np.ndarray, omega: float = 1.0) -> np.ndarray:
    """∂f/∂x of the Andronov-Hopf oscillator (eq. 4.14) at each (x, y): shape (len(x), 2, 2)."""
    r2 = x * x + y * y
    J = np.empty((len(x), 2, 2))
    J[:, 0, 0] = 1 - r2 - 2 * x * x
    J[:, 0, 1] = -2 * x * y - omega
    J[:, 1, 0] = -2 * x * y + omega
    J[:, 1, 1] = 1 - r2 - 2 * y * y
    return J


def _hopf_sampled_sup(graph: CouplingGraph, k: float, samples: int, seed: int) -> float:
    n = graph.n
    V = np.kron(complement_basis(n), np.eye(2))
    coupling = k * np.kron(graph.laplacian, np.eye(2))
    rng = np.random.default_rng(seed)
    worst = -np.inf
    for s in range(samples):
        radius = np.zeros(n) if s == 0 else rng.uniform(0.0, 1.5, n)
        angle = rng.uniform(-np.pi, np.pi, n)
        D = np.zeros((2 * n, 2 * n))
        for i, block in enumerate(hopf_jacobian(radius * np.cos(angle), radius * np.sin(angle))):
            D[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = block
        J = D - coupling
        worst = max(worst, float(np.linalg.eigvalsh(V @ ((J + J.T) / 2) @ V.T)[-1]))
    return worst


def _strong_symmetric(graph: CouplingGraph, g: np.ndarray) -> bool:
    eig = graph.projected_eigenvalues
    a, b = eig[0] / eig[-1], g.min() / g.max()
    return (1 - a) ** 2 / (1 + a) ** 2 + (1 - b) ** 2 / (1 + b) ** 2 < 1


def _step_frequency(cfg: CouplingConfig, lam: float, method: str, g: np.ndarray) -> list[Condition]:
    graph, m_d = cfg.graph, cfg.m_d
    out = []
    if graph.topology == "all":
        rate = m_d * g.min() * lam
        out.append(Condition("step_frequency", "m_d min g λ⁺ > 0 (all-to-all)", rate > 0, rate,
                             rate if rate > 0 else None, method))
    elif graph.symmetric:
        eig = graph.projected_eigenvalues
        a = eig[0] / eig[-1]
        mean = g.mean()
        weak = a - np.abs(g - mean).max() / mean
        b = g.min() / g.max()
        strong = 1 - ((1 - a) ** 2 / (1 + a) ** 2 + (1 - b) ** 2 / (1 + b) ** 2)
        holds = m_d > 0 and (weak > 0 or strong > 0)
        rate = _step_frequency_sampled(graph, m_d, g, cfg.samples, cfg.seed) if holds else None
        out.append(Condition("step_frequency", "λ⁺_min/λ⁺_max > max|g − ḡ|/ḡ", m_d > 0 and weak > 0, weak,
                             rate if m_d > 0 and weak > 0 else None, "closed form (weak, conference paper)"))
        out.append(Condition("step_frequency_thm6", "(1−a)²/(1+a)² + (1−b)²/(1+b)² < 1", m_d > 0 and strong > 0,
                             strong, rate if m_d > 0 and strong > 0 else None, "closed form (thesis Theorem 6)"))
    else:
        worst = _step_frequency_sampled(graph, m_d, g, cfg.samples, cfg.seed)
        out.append(Condition("step_frequency", "sup λ_max(−m_d V (L D_g)_s Vᵀ) < 0", worst is not None,
                             worst or 0.0, worst,
                             f"numerical: {cfg.samples} sampled speed profiles, projected symmetrized Jacobian"))
    if cfg.lowpass is not None:
        bound = float(np.sqrt(max(m_d, 0.0) * g.max() * graph.lambda_max))
        out.append(Condition("lowpass_filter", "α > sqrt(m_d max g λ_max(L_s))", m_d > 0 and cfg.lowpass > bound,
                             cfg.lowpass - bound, None, "closed form (paper 003)"))
    return out


def _step_frequency_sampled(graph: CouplingGraph, m_d: float, g: np.ndarray, samples: int, seed: int) -> float | None:
    """Guaranteed rate ``−sup λ_max(−m_d V (L D_g)_s Vᵀ)`` over sampled phases, or None if not negative."""
    V = complement_basis(graph.n)
    rng = np.random.default_rng(seed)
    worst = -np.inf
    for _ in range(samples):
        Dg = np.diag(rng.choice(g, graph.n))
        J = -m_d * graph.laplacian @ Dg
        worst = max(worst, float(np.linalg.eigvalsh(V @ ((J + J.T) / 2) @ V.T)[-1]))
    return -worst if worst < 0 else None


def refuse_violated(conditions: list[Condition], allow_unstable: bool, log: Callable[[str], None] = print) -> None:
    """Raise ``ValueError`` naming the violated conditions unless ``allow_unstable``; with it, say
    that convergence is not guaranteed."""
    violated = [c.name for c in conditions if not c.holds]
    if violated and not allow_unstable:
        raise ValueError(f"the contraction condition(s) {', '.join(violated)} are violated for this configuration; "
                         "pass --allow-unstable to run it anyway")
    if violated:
        log(f"running an uncertified configuration ({', '.join(violated)} violated): convergence is not guaranteed")
