"""The group walk's measurements: measured touch-downs per robot, the phase dispersion R̂(t) and its
empirical rate, when the phases synchronized, and the phase-difference figure."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Sequence

import numpy as np

from robot_ctrl.crowd.dispersion import angular_dispersion, empirical_rate
from robot_ctrl.crowd.gait_bridge import GaitBridge
from robot_ctrl.crowd.gait_coupling import wrap
from robot_ctrl.eval.recording.report_file import write_report
from robot_ctrl.geometry import SIDES


class TouchdownRecorder:
    """Per robot, (time, side) of each measured touch-down: a foot whose estimated contact (foot
    force above the estimator's threshold) begins."""

    def __init__(self, controllers: Sequence):
        self.controllers = list(controllers)
        self.touchdowns: list[list[tuple[float, str]]] = [[] for _ in self.controllers]
        self._down = [dict.fromkeys(SIDES, True) for _ in self.controllers]

    def on_command(self, tick) -> None:
        pass

    def on_state(self, tick) -> None:
        for i, (controller, state) in enumerate(zip(self.controllers, tick.states)):
            for side, down in controller.estimate.in_contact.items():
                if down and not self._down[i][side]:
                    self.touchdowns[i].append((state.t, side))
                self._down[i][side] = down


def phase_metrics(times: np.ndarray, phases: np.ndarray, positions: np.ndarray, tolerance: float) -> dict:
    """From the coupled ticks' gait phases (T, N) and planned positions (T, N): dispersion R̂ and
    its empirical rate, the phase spread at the start and end, when the spread fell below
    ``tolerance`` for good (seconds after the coupling started), the final position spread."""
    dispersion = angular_dispersion(phases)
    spread = np.abs(wrap(phases - phases[:, :1])).max(axis=1) if len(times) else np.zeros(0)
    above = np.flatnonzero(spread >= tolerance)
    synced_at = None
    if len(times) and (len(above) == 0 or above[-1] + 1 < len(times)):
        synced_at = float(times[above[-1] + 1] - times[0]) if len(above) else 0.0
    return {"dispersion": dispersion,
            "rate": empirical_rate(times - times[0], dispersion) if len(times) else None,
            "initial_spread": round(float(spread[0]), 4) if len(spread) else None,
            "final_spread": round(float(spread[-1]), 5) if len(spread) else None,
            "synced_at": None if synced_at is None else round(synced_at, 3),
            "final_position_spread": round(float(np.ptp(positions[-1])), 4) if len(positions) else None}


def touchdown_phase_differences(touchdowns, coupled_since, stop_time, bridge: GaitBridge) -> float | None:
    """Largest phase difference [rad] between the robots' measured touch-downs of the same foot over
    the last gait cycle before the stop: 2π Δt / gait period for the nearest matching touch-down."""
    if coupled_since is None or stop_time is None:
        return None
    window = (stop_time - 2 * bridge.step_period, stop_time)
    cycle = 2 * bridge.step_period
    worst = 0.0
    for i, own in enumerate(touchdowns):
        for t, side in own:
            if not window[0] <= t <= window[1]:
                continue
            for j, other in enumerate(touchdowns):
                if j == i:
                    continue
                candidates = [u for u, s in other if s == side and abs(u - t) < cycle / 2]
                if not candidates:
                    return None
                dt = min(abs(u - t) for u in candidates)
                worst = max(worst, 2 * np.pi * dt / cycle)
    return round(worst, 4)


def plot_phases(path: Path, times, phases, dispersion, z, certified_rate, tolerance) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_p, ax_r, ax_z) = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    for i in range(1, phases.shape[1]):
        ax_p.plot(times, wrap(phases[:, i] - phases[:, 0]), label=f"φ{i} − φ0")
    ax_p.axhline(tolerance, color="k", ls=":", lw=0.8)
    ax_p.axhline(-tolerance, color="k", ls=":", lw=0.8, label=f"±{tolerance} rad")
    ax_p.set_ylabel("phase difference [rad]")
    ax_p.legend(fontsize=8)
    ax_r.semilogy(times, np.maximum(dispersion, 1e-9), label="angular dispersion R̂")
    inside = np.flatnonzero(dispersion < 0.1)  # where the exponential regime (and the rate fit) starts
    if certified_rate is not None and len(inside):
        t0 = times[inside[0]]
        ax_r.semilogy(times[inside], dispersion[inside[0]] * np.exp(-certified_rate * (times[inside] - t0)), "--",
                      label=f"certified rate {certified_rate:.3g} 1/s (from R̂ = 0.1)")
    ax_r.set_ylim(1e-6, 1.5)
    ax_r.set_ylabel("R̂")
    ax_r.legend(fontsize=8)
    for i in range(z.shape[1]):
        ax_z.plot(times, z[:, i] - z.mean(axis=1), label=f"robot {i}")
    ax_z.set_ylabel("x − group mean [m]")
    ax_z.set_xlabel("time since coupling on [s]")
    ax_z.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def group_walk_report(robot, g, commander, metrics, safety, touchdowns, conditions, profile, bridge, starts, result,
                      out_dir, log, disturbances: dict | None = None) -> dict:
    """The group walk's report (written to ``out_dir/report.json`` with ``phases.png``)."""
    times = np.asarray(commander.times)
    phases = np.asarray(commander.phases, dtype=float).reshape(len(times), g.n)
    positions = np.asarray(commander.positions).reshape(len(times), g.n)
    m = phase_metrics(times, phases, positions, g.sync_tolerance)
    phase_rate = next((c.rate for c in conditions if c.name == "phase_coupling"), None)
    rate = m["rate"]
    measured = touchdown_phase_differences(touchdowns.touchdowns, commander.coupled_since, commander.stop_time, bridge)
    report = {
        "robot": robot.name, **{k: v for k, v in asdict(g).items() if k not in ("k", "m_z", "m_psi", "speed", "spacing")},
        "gains": {"k": g.k, "m_z": g.m_z, "m_psi": g.m_psi}, "speed_mps": g.speed, "spacing_m": g.spacing,
        "start_delays_s": starts.round(4).tolist(), "certificate": [c.to_dict() for c in conditions],
        "gait_profile": profile.source, "fell": any(x.fell for x in metrics),
        "robots": [x.report() | {"prefix": f"{robot.name}_{i}", "safety": safe}
                   for i, (x, safe) in enumerate(zip(metrics, safety))],
        "coupled_from_s": commander.coupled_since, "stopped_at_s": commander.stop_time,
        "initial_phase_spread_rad": m["initial_spread"], "final_phase_spread_rad": m["final_spread"],
        "synchronized_after_s": m["synced_at"], "sync_tolerance_rad": g.sync_tolerance,
        "empirical_phase_rate_per_s": rate, "certified_phase_rate_per_s": phase_rate,
        "rate_not_below_certified": bool(rate is not None and phase_rate is not None and rate >= phase_rate),
        "measured_touchdown_phase_difference_rad": measured,
        "final_position_spread_m": m["final_position_spread"],
        "bridge_saturated_ratio": round(commander.saturated / max(commander.decisions, 1), 4),
        "disturbances": disturbances,
        "rtf": round(result.rtf, 3),
    }
    log(f"fell: {str(report['fell']).lower()}  phase spread {m['initial_spread']} -> {m['final_spread']} rad, below "
        f"{g.sync_tolerance} rad after {m['synced_at']} s; empirical rate {rate if rate is None else round(rate, 3)} "
        f"1/s vs certified {phase_rate}; measured touch-down phase difference {measured} rad; rtf {report['rtf']}")
    write_report(report, out_dir, log)
    if out_dir is not None and len(times):
        plot_phases(Path(out_dir) / "phases.png", times - times[0], phases, m["dispersion"], positions, phase_rate,
                    g.sync_tolerance)
        log(f"wrote {Path(out_dir) / 'phases.png'}")
    return report
