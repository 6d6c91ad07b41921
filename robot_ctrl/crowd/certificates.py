"""Contraction certificates for coupled gaits (thesis 4.3-4.4, conference/journal papers).

Each applicable sufficient condition is returned as a :class:`Condition` with its margin
(left-hand side minus right-hand side: > 0 holds) and the guaranteed minimum convergence rate
[1/s] when it holds. Every figure is either the condition's exact worst case over all states and
parameters it covers (``exact``, ``[exact]``) or a bound that is never optimistic (``[bound]``);
nothing is sampled (``crowd.worst_case``). Graph quantities: λ⁺ and λ_max of the symmetric Laplacian part projected on
the complement of the synchronization manifold (see ``CouplingGraph``); g(φ) the gait's speed
profile (forward speed over a cycle, normalized or not), given as samples over one cycle.

- ``hopf_diffusive`` (thesis 4.3.4, eq. 4.25, Table 4.1): Andronov-Hopf oscillators with diffusive
  state coupling ``ẋ_i = f(x_i) + k Σ_j A_ij (x_j − x_i)`` contract to synchrony if
  ``k λ⁺ > sup λ_max(∂f/∂x)_s = 1``; rate ``k λ⁺ − 1``, exact for any graph (the supremum of the
  projected symmetrized Jacobian ``V (D(x) − k L⊗I₂)_s Vᵀ`` is reached with every oscillator at
  r = 0). λ⁺ is Table 4.1's closed form times the link weight for named topologies (N = 2: one link,
  2 w), the projected symmetric Laplacian's smallest eigenvalue otherwise.
- ``phase_coupling`` (4.3.2, scenario 1 of 4.4.2): ``φ̇ = ω − k L φ``; holds for ``k λ⁺ > 0``, rate ``k λ⁺``.
- ``leader_group`` (4.3.7, eq. 4.27): followers ``ẋ = f(x) − k L x − α (x − x̃₀)``; the thesis gives
  ``λ_min(k L + α I) > 1`` and, for all-to-all followers, ``k N + α > 1`` with rate ``k N + α``. On
  the full follower space λ_min(k L_s + α I) = α (L has the eigenvalue 0 along 1), so we certify
  ``λ_min(k L_s + α I) > 1`` with rate ``λ_min − 1`` and report the thesis's all-to-all form as a
  second line (it bounds the followers' mutual synchronization, on 1⊥).
- ``step_frequency`` (scenario 2, conference eq. 2): ``φ̇ = ω₀ 1 − m_d (L G(φ) + c)``. All-to-all:
  rate ``m_d min g λ⁺`` for m_d > 0, g > 0 (exact). Other graphs: the projected symmetrized Jacobian
  ``−m_d V (L D_g)_s Vᵀ`` over every g_i ∈ [min g, max g], its worst case at a vertex of that box
  (exact up to 12 agents, a relaxation above that is never optimistic, ``crowd.worst_case``). For
  symmetric graphs the papers' closed forms are listed beside it: the weak condition ``λ⁺_min / λ⁺_max > max|g − ḡ| / ḡ`` and the strong one
  (thesis Theorem 6) ``(1 − a)²/(1 + a)² + (1 − b)²/(1 + b)² < 1``, a = λ⁺_min/λ⁺_max, b = min g / max g.
- ``lowpass_filter`` (journal/paper 003): with ``ż = −α z + G(φ)``, the paper's two conditions: the
  unfiltered step-frequency condition, and ``α²/m_d > ½ λ_max(V B Vᵀ)``, bounded by ``α > sqrt(m_d
  max g ‖L‖₂)`` (the paper's λ_max(L_s) for a symmetric graph); only where the paper's argument
  holds (it drops off-diagonal blocks that vanish for all-to-all coupling or a constant profile on a
  symmetric graph), violated elsewhere.
- ``step_length`` (scenario 3): ``ż = ω g(φ)(1 − m_z (L z + c))``, Jacobian ``−m_z D_ω D_g L`` with
  each agent's gait frequency in [``omega``, ``omega_max``] (1 by default as in the thesis; a bridge
  to walking robots lets each run in a range): all-to-all ``ρ_z = m_z ω min g λ⁺`` (exact), other
  graphs the worst case over the box of ω_i g_i as for the step frequency; with phase coupling the
  overall rate is ``min(ρ_φ, ρ_z)``.
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
  (our derivation from the thesis's Jacobian; a bound). Asymmetric graphs: the projected symmetrized
  Jacobian with every coupled cosine anywhere in [cos Δ, 1], a box that contains every angle set of
  spread ≤ Δ (a bound: vertex enumeration up to 12 coupled pairs, the relaxation of
  ``crowd.worst_case`` above). Outside the region the potential
  U = −k Σ A_ij cos(ψ_i − ψ_j) (eq. 4.40) still decreases: convergence without a guaranteed rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from robot_ctrl.crowd.coupling_graph import CouplingGraph
from robot_ctrl.crowd.worst_case import RELAXED_UP_TO, profile_coupling_rate, sine_coupling_rate


@dataclass(frozen=True)
class Condition:
    name: str
    statement: str
    holds: bool
    margin: float
    rate: float | None  # guaranteed minimum convergence rate [1/s], None if not guaranteed
    method: str
    exact: bool  # margin and rate are the condition's worst case (else a bound that is never optimistic)

    def to_dict(self) -> dict:
        return {"name": self.name, "statement": self.statement, "holds": bool(self.holds),
                "margin": float(self.margin), "rate": None if self.rate is None else float(self.rate),
                "exact": self.exact, "method": self.method}

    def line(self) -> str:
        rate = f"rate {self.rate:.4g} 1/s" if self.rate is not None else "no rate guaranteed"
        verdict = "holds" if self.holds else "violated"
        kind = "[exact]" if self.exact else "[bound]"
        return (f"{self.name:18s} {self.statement:40s} {verdict:8s} margin {self.margin:+.4g}  {rate}  {kind} "
                f"{self.method}")


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
    omega_max: float | None = None  # [rad/s] highest gait frequency an agent may run at; None: omega

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
        if self.omega_max is not None and not (np.isfinite(self.omega_max) and self.omega_max >= self.omega):
            raise ValueError(f"omega_max = {self.omega_max} rad/s must be ≥ omega = {self.omega} rad/s")
        if not 0 < self.heading_spread < np.pi / 2:
            raise ValueError(f"heading_spread = {self.heading_spread} must be in (0, π/2) rad")


def certify(cfg: CouplingConfig) -> list[Condition]:
    """Every condition that applies to the given gains."""
    graph = cfg.graph
    if not graph.connected:
        return [Condition("connectivity", "coupling graph connected", False, 0.0, None,
                          "the graph has more than one component: no synchronization of the whole group", True)]
    lam, method = _extreme(graph, 1.0)
    g = np.asarray(cfg.g, dtype=float)
    out: list[Condition] = []
    if cfg.k is not None:
        k_lam, k_method = _extreme(graph, cfg.k)
        out.append(_hopf(cfg.k, k_lam, k_method))
        out.append(_rated("phase_coupling", "min_λ k λ > 0", cfg.k * k_lam, k_method, True))
    if cfg.alpha is not None:
        out.extend(_leader(cfg))
    if cfg.m_d is not None:
        out.extend(_step_frequency(cfg, lam, method, g))
    if cfg.m_z is not None:
        out.append(_step_length(cfg, lam, g))
    if cfg.m_psi is not None:
        rate = cfg.m_psi * float(np.cos(cfg.heading_spread))
        out.append(_rated("heading_consensus", f"m_ψ > 0, |χ − ψ| ≤ {np.degrees(cfg.heading_spread):.0f}° < 90°", rate,
                          "closed form (journal eq. 12), rate m_ψ cos Δ for unit gait frequency", True))
        out.append(_rated("heading_goal_region", "m_ψ > 0, |ψ − ψ_goal| < 180°", cfg.m_psi,
                          "closed form (thesis 4.4.3), metric 1/(1 + cos(ψ − ψ_goal))", True))
    if cfg.k_sine is not None:
        out.append(_schoener_dose(cfg, lam, method))
    return out


def _rated(name: str, statement: str, rate: float, method: str, exact: bool) -> Condition:
    """A condition that holds when its guaranteed rate is positive (margin = rate)."""
    return Condition(name, statement, rate > 0, rate, rate if rate > 0 else None, method, exact)


def _extreme(graph: CouplingGraph, gain: float) -> tuple[float, str]:
    """The projected symmetric Laplacian's eigenvalue that a diffusive coupling of ``gain`` meets
    at its worst (λ⁺ for a gain ≥ 0, the largest for a negative one), and how it was found."""
    which = "λ⁺" if gain >= 0 else "λ_top (negative gain)"
    if graph.topology is not None:
        return graph.extreme_eigenvalue(gain), f"closed form {which}, Table 4.1 ({graph.topology}, weight {graph.weight:g})"
    return graph.extreme_eigenvalue(gain), f"numerical: {which} of V L_s Vᵀ"


def _hopf(k: float, lam: float, method: str) -> Condition:
    """The oscillator's symmetrized Jacobian is ``(1 − r²) I − 2 p pᵀ`` (p = (x, y)), whose largest
    eigenvalue 1 − r² is at most 1, reached at r = 0; so for any graph and any sign of k
    ``sup_x λ_max(V (D(x) − k L⊗I₂)_s Vᵀ) = 1 − min_λ k λ(V L_s Vᵀ)`` exactly (Weyl for ≤, all r = 0
    for =): ``lam`` is λ⁺ for k ≥ 0, the largest eigenvalue for k < 0."""
    margin = k * lam - 1.0
    return Condition("hopf_diffusive", "min_λ k λ > sup λ_max(∂f/∂x)_s = 1", margin > 0, margin,
                     margin if margin > 0 else None, f"{method}; sup attained at r = 0", True)


def _leader(cfg: CouplingConfig) -> list[Condition]:
    graph, k = cfg.graph, cfg.k or 0.0
    if graph.topology is not None:  # L_s's eigenvalues are 0 (along 1) and the projected ones
        lam_min, how = cfg.alpha + min(0.0, k * graph.lambda_plus, k * graph.lambda_top), "closed form (Table 4.1)"
    else:
        Ls = (graph.laplacian + graph.laplacian.T) / 2
        lam_min, how = float(np.linalg.eigvalsh(k * Ls + cfg.alpha * np.eye(graph.n))[0]), "numerical eigenvalues"
    out = [_rated("leader_group", "λ_min(k L_s + α I) > 1", lam_min - 1, how, True)]
    if graph.topology == "all":
        out.append(_rated("leader_group_1perp", "k N w + α > 1 (thesis, followers' synchrony)",
                          k * graph.n * graph.weight + cfg.alpha - 1, "closed form, all-to-all", True))
    return out


def _profile_rate(graph: CouplingGraph, gain: float, low: float, high: float, side: str,
                  box: str = "g ∈ [min g, max g]") -> tuple[float, bool, str]:
    rate, exact = profile_coupling_rate(graph, gain, low, high, side)
    how = (f"worst case over the {2 ** graph.n} vertices of {box}^N" if exact
           else f"relaxation over {box}^N (arithmetic-geometric mean per agent, its multipliers minimized), at "
                "least Weyl's m (ḡ λ⁺ − Δg ‖L‖₂)" if graph.n <= RELAXED_UP_TO
           else "Weyl: m (ḡ λ⁺ − Δg ‖L‖₂)")
    return rate, exact, how


def _step_frequency(cfg: CouplingConfig, lam: float, method: str, g: np.ndarray) -> list[Condition]:
    graph, m_d = cfg.graph, cfg.m_d
    if graph.topology == "all":
        # V (L D_g)_s Vᵀ = w N V D_g Vᵀ on 1⊥ for the complete graph: the worst case is all g at min g.
        # A negative gain meets the largest g (and the graph's largest eigenvalue: N w as well).
        worst_g = g.min() if m_d >= 0 else g.max()
        out = [_rated("step_frequency", "m_d min g λ⁺ > 0 (all-to-all)", m_d * worst_g * lam, method, True)]
    else:
        rate, exact, how = _profile_rate(graph, m_d, float(g.min()), float(g.max()), "right")
        out = [_rated("step_frequency", "sup λ_max(−m_d V (L D_g)_s Vᵀ) < 0", rate, how, exact)]
        if graph.symmetric:  # the papers' closed-form sufficient conditions, for reference
            a, b = graph.lambda_plus / graph.lambda_top, g.min() / g.max()
            weak = a - np.abs(g - g.mean()).max() / g.mean()
            strong = 1 - ((1 - a) ** 2 / (1 + a) ** 2 + (1 - b) ** 2 / (1 + b) ** 2)
            for name, statement, value, source in (
                    ("step_frequency_weak", "λ⁺_min/λ⁺_max > max|g − ḡ|/ḡ", weak, "conference paper"),
                    ("step_frequency_thm6", "(1−a)²/(1+a)² + (1−b)²/(1+b)² < 1", strong, "thesis Theorem 6")):
                holds = m_d > 0 and value > 0
                out.append(Condition(name, statement, holds, float(value), rate if holds and rate > 0 else None,
                                     f"closed form ({source}); rate from the worst case above", exact))
    if cfg.lowpass is not None:
        # Paper 003's argument drops the transformed Jacobian's off-diagonal blocks ±(m_d/α) V L D_g Vᵀ
        # from its symmetric part, which holds where V L D_g Vᵀ is symmetric for every g: all-to-all
        # coupling (V L D_g Vᵀ = N w V D_g Vᵀ), or a constant profile on a symmetric graph. There it
        # needs the unfiltered step-frequency condition and α²/m_d > ½ λ_max(V B Vᵀ) ≤ max g ‖L‖₂.
        bound = float(np.sqrt(max(m_d, 0.0) * g.max() * graph.norm2))
        covered = graph.topology == "all" or (graph.symmetric and g.min() == g.max())
        holds = covered and m_d > 0 and out[0].holds and cfg.lowpass > bound
        how = "closed form (paper 003)" + ("" if covered else "; its argument covers all-to-all coupling, or a "
                                           "constant profile on a symmetric graph, only: not this one")
        out.append(Condition("lowpass_filter", "step_frequency holds, α > sqrt(m_d max g ‖L‖₂)", holds,
                             cfg.lowpass - bound, None, how, False))
    return out


def _step_length(cfg: CouplingConfig, lam: float, g: np.ndarray) -> Condition:
    """ż_i = ω_i g(φ_i)(1 − m_z (L z + c)_i): J = −m_z D_h L with ``h_i = ω_i g(φ_i)``, each agent's
    gait frequency anywhere in [ω, ω_max] and its profile value in [min g, max g], so h in the box
    [ω min g, ω_max max g]^N (every point of it reachable: the worst case over it is exact); with
    phase coupling the overall rate is min(ρ_φ, ρ_z)."""
    graph = cfg.graph
    h = np.array([cfg.omega * g.min(), (cfg.omega_max or cfg.omega) * g.max()])
    if graph.topology == "all":  # every eigenvalue is N w; a negative gain meets the largest h
        rate = cfg.m_z * (h[0] if cfg.m_z >= 0 else h[1]) * lam
        exact, how = True, "closed form, all-to-all: m_z ω min g λ⁺"
    else:
        rate, exact, how = _profile_rate(graph, cfg.m_z, float(h[0]), float(h[1]), "left",
                                         "ω g ∈ [ω min g, ω_max max g]")
    if cfg.k is not None and cfg.k > 0 and rate > 0:
        rate, how = min(rate, cfg.k * lam), f"{how}; rate min(ρ_φ, ρ_z)"
    return _rated("step_length", "sup λ_max(−m_z V (D_ω D_g L)_s Vᵀ) < 0", rate, how, exact)


def _schoener_dose(cfg: CouplingConfig, lam: float, method: str) -> Condition:
    graph, k, spread = cfg.graph, cfg.k_sine, cfg.heading_spread
    statement = f"k > 0, |ψ_i − ψ_j| ≤ {np.degrees(spread):.0f}° < 90° (eq. 4.45)"
    if graph.symmetric:
        if k < 0:  # repulsive: λ_max(−k V L(W) Vᵀ) ≥ |k| cos Δ λ⁺ > 0, and ≤ |k| λ_top (W ≤ A)
            return _rated("schoener_dose", statement, k * graph.lambda_top, "symmetric graph, k < 0: rate ≥ k λ_top", False)
        return _rated("schoener_dose", statement, k * lam * float(np.cos(spread)), f"{method}; rate k λ⁺ cos Δ", False)
    adjacency = -graph.laplacian.copy()
    np.fill_diagonal(adjacency, 0.0)
    rate, how = sine_coupling_rate(adjacency, k, spread)
    return _rated("schoener_dose", statement, rate, how, False)


def refuse_violated(conditions: list[Condition], allow_unstable: bool, log: Callable[[str], None] = print) -> None:
    """Raise ``ValueError`` naming the violated conditions unless ``allow_unstable``; with it, say
    that convergence is not guaranteed."""
    violated = [c.name for c in conditions if not c.holds]
    if violated and not allow_unstable:
        raise ValueError(f"the contraction condition(s) {', '.join(violated)} are violated for this configuration; "
                         "pass --allow-unstable to run it anyway")
    if violated:
        log(f"running an uncertified configuration ({', '.join(violated)} violated): convergence is not guaranteed")
