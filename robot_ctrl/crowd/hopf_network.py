"""Kinematic crowd: Andronov-Hopf gait oscillators with the crowd control laws (thesis 4.3-4.4),
many independent runs at once.

Each agent i has the oscillator state ``x_i = (x, y)`` (phase φ_i = atan2(y, x)), a position z_i
[m] along its path, a heading ψ_i [rad] and a floor position p_i [m] (world frame)::

    ω_i = ω₀ − m_d (L (z − o))_i                       step frequency (eq. 4.28)
    ẋ_i = f(x_i; ω_i) − k (L x)_i                      diffusive phase coupling (eq. 4.25)
    ż_i = (1 + μ_i) φ̇_i g(φ_i),  μ_i = −m_z (L (z − o))_i     step length (eq. 4.30)
    ψ̇_i = m_ψ sin(χ − ψ_i)                             heading consensus (eq. 4.33)
    ṗ_i = ż_i (cos ψ_i, sin ψ_i)

with f the Andronov-Hopf oscillator of eq. 4.14 (limit cycle r = 1, frequency ω), φ̇_i the
oscillator's instantaneous angular speed and g(φ) the gait profile (``GaitProfile``: measured on
the walking robot, or constant). Integrated with RK4 for ``runs`` initial conditions in arrays
(runs, N, ...): phases uniform on the circle, radii uniform in [0.5, 1.5], positions uniform in
±``z_spread``/2 around the formation offsets, headings uniform in ±``heading_spread``/2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.crowd.coupling_graph import CouplingGraph
from robot_ctrl.crowd.gait_coupling import GaitCoupling


def hopf_field(state: np.ndarray, omega) -> np.ndarray:
    """f(x) of eq. 4.14 for states (..., 2); ``omega`` broadcasts over the leading axes."""
    x, y = state[..., 0], state[..., 1]
    radial = 1.0 - (x * x + y * y)
    return np.stack([radial * x - omega * y, radial * y + omega * x], axis=-1)


@dataclass(frozen=True)
class CrowdTrajectory:
    times: np.ndarray  # (T,) [s]
    phases: np.ndarray  # (T, runs, N) [rad]
    z: np.ndarray | None  # (T, runs, N) [m], None without position dynamics
    headings: np.ndarray | None  # (T, runs, N) [rad], None without heading dynamics
    positions: np.ndarray | None  # (T, runs, N, 2) floor positions [m], with position dynamics


#: Work a simulation may take: RK4 steps, and values of the recorded trajectories (8 bytes each).
MAX_STEPS = 2_000_000
MAX_RECORDED = 200_000_000


def simulate_crowd(coupling: GaitCoupling, duration: float, omega: float = 2 * np.pi, g: np.ndarray | None = None,
                   runs: int = 100, seed: int = 0, dt: float | None = None, z_spread: float = 2.0,
                   heading_spread: float = np.pi / 2, record_every: int = 1) -> CrowdTrajectory:
    """Simulate the crowd for ``duration`` seconds at nominal gait frequency ``omega`` [rad/s] with
    gait profile ``g`` (dz/dφ per phase bin [m/rad], default constant 1/ω: 1 m/s). Positions and
    headings are simulated when their gains (m_d, m_z; m_ψ) are non-zero or ``g`` is given. Without
    ``dt`` the step is ``min(0.01, 1 / ((|k| + 1.5 |m_z| ω max g + |m_d| max g) λ_max + ω + 2))`` s,
    inside RK4's stability region for the fastest coupled mode."""
    graph = coupling.graph
    n = graph.n
    k, m_d, m_z, m_psi = coupling.k, coupling.m_d, coupling.m_z, coupling.m_psi
    if not (np.isfinite(duration) and duration > 0) or not (isinstance(runs, int) and runs >= 1):
        raise ValueError(f"duration = {duration} s must be > 0 and runs = {runs!r} an integer ≥ 1")
    walk = bool(m_d or m_z) or g is not None
    turn = bool(m_psi)
    g = np.full(32, 1.0 / omega) if g is None else np.asarray(g, dtype=float)
    bins = len(g)
    if dt is None:  # the fastest coupled mode of each law sets the step
        stiff = (abs(k) + abs(m_z) * 1.5 * omega * g.max() + abs(m_d) * g.max()) * graph.lambda_max
        dt = min(0.01, 1.0 / (stiff + omega + 2.0))

    def laplacian_times(values):  # L applied along the agent axis of (runs, N, c): O(N) for named graphs
        flat = np.ascontiguousarray(values.transpose(1, 0, 2)).reshape(n, -1)
        return graph.apply(flat).reshape(n, runs, -1).transpose(1, 0, 2)
    rng = np.random.default_rng(seed)
    radius = rng.uniform(0.5, 1.5, (runs, n))
    angle = rng.uniform(-np.pi, np.pi, (runs, n))
    osc = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)
    z = coupling.offsets + rng.uniform(-z_spread / 2, z_spread / 2, (runs, n))
    psi = rng.uniform(-heading_spread / 2, heading_spread / 2, (runs, n))
    p = np.stack([z * np.cos(psi), z * np.sin(psi)], axis=-1)

    def g_at(phase):  # phase in [−π, π] (atan2): shifted by a whole period it truncates to its bin
        return g.take((phase * (bins / (2 * np.pi)) + bins).astype(np.intp) % bins)

    def rates(osc, z, psi):
        # One product with L per stage: oscillator states and positions minus offsets stacked.
        stacked = np.concatenate([osc, (z - coupling.offsets)[..., None]], axis=-1) if walk else osc
        coupled = laplacian_times(stacked)
        error = coupled[..., 2] if walk else 0.0  # L (z − o)
        w = omega - m_d * error if m_d else omega
        d_osc = hopf_field(osc, w)
        if k:
            d_osc = d_osc - k * coupled[..., :2]
        if not walk:
            return d_osc, None, None
        x, y = osc[..., 0], osc[..., 1]
        phase_rate = (x * d_osc[..., 1] - y * d_osc[..., 0]) / np.maximum(x * x + y * y, 1e-12)
        dz = (1.0 - m_z * error) * phase_rate * g_at(np.arctan2(y, x))
        dpsi = coupling.heading_rates(psi) if turn else None
        return d_osc, dz, dpsi

    steps = int(round(duration / dt))
    frames = steps // record_every + 1
    if steps > MAX_STEPS or frames * runs * n > MAX_RECORDED:
        raise ValueError(f"the simulation would take {steps:.3g} steps of {dt:.3g} s and record {frames * runs * n:.3g} "
                         f"values (limits {MAX_STEPS:.0e} and {MAX_RECORDED:.0e}): lower the duration, the runs or "
                         "the coupling gains (large gains need small steps)")
    phases = np.empty((frames, runs, n))
    zs = np.empty((frames, runs, n)) if walk else None
    psis = np.empty((frames, runs, n)) if walk and turn else None
    ps = np.empty((frames, runs, n, 2)) if walk else None

    def record(frame):
        phases[frame] = np.arctan2(osc[..., 1], osc[..., 0])
        if walk:
            zs[frame], ps[frame] = z, p
            if turn:
                psis[frame] = psi

    def shifted(state, rate, h):  # state + h · rate, parts without dynamics (rate None) unchanged
        return tuple(x if d is None else x + h * d for x, d in zip(state, rate))

    record(0)
    with np.errstate(invalid="ignore", over="ignore"):  # a diverging group ends as NaN, checked below
        for i in range(steps):
            state = (osc, z, psi)
            stages = [rates(*state)]
            for h in (0.5 * dt, 0.5 * dt, dt):
                stages.append(rates(*shifted(state, stages[-1], h)))
            increment = tuple(None if parts[0] is None else (parts[0] + 2 * parts[1] + 2 * parts[2] + parts[3]) / 6.0
                              for parts in zip(*stages))
            if walk:  # the floor position moves along the heading at the path speed (heading at the step's start)
                p = p + dt * np.stack([increment[1] * np.cos(psi), increment[1] * np.sin(psi)], axis=-1)
            osc, z, psi = shifted(state, increment, dt)
            if (i + 1) % record_every == 0:
                record((i + 1) // record_every)
            if not (np.isfinite(osc).all() and (z is None or np.isfinite(z).all())):
                # Diverged: the rest of the record is NaN (the caller reports when it began).
                frame = (i + 1) // record_every + 1
                for values in (phases, zs, psis, ps):
                    if values is not None:
                        values[frame:] = np.nan
                phases[min(frame - 1, frames - 1)] = np.nan
                break
    times = np.arange(frames) * dt * record_every
    return CrowdTrajectory(times, phases, zs, psis, ps)


def simulate(graph: CouplingGraph, k: float, duration: float, dt: float | None = None, omega: float = 2 * np.pi,
             runs: int = 100, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Phases (steps + 1, runs, N) and times of Hopf oscillators with diffusive coupling k only."""
    out = simulate_crowd(GaitCoupling(graph, k=k), duration, omega=omega, runs=runs, seed=seed, dt=dt)
    return out.phases, out.times
