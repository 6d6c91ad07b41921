"""Crowd experiments: one simulated group with its certificate, and the rate-vs-coupling study of
thesis Fig. 4.6 (empirical convergence rate against k, and its slope against N)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.crowd.certificates import Condition, CouplingConfig, certify
from robot_ctrl.crowd.coupling_graph import CouplingGraph
from robot_ctrl.crowd.dispersion import angular_dispersion, empirical_rate
from robot_ctrl.crowd.hopf_network import simulate


@dataclass(frozen=True)
class GroupRun:
    conditions: list[Condition]
    times: np.ndarray
    dispersion: np.ndarray  # R̂(t) averaged over runs
    empirical_rate: float | None  # [1/s]
    final_spread: float  # [rad] mean over runs of the largest phase distance to the circular mean at the end

    def report(self) -> dict:
        return {
            "certificate": [c.to_dict() for c in self.conditions],
            "empirical_rate_per_s": self.empirical_rate,
            "final_phase_spread_rad": self.final_spread,
            "final_dispersion": float(self.dispersion[-1]),
        }


def run_group(graph: CouplingGraph, k: float, duration: float = 30.0, runs: int = 100, seed: int = 0) -> GroupRun:
    phases, times = simulate(graph, k, duration, runs=runs, seed=seed)
    dispersion = angular_dispersion(phases).mean(axis=1)
    last = phases[-1]
    mean = np.angle(np.exp(1j * last).mean(axis=1, keepdims=True))
    spread = np.abs(np.angle(np.exp(1j * (last - mean)))).max(axis=1).mean()
    return GroupRun(certify(CouplingConfig(graph, k=k)), times, dispersion, empirical_rate(times, dispersion),
                    float(spread))


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
