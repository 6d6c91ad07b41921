"""Crowd experiments: one simulated group with its certificate and empirical rates (phases,
positions, headings), and the rate-vs-coupling study of thesis Fig. 4.6 (empirical convergence
rate against k, and its slope against N)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.crowd.certificates import Condition
from robot_ctrl.crowd.coupling_graph import CouplingGraph
from robot_ctrl.crowd.dispersion import angular_dispersion, empirical_rate
from robot_ctrl.crowd.gait_coupling import GaitCoupling
from robot_ctrl.crowd.gait_profile import GaitProfile
from robot_ctrl.crowd.hopf_network import simulate, simulate_crowd


class CrowdDiverged(ArithmeticError):
    """A simulated group's state became non-finite (an uncertified, diverging coupling)."""


@dataclass(frozen=True)
class GroupRun:
    conditions: list[Condition]
    times: np.ndarray
    dispersion: np.ndarray  # R̂(t) averaged over runs
    empirical_rate: float | None  # [1/s] of the phases
    final_spread: float  # [rad] mean over runs of the largest phase distance to the circular mean at the end
    position_error: np.ndarray | None = None  # ‖(z − o) − mean‖ averaged over runs [m], with position control
    position_rate: float | None = None  # [1/s]
    heading_error: np.ndarray | None = None  # ‖ψ − mean‖ averaged over runs [rad], with heading control
    heading_rate: float | None = None  # [1/s]

    def report(self) -> dict:
        out = {
            "certificate": [c.to_dict() for c in self.conditions],
            "empirical_rate_per_s": self.empirical_rate,
            "final_phase_spread_rad": self.final_spread,
            "final_dispersion": float(self.dispersion[-1]),
        }
        if self.position_error is not None:
            out.update(empirical_position_rate_per_s=self.position_rate,
                       final_position_error_m=float(self.position_error[-1]))
        if self.heading_error is not None:
            out.update(empirical_heading_rate_per_s=self.heading_rate,
                       final_heading_error_rad=float(self.heading_error[-1]))
        return out


def run_group(coupling: GaitCoupling, duration: float = 30.0, runs: int = 100, seed: int = 0,
              profile: GaitProfile | None = None, omega: float = 2 * np.pi) -> GroupRun:
    """Simulate the kinematic crowd and measure its convergence: phases from R̂ (thesis 4.3.6), positions
    and headings from their distance to the synchronization manifold, each rate fitted over the decay
    from 10 % of its start value down to 1e-6 of it."""
    g = None if profile is None else profile.scaled(profile.nominal_speed, omega).g
    out = simulate_crowd(coupling, duration, omega=omega, g=g, runs=runs, seed=seed)
    times, phases = out.times, out.phases
    finite = np.ones(len(times), dtype=bool)
    for values in (out.phases, out.z, out.headings):
        if values is not None:
            finite &= np.isfinite(values).reshape(len(times), -1).all(axis=1)
    if not finite.all():
        raise CrowdDiverged(f"the group's state became non-finite at t = {times[np.argmin(finite)]:.3g} s: "
                            "the coupling diverged")
    dispersion = angular_dispersion(phases).mean(axis=1)
    last = phases[-1]
    mean = np.angle(np.exp(1j * last).mean(axis=1, keepdims=True))
    spread = np.abs(np.angle(np.exp(1j * (last - mean)))).max(axis=1).mean()
    g_cert = np.full(1, 1.0 / omega) if g is None else g
    conditions = coupling.certify(g_cert, omega, phases="hopf")
    position = heading = None
    if out.z is not None and (coupling.m_z or coupling.m_d):
        position = _disagreement(out.z - coupling.offsets)
    if out.headings is not None:
        heading = _disagreement(out.headings)
    return GroupRun(conditions, times, dispersion, empirical_rate(times, dispersion), float(spread),
                    position, _relative_rate(times, position), heading, _relative_rate(times, heading))


def _disagreement(values: np.ndarray) -> np.ndarray:
    """Mean over runs of the distance to the synchronization manifold, ‖v − mean(v)‖, per time."""
    return np.linalg.norm(values - values.mean(axis=-1, keepdims=True), axis=-1).mean(axis=1)


def _relative_rate(times: np.ndarray, error: np.ndarray | None) -> float | None:
    if error is None:
        return None
    return empirical_rate(times, error, upper=0.1 * error[0], lower=1e-6 * error[0])


def rate_slopes(topologies=("all", "ring", "chain", "star"), sizes=(3, 5, 8, 16, 49), factors=(0.5, 1.2, 2.0, 3.0),
                runs: int = 30, duration: float = 25.0) -> dict:
    """For each topology and N: empirical rates at k = factor / λ⁺ (on both sides of the bound
    k λ⁺ > 1), the fitted slope dλ/dk and the theoretical slope λ⁺ (the certificate's rate is
    k λ⁺ − 1 where it holds)."""
    out = {}
    for topology in topologies:
        for n in sizes:
            graph = CouplingGraph.named(topology, n)
            lam = graph.closed_form_lambda_plus()
            ks = [f / lam for f in factors]
            rates = [empirical_rate(*_mean_dispersion(graph, k, runs, duration)) for k in ks]
            slope = float(np.polyfit(ks, rates, 1)[0]) if None not in rates else None
            out[f"{topology}-{n}"] = {"topology": topology, "n": n, "lambda_plus": lam, "k": ks, "rates": rates,
                                      "certified": [k * lam - 1 for k in ks], "slope": slope,
                                      "theory_slope": lam}
    return out


def _mean_dispersion(graph, k, runs, duration):
    phases, times = simulate(graph, k, duration, runs=runs)
    return times, angular_dispersion(phases).mean(axis=1)
