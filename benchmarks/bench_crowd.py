"""Kinematic crowds at scale: certificates and simulations of 10,000 agents all-to-all and 100,000
on a ring against real time.

- ``crowd certify``: the wall time of ``certify`` for a ring of ``--certify-n`` agents with the
  phase coupling k = 1 (closed forms, no matrix).
- ``crowd run``'s law: Andronov-Hopf gait oscillators with diffusive phase coupling only (``robot-ctrl
  crowd run --k K``), k = 2 / λ_max so the fastest coupled mode stays inside RK4's region at 10 ms;
- the walking law: the same plus step-length control from the positions (m_z), heading consensus
  (m_ψ) and the gait profile measured on Talos (``robot_ctrl.crowd.hopf_network.simulate_crowd``).

Each is ``--repeats`` simulations of ``--duration`` simulated seconds (one run of the group, RK4 at
dt = 10 ms); the script prints the median wall time and the real-time factor (simulated / wall
seconds), and with ``--json`` one JSON object as its last line. Run: ``python benchmarks/bench_crowd.py``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from robot_ctrl.crowd.certificates import CouplingConfig, certify
from robot_ctrl.crowd.coupling_graph import CouplingGraph
from robot_ctrl.crowd.gait_coupling import GaitCoupling
from robot_ctrl.crowd.gait_profile import GaitProfile
from robot_ctrl.crowd.hopf_network import simulate_crowd

GROUPS = (("all", 10_000), ("ring", 100_000))


def median_wall(run, repeats: int) -> float:
    walls = []
    for r in range(repeats):
        t0 = time.perf_counter()
        run(r)
        walls.append(time.perf_counter() - t0)
    return float(np.median(walls))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=5.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--certify-n", type=int, default=100_000)
    parser.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    args = parser.parse_args()
    omega = 2 * np.pi  # 1 Hz gait
    profile = GaitProfile.load_or_constant("talos", omega, 1.0)
    results = {}

    certify_s = median_wall(lambda r: certify(CouplingConfig(CouplingGraph.named("ring", args.certify_n), k=1.0)),
                            args.repeats)
    results[f"certify_ring_{args.certify_n}_s"] = round(certify_s, 4)
    print(f"crowd certify, ring of {args.certify_n} agents, k = 1: median {certify_s:.3f} s")
    print(f"gait profile: {profile.source}; dt = 10 ms, RK4, {args.duration} s simulated per run, one run per group")
    print(f"{'law':8s} {'graph':6s} {'agents':>7s} {'wall median [s]':>16s} {'real-time factor':>17s}")
    for law_name in ("phase", "walk"):
        for topology, n in GROUPS:
            graph = CouplingGraph.named(topology, n)
            if law_name == "phase":
                law, g = GaitCoupling(graph, k=2.0 / graph.lambda_max), None
            else:
                law, g = GaitCoupling(graph, k=2.0 / graph.lambda_max, m_psi=0.5,
                                      m_z=1.0 / (omega * profile.g.min() * graph.lambda_max)), profile.g

            def run(seed, law=law, g=g, topology=topology, n=n):
                out = simulate_crowd(law, args.duration, omega=omega, g=g, runs=1, seed=seed, dt=0.01,
                                     record_every=100)
                if not np.all(np.isfinite(out.phases)):
                    raise RuntimeError(f"{topology} N={n}: the simulation diverged")
            wall = median_wall(run, args.repeats)
            rtf = args.duration / wall
            results[f"{law_name}_{topology}_{n}_rtf"] = round(rtf, 3)
            print(f"{law_name:8s} {topology:6s} {n:7d} {wall:16.3f} {rtf:17.2f}")
    if args.json:
        print(json.dumps(results))


if __name__ == "__main__":
    main()
