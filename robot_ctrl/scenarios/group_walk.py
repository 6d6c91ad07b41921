"""Group walk: several robots in one MuJoCo world, each with its own walking controller, walking
side by side with their gaits coupled by the crowd control laws (``crowd.gait_coupling``) through
``crowd.gait_bridge``.

The robots stand in a row along the world y axis, ``spacing`` metres apart, facing +x. Each starts
walking after a random delay in [0, one gait cycle), so their step phases start at random. Once all
of them are stepping, the coupling runs: step phase (k), step length from the positions along x
(m_z, walking abreast: zero offsets) and heading consensus (m_ψ). Every pattern-generator sample,
each robot's gait frequency, step-length scale and yaw rate come from the laws evaluated on the
group's current gait phases (from the plans), planned CoM positions and headings. After
``coupled_time`` seconds the robots stop and stand.

The report has the certificate computed before the run, the phase dispersion R̂(t) with its fitted
empirical rate, the time after which all phase differences stay below ``sync_tolerance``, the
measured touch-down phase differences, and each robot's fall, torque and GRF figures.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import numpy as np

from robot_ctrl.control.walking_controller import WalkingController
from robot_ctrl.crowd.coupling_graph import CouplingGraph
from robot_ctrl.crowd.dispersion import angular_dispersion, empirical_rate
from robot_ctrl.crowd.gait_bridge import GaitBridge
from robot_ctrl.crowd.gait_coupling import GaitCoupling, wrap
from robot_ctrl.crowd.gait_profile import GaitProfile
from robot_ctrl.eval import FallCriterion, RunMetrics
from robot_ctrl.eval.report_file import write_report
from robot_ctrl.hw.mujoco_backend import MujocoBackend
from robot_ctrl.hw.mujoco_world import MujocoWorld
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.wpg.params import WalkParams

STAND_AFTER = 1.5  # [s] standing after the stop


def run_group_walk(robot: RobotModel, n: int = 3, graph: str = "all", k: float = 1.0, m_z: float = 1.0,
                   m_psi: float = 0.5, speed: float = 0.2, spacing: float = 1.2, coupled_time: float = 10.0,
                   seed: int = 0, sync_tolerance: float = 0.1, allow_unstable: bool = False,
                   out_dir: Path | None = None, viewer: bool = False, log: Callable[[str], None] = print,
                   control_dt: float = 0.005) -> dict:
    checks = {"n": (2, 8), "spacing": (0.8, 5.0), "speed": (0.05, 0.3), "coupled_time": (1.0, 120.0)}
    for name, (lo, hi) in checks.items():
        value = locals()[name]
        if not (np.isfinite(value) and lo <= value <= hi):
            raise ValueError(f"{name} = {value} is outside the allowed range [{lo}, {hi}]")
    coupling = GaitCoupling(CouplingGraph.named(graph, n), k=k, m_z=m_z, m_psi=m_psi)
    bridge = GaitBridge(WalkParams().step_period, speed)
    profile = GaitProfile.load_or_constant(robot.name, bridge.omega0, speed)
    # The certificate is checked before the group moves; the slowest gait the bridge allows bounds ω.
    omega_min = bridge.omega0 / bridge.time_scale_range[1]
    conditions = coupling.certify(profile.g, omega_min)
    violated = [c.name for c in conditions if not c.holds]
    for c in conditions:
        log(c.line())
    if violated and not allow_unstable:
        raise ValueError(f"the contraction condition(s) {', '.join(violated)} are violated; "
                         "allow_unstable (--allow-unstable) runs the group anyway")
    if violated:
        log(f"running an uncertified configuration ({', '.join(violated)} violated): convergence is not guaranteed")
    prefixes = tuple(f"{robot.name}_{i}" for i in range(n))
    world = MujocoWorld(robot.group_mjcf_path(prefixes), control_dt, viewer)
    ys = (np.arange(n) - (n - 1) / 2) * spacing
    hws = [MujocoBackend(robot, world=world, prefix=p, base_xy_yaw=(0.0, float(y), 0.0)) for p, y in zip(prefixes, ys)]
    for hw in hws:
        hw.configure()
    for hw in hws:
        hw.activate()
    world.open_viewer()
    states = [hw.read() for hw in hws]
    controllers = [WalkingController(robot, s, WalkParams(), control_dt) for s in states]
    wpgs = [c.wpg for c in controllers]
    rng = np.random.default_rng(seed)
    starts = rng.uniform(0.0, 2 * bridge.step_period, n)
    log("start delays [s]: " + " ".join(f"{s:.3f}" for s in starts))
    metrics = [RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(s.base_pos[2]))) for s in states]
    coupled_since = stop_time = None
    times, phase_log, z_log = [], [], []
    contact_prev = [dict.fromkeys(("left", "right"), True) for _ in range(n)]
    touchdowns: list[list[tuple[float, str]]] = [[] for _ in range(n)]
    saturated = 0
    decisions = 0
    wall0 = time.perf_counter()
    tick = 0
    fell = False
    try:
        while True:
            t = tick * control_dt
            phases = [w.gait_phase(t - w.sample_start) for w in wpgs]
            if coupled_since is None and all(p is not None for p in phases):
                coupled_since = t
                log(f"t = {t:6.2f} s  all robots stepping: coupling on")
            if coupled_since is not None and stop_time is None and t - coupled_since >= coupled_time:
                stop_time = t
                log(f"t = {t:6.2f} s  stopping")
            z = np.array([w.com_x[0] for w in wpgs])
            headings = np.array([w.heading for w in wpgs])
            for i, (c, w) in enumerate(zip(controllers, wpgs)):
                if not c.sample_due:
                    continue
                if stop_time is not None or t < starts[i]:
                    w.set_velocity(0.0, 0.0, 0.0)
                elif coupled_since is None:
                    w.set_velocity(speed, 0.0, 0.0)
                else:
                    phi = np.array(phases)
                    omega = coupling.phase_rates(phi, z, bridge.omega0)[i]
                    mu = coupling.step_length_scales(z)[i]
                    yaw_rate = coupling.heading_rates(headings)[i]
                    cmd = bridge.command(omega, mu, yaw_rate)
                    saturated += cmd.saturated
                    decisions += 1
                    w.set_time_scale(cmd.time_scale)
                    w.set_velocity(*cmd.velocity)
            commands = [c.step(s) for c, s in zip(controllers, states)]
            for hw, cmd in zip(hws, commands):
                hw.write(cmd)
            world.step()
            states = [hw.read() for hw in hws]
            for i, (m, s, c) in enumerate(zip(metrics, states, controllers)):
                m.update(s)
                for side, down in c.estimate.in_contact.items():
                    if down and not contact_prev[i][side]:
                        touchdowns[i].append((s.t, side))
                    contact_prev[i][side] = down
            if coupled_since is not None and stop_time is None:
                times.append(t)
                phase_log.append(phases)
                z_log.append(z)
            if any(m.fell for m in metrics):
                who = next(i for i, m in enumerate(metrics) if m.fell)
                log(f"t = {states[who].t:6.2f} s  robot {who} FELL: {metrics[who].fall_reason}")
                fell = True
                break
            if stop_time is not None and all(w.standing for w in wpgs) and t - stop_time > 2 * bridge.step_period + STAND_AFTER:
                break
            if t > starts.max() + coupled_time + 20.0:
                log(f"t = {t:6.2f} s  the group did not stop in time")
                break
            tick += 1
    finally:
        wall = time.perf_counter() - wall0
        for hw in hws:
            hw.close()
        world.close()

    times = np.asarray(times)
    phase_log = np.asarray(phase_log, dtype=float).reshape(len(times), n)
    z_log = np.asarray(z_log).reshape(len(times), n)
    dispersion = angular_dispersion(phase_log)
    spread = np.abs(wrap(phase_log - phase_log[:, :1])).max(axis=1) if len(times) else np.zeros(0)
    above = np.flatnonzero(spread >= sync_tolerance)
    synced_at = None
    if len(times) and (len(above) == 0 or above[-1] + 1 < len(times)):
        synced_at = float(times[above[-1] + 1] - times[0]) if len(above) else 0.0
    rate = empirical_rate(times - times[0], dispersion) if len(times) else None
    phase_rate = next((c.rate for c in conditions if c.name == "phase_coupling"), None)
    measured = _touchdown_phase_differences(touchdowns, coupled_since, stop_time, bridge)
    report = {
        "robot": robot.name, "n": n, "graph": graph, "gains": {"k": k, "m_z": m_z, "m_psi": m_psi},
        "speed_mps": speed, "spacing_m": spacing, "seed": seed, "start_delays_s": starts.round(4).tolist(),
        "certificate": [c.to_dict() for c in conditions],
        "gait_profile": profile.source,
        "fell": fell,
        "robots": [m.report() | {"prefix": p} for m, p in zip(metrics, prefixes)],
        "coupled_from_s": coupled_since, "stopped_at_s": stop_time,
        "initial_phase_spread_rad": round(float(spread[0]), 4) if len(spread) else None,
        "final_phase_spread_rad": round(float(spread[-1]), 5) if len(spread) else None,
        "synchronized_after_s": None if synced_at is None else round(synced_at, 3),
        "sync_tolerance_rad": sync_tolerance,
        "empirical_phase_rate_per_s": rate,
        "certified_phase_rate_per_s": phase_rate,
        "rate_not_below_certified": bool(rate is not None and phase_rate is not None and rate >= phase_rate),
        "measured_touchdown_phase_difference_rad": measured,
        "final_position_spread_m": round(float(np.ptp(z_log[-1])), 4) if len(z_log) else None,
        "bridge_saturated_ratio": round(saturated / max(decisions, 1), 4),
        "rtf": round(states[0].t / wall, 3),
    }
    log(f"fell: {str(fell).lower()}  phase spread {report['initial_phase_spread_rad']} -> "
        f"{report['final_phase_spread_rad']} rad, below {sync_tolerance} rad after {report['synchronized_after_s']} s; "
        f"empirical rate {rate if rate is None else round(rate, 3)} 1/s vs certified {phase_rate}; "
        f"measured touch-down phase difference {measured} rad; rtf {report['rtf']}")
    write_report(report, out_dir, log)
    if out_dir is not None and len(times):
        _plot(Path(out_dir) / "phases.png", times - times[0], phase_log, dispersion, z_log, phase_rate, sync_tolerance)
        log(f"wrote {Path(out_dir) / 'phases.png'}")
    return report


def _touchdown_phase_differences(touchdowns, coupled_since, stop_time, bridge: GaitBridge) -> float | None:
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


def _plot(path: Path, times, phases, dispersion, z, certified_rate, tolerance) -> None:
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
