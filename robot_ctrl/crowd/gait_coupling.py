"""GaitCoupling: the crowd control laws of thesis 4.4.1 (eqs. 4.28-4.33) as pure functions.

For agents i = 1..N with gait phase φ_i [rad], position z_i [m] along the direction of travel and
heading ψ_i [rad] (world frame, about z), on a coupling graph with adjacency A and Laplacian L:

- step frequency (eq. 4.28) and step phase (eq. 4.31):
  ``φ̇_i = ω₀ − m_d (L (z − o))_i − k Σ_j A_ij sin(φ_i − φ_j)``.
  Simplification: the thesis couples the phase differences taken modulo 2π; we use their sine,
  which is the same to first order at synchrony (rate k λ⁺) but has no stable state other than
  synchrony for all-to-all coupling. With the wrapped difference, N equally spaced phases are a
  stable equilibrium too: three robots started at random phases locked 2π/3 apart (seed 0 of the
  group walk). The sine form is the Schöner-Dose-type coupling of thesis 4.4.3 (eq. 4.45), so its
  certificate covers it (contracting while all coupled differences stay below π/2);
- step length (eq. 4.30): ``μ_i = −m_z (L (z − o))_i``, the gait then advances ``ż_i = (1 + μ_i) ω_i g(φ_i)``;
- heading consensus (eq. 4.33 without the gait's own heading oscillation g_ψ):
  ``ψ̇_i = m_ψ sin(χ − ψ_i)``, χ the circular mean heading.

``o`` are the formation offsets along the direction of travel (the thesis's d_ij = o_i − o_j, so
``c = −L o``); zero for walking abreast. Arrays carry the agents on their last axis, any leading
axes (independent runs) broadcast.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robot_ctrl.crowd.certificates import Condition, CouplingConfig, certify
from robot_ctrl.crowd.coupling_graph import CouplingGraph


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles mapped into [−π, π)."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def phase_disagreement(phases: np.ndarray, adjacency: np.ndarray) -> np.ndarray:
    """``Σ_j A_ij sin(φ_i − φ_j)``, shape of ``phases``; computed as ``Im(e^{iφ_i} (A e^{−iφ})_i)``."""
    unit = np.exp(1j * phases)
    return np.imag(unit * (np.conj(unit) @ adjacency.T))


def formation_error(z: np.ndarray, graph: CouplingGraph, offsets: np.ndarray) -> np.ndarray:
    """``L (z − o)`` along the last axis [m]."""
    return np.moveaxis(graph.apply(np.moveaxis(z - offsets, -1, 0)), 0, -1)


def consensus_sin_cos(cos_psi: np.ndarray, sin_psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sin χ and cos χ of the circular mean χ = angle(Σ_i exp(i ψ_i)) over the last axis, from the
    headings' cosines and sines (χ = 0 where the sum vanishes, as ``np.angle(0)``)."""
    c, s = cos_psi.sum(axis=-1, keepdims=True), sin_psi.sum(axis=-1, keepdims=True)
    norm = np.hypot(c, s)
    none = norm == 0.0
    norm[none] = 1.0
    return np.where(none, 0.0, s / norm), np.where(none, 1.0, c / norm)


@dataclass(frozen=True)
class GaitCoupling:
    graph: CouplingGraph
    k: float = 0.0  # step-phase coupling [1/s]
    m_d: float = 0.0  # step-frequency-from-distance coupling [rad/(s·m)]
    m_z: float = 0.0  # step-length-from-distance coupling [1/m]
    m_psi: float = 0.0  # heading consensus [1/s]
    offsets: np.ndarray = field(default=None)  # (N,) formation offsets along the travel direction [m]

    def __post_init__(self):
        for name in ("k", "m_d", "m_z", "m_psi"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} = {getattr(self, name)} must be finite")
        offsets = np.zeros(self.graph.n) if self.offsets is None else np.asarray(self.offsets, dtype=float)
        if offsets.shape != (self.graph.n,) or not np.all(np.isfinite(offsets)):
            raise ValueError(f"offsets must be {self.graph.n} finite positions [m], got {self.offsets}")
        object.__setattr__(self, "offsets", offsets)

    @property
    def adjacency(self) -> np.ndarray:
        A = -self.graph.laplacian.copy()
        np.fill_diagonal(A, 0.0)
        return A

    def phase_rates(self, phases: np.ndarray, z: np.ndarray, omega0: float) -> np.ndarray:
        """Gait frequencies ``φ̇_i`` [rad/s] (eqs. 4.28, 4.31)."""
        rate = omega0 - self.k * phase_disagreement(phases, self.adjacency)
        if self.m_d:
            rate = rate - self.m_d * formation_error(z, self.graph, self.offsets)
        return rate

    def step_length_scales(self, z: np.ndarray) -> np.ndarray:
        """Step-length morphing ``μ_i`` (eq. 4.30), dimensionless."""
        return -self.m_z * formation_error(z, self.graph, self.offsets)

    def heading_rates(self, headings: np.ndarray) -> np.ndarray:
        """``ψ̇_i`` [rad/s] of the heading consensus (eq. 4.33)."""
        cos_psi, sin_psi = np.cos(headings), np.sin(headings)
        sin_chi, cos_chi = consensus_sin_cos(cos_psi, sin_psi)
        return self.m_psi * (sin_chi * cos_psi - cos_chi * sin_psi)  # sin(χ − ψ_i)

    def certify(self, g: np.ndarray, omega: float, spread: float = np.pi / 4, phases: str = "sine",
                omega_max: float | None = None) -> list[Condition]:
        """The conditions that apply to these laws, with ``g`` = dz/dφ over a cycle [m/rad] and
        ``omega`` .. ``omega_max`` the gait frequencies an agent may run at [rad/s]. ``phases`` says how
        the step phases are coupled:
        ``"sine"`` (these laws: ``phase_coupling``, the linearization at synchrony with rate k λ⁺, and
        ``schoener_dose``, the sine coupling inside a phase spread ``spread``) or ``"hopf"``
        (oscillators coupled through their (x, y) state: ``hopf_diffusive`` and ``phase_coupling``)."""
        if phases not in ("sine", "hopf"):
            raise ValueError(f"phases = {phases!r} must be 'sine' or 'hopf'")

        def active(v):
            return v if v else None
        cfg = CouplingConfig(self.graph, k=active(self.k), k_sine=active(self.k) if phases == "sine" else None,
                             m_d=active(self.m_d), m_z=active(self.m_z), m_psi=active(self.m_psi),
                             g=np.asarray(g, dtype=float), omega=omega, omega_max=omega_max, heading_spread=spread)
        conditions = certify(cfg)
        return [c for c in conditions if c.name != "hopf_diffusive"] if phases == "sine" else conditions
