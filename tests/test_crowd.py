"""Coupling graphs, contraction certificates and the kinematic Hopf-network crowd (thesis 4.3)."""

import json

import numpy as np
import pytest

from robot_ctrl.cli import main
from robot_ctrl.crowd.certificates import CouplingConfig, certify
from robot_ctrl.crowd.coupling_graph import TOPOLOGIES, CouplingGraph
from robot_ctrl.crowd.experiments import run_group
from robot_ctrl.crowd.gait_coupling import GaitCoupling


@pytest.mark.parametrize("topology", TOPOLOGIES)
@pytest.mark.parametrize("n", [3, 5, 8, 16, 49])
def test_table_4_1_closed_forms_match_the_spectrum(topology, n):
    graph = CouplingGraph.named(topology, n)
    assert graph.connected
    spectrum = graph.projected_eigenvalues  # numerical, from the dense Laplacian
    assert graph.lambda_plus == pytest.approx(spectrum[0], abs=1e-9)  # closed form (Table 4.1)
    assert graph.lambda_top == pytest.approx(spectrum[-1], abs=1e-9)


def by_name(conditions):
    return {c.name: c for c in conditions}


def test_hopf_bound_on_both_sides():
    # Thesis 4.3.5: three all-to-all characters contract for k ≥ 1/3; k = 0.111 violates the bound.
    assert by_name(certify(CouplingConfig(CouplingGraph.named("all", 3), k=0.334)))["hopf_diffusive"].holds
    low = by_name(certify(CouplingConfig(CouplingGraph.named("all", 3), k=0.111)))["hopf_diffusive"]
    assert not low.holds and low.rate is None and low.margin == pytest.approx(3 * 0.111 - 1)
    chain = by_name(certify(CouplingConfig(CouplingGraph.named("chain", 3), k=1.5)))["hopf_diffusive"]
    assert chain.rate == pytest.approx(1.5 * 1.0 - 1.0)  # λ⁺ = 2(1 − cos(π/3)) = 1


def test_numerical_certificate_agrees_with_the_closed_form_on_a_symmetric_graph():
    A = -CouplingGraph.named("ring", 6).laplacian
    np.fill_diagonal(A, 0.0)
    numeric = by_name(certify(CouplingConfig(CouplingGraph.from_adjacency(A), k=1.5)))["hopf_diffusive"]
    closed = by_name(certify(CouplingConfig(CouplingGraph.named("ring", 6), k=1.5)))["hopf_diffusive"]
    assert numeric.method.startswith("numerical") and closed.method.startswith("closed form")
    assert numeric.margin == pytest.approx(closed.margin, abs=1e-9) and numeric.exact and closed.exact


def test_disconnected_and_invalid_graphs_are_reported():
    A = np.zeros((4, 4))
    A[0, 1] = A[1, 0] = A[2, 3] = A[3, 2] = 1.0
    (cond,) = certify(CouplingConfig(CouplingGraph.from_adjacency(A), k=1.0))
    assert cond.name == "connectivity" and not cond.holds
    with pytest.raises(ValueError, match="rows must sum to zero"):
        CouplingGraph.from_laplacian([[1.0, -0.5], [-1.0, 1.0]])
    with pytest.raises(ValueError, match="≥ 0"):
        CouplingGraph.from_adjacency([[0.0, -1.0], [1.0, 0.0]])


def test_step_frequency_and_leader_conditions():
    g = 1.0 + 0.3 * np.sin(np.linspace(0, 2 * np.pi, 64, endpoint=False))
    conds = by_name(certify(CouplingConfig(CouplingGraph.named("all", 5), k=0.1, alpha=1.5, m_d=0.4, lowpass=3.0, g=g)))
    assert conds["step_frequency"].rate == pytest.approx(0.4 * g.min() * 5)
    assert conds["leader_group"].holds and conds["leader_group"].rate == pytest.approx(0.5)
    assert conds["leader_group_1perp"].margin == pytest.approx(0.1 * 5 + 1.5 - 1)
    assert conds["lowpass_filter"].margin == pytest.approx(3.0 - np.sqrt(0.4 * g.max() * 5))
    assert not by_name(certify(CouplingConfig(CouplingGraph.named("all", 5), m_d=-0.4, g=g)))["step_frequency"].holds


@pytest.mark.parametrize("topology,n", [("all", 5), ("ring", 8), ("chain", 5), ("star", 8)])
def test_empirical_rate_beats_the_certificate_and_the_slope_matches(topology, n):
    graph = CouplingGraph.named(topology, n)
    lam = graph.closed_form_lambda_plus()
    ks = [1.2 / lam, 2.0 / lam]
    runs = [run_group(GaitCoupling(graph, k=k), duration=15.0, runs=10) for k in ks]
    for k, result in zip(ks, runs):
        certified = by_name(result.conditions)["hopf_diffusive"].rate
        assert result.empirical_rate >= certified
    slope = (runs[1].empirical_rate - runs[0].empirical_rate) / (ks[1] - ks[0])
    assert slope == pytest.approx(lam, rel=0.10)


def test_negative_coupling_does_not_converge():
    result = run_group(GaitCoupling(CouplingGraph.named("all", 5), k=-0.3), duration=10.0, runs=10)
    assert result.empirical_rate is None and result.dispersion[-1] > 0.3


def test_cli_certify_and_run(tmp_path, capsys):
    assert main(["crowd", "certify", "--graph", "ring", "--n", "8", "--k", "2.0", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data[0]["name"] == "hopf_diffusive" and data[0]["holds"] is True
    assert main(["crowd", "run", "--graph", "chain", "--n", "5", "--k", "0.3", "--runs", "5"]) == 2
    assert "--allow-unstable" in capsys.readouterr().err
    assert main(["crowd", "run", "--graph", "all", "--n", "4", "--k", "0.5", "--runs", "5", "--duration", "10",
                 "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["final_phase_spread_rad"] < 0.1
    # The certified rate is a lower bound of the measured one (phase coupling: k λ⁺ = 0.5 · 4 = 2).
    certified = {c["name"]: c for c in report["certificate"]}["phase_coupling"]["rate"]
    assert certified == pytest.approx(2.0) and certified * 0.95 <= report["empirical_rate_per_s"]
    import matplotlib.image

    image = matplotlib.image.imread(tmp_path / "dispersion.png")  # a plot: light background, dark curves
    assert image.shape[0] > 200 and image.shape[1] > 300
    # A repulsive step-frequency coupling diverges: refused, and run anyway it stops, saying so.
    diverging = ["crowd", "run", "--graph", "ring", "--n", "14", "--k", "0.5", "--md", "-5", "--runs", "2",
                 "--duration", "20", "--out", str(tmp_path / "diverging")]
    assert main(diverging) == 2 and "step_frequency" in capsys.readouterr().err
    assert main([*diverging, "--allow-unstable"]) == 1
    assert "the group's state became non-finite at t = 1.21 s" in capsys.readouterr().err
    assert not (tmp_path / "diverging" / "report.json").exists()
    luminance = image[..., :3].mean(axis=2)
    assert (luminance > 0.9).mean() > 0.5 and (luminance < 0.5).mean() > 0.005


def test_schoener_dose_region_and_rate():
    graph = CouplingGraph.named("ring", 5)
    spread = np.pi / 3
    sd = by_name(certify(CouplingConfig(graph, k_sine=0.8, heading_spread=spread)))["schoener_dose"]
    assert sd.holds and sd.rate == pytest.approx(0.8 * graph.lambda_plus * 0.5)
    # The closed-form rate bounds the numerical one of the same graph given as a matrix.
    A = -graph.laplacian
    np.fill_diagonal(A, 0.0)
    A[0, 1] *= 1.5  # asymmetric: the box of coupled cosines
    boxed = by_name(certify(CouplingConfig(CouplingGraph.from_adjacency(A), k_sine=0.8, heading_spread=spread)))
    assert "vertices" in boxed["schoener_dose"].method and boxed["schoener_dose"].holds
    assert not boxed["schoener_dose"].exact and boxed["schoener_dose"].rate <= sd.rate
    assert not by_name(certify(CouplingConfig(graph, k_sine=-0.1)))["schoener_dose"].holds
    goal = by_name(certify(CouplingConfig(graph, m_psi=0.7)))["heading_goal_region"]
    assert goal.holds and goal.rate == pytest.approx(0.7)


def test_sine_headings_converge_at_the_certified_rate():
    """Eq. 4.45 integrated from headings inside ±30°: the spread decays at least as fast as certified."""
    graph = CouplingGraph.named("chain", 4)
    law = GaitCoupling(graph, k=0.6)
    rate = by_name(law.certify(np.ones(4), 1.0, spread=np.radians(60)))["schoener_dose"].rate
    psi = np.radians([30.0, -30.0, 10.0, -5.0])
    def disagreement(p):  # distance to the synchronization manifold, ‖V ψ‖
        return np.linalg.norm(p - p.mean())

    dt, start = 0.001, disagreement(psi)
    for _ in range(3000):
        psi = psi + dt * law.phase_rates(psi, np.zeros(4), 0.0)  # ψ̇_i = −k Σ_j A_ij sin(ψ_i − ψ_j)
    assert 0 < disagreement(psi) <= start * np.exp(-rate * 3.0)


def test_gait_bridge_maps_frequency_and_step_length():
    from robot_ctrl.crowd.gait_bridge import GaitBridge

    bridge = GaitBridge(step_period=0.8, speed=0.2)
    cmd = bridge.command(bridge.omega0 * 1.1, 0.2, 0.05)
    assert cmd.time_scale == pytest.approx(1 / 1.1) and not cmd.saturated
    assert cmd.velocity == pytest.approx((1.2 * 1.1 * 0.2, 0.0, 0.05))  # (1 + μ) ω/ω₀ v₀
    slow = bridge.command(bridge.omega0 * 0.5, 0.9, 1.0)
    assert slow.saturated and slow.time_scale == 1.25 and slow.velocity[0] == pytest.approx(1.5 * 0.2 / 1.25)
    assert slow.velocity[2] == 0.3
    with pytest.raises(ValueError, match="finite"):
        bridge.command(np.nan, 0.0, 0.0)


def test_phase_coupling_matches_the_linear_law_near_synchrony():
    graph = CouplingGraph.named("star", 4)
    law = GaitCoupling(graph, k=0.5)
    phases = np.array([0.01, -0.02, 0.015, 0.0]) + 2 * np.pi * np.array([0, 1, 3, -2])  # whole cycles apart
    linear = 1.0 - 0.5 * graph.laplacian @ np.array([0.01, -0.02, 0.015, 0.0])
    np.testing.assert_allclose(law.phase_rates(phases, np.zeros(4), 1.0), linear, atol=1e-5)


def test_step_length_and_heading_control_converge_no_slower_than_certified():
    """Scenario 3 + heading consensus with the gait profile measured on Talos (min g / mean g ≈ 0.67)."""
    from robot_ctrl.crowd.gait_profile import GaitProfile

    omega = 2 * np.pi
    profile = GaitProfile.load_or_constant("talos", omega, 1.0)
    assert profile.source.startswith("measured")
    law = GaitCoupling(CouplingGraph.named("all", 8), k=0.5, m_z=0.3, m_psi=0.5)
    result = run_group(law, duration=15.0, runs=10, profile=profile, omega=omega)
    conds = by_name(result.conditions)
    assert result.final_spread < 1e-6
    assert result.position_rate >= conds["step_length"].margin  # ρ_z = m_z ω min g λ⁺
    assert result.heading_rate >= conds["heading_consensus"].rate
    assert result.position_error[-1] < 1e-6 * result.position_error[0]


def test_step_frequency_control_rate_is_tight_for_a_constant_profile_and_diverges_for_negative_gain():
    graph = CouplingGraph.named("all", 6)
    result = run_group(GaitCoupling(graph, m_d=0.5), duration=15.0, runs=10)
    certified = by_name(result.conditions)["step_frequency"].rate  # m_d min g λ⁺, g = 1/ω
    assert result.position_rate == pytest.approx(certified, rel=0.02)
    unstable = run_group(GaitCoupling(graph, m_d=-0.5), duration=5.0, runs=10)
    assert not by_name(unstable.conditions)["step_frequency"].holds
    assert unstable.position_error[-1] > 10 * unstable.position_error[0]


@pytest.mark.parametrize("topology", TOPOLOGIES)
def test_a_named_graph_applies_its_laplacian_without_the_matrix(topology):
    """Every named topology's L x, as the dense Laplacian gives it (all-to-all by w (N x − Σ x),
    the others sparse), and its spectral figures in closed form."""
    rng = np.random.default_rng(3)
    for n in (2, 3, 8):
        graph = CouplingGraph.named(topology, n, weight=0.7)
        L = graph.laplacian
        x = rng.normal(size=(n, 3))
        np.testing.assert_allclose(graph.apply(x), L @ x, atol=1e-12)
        np.testing.assert_allclose(graph.lambda_max, np.linalg.eigvalsh(L)[-1], atol=1e-12)
        np.testing.assert_allclose(graph.scale, np.abs(L).max(), rtol=1e-12)
        assert graph.symmetric and graph.connected


def test_a_hundred_thousand_agents_are_certified_and_simulated_in_closed_form_and_sparse(capsys):
    """A ring of 100,000 agents: its dense Laplacian would take 80 GB; the certificate comes from
    Table 4.1's closed form (λ⁺ = 2 (1 − cos 2π/N)), the simulation from sparse products."""
    n = 100_000
    assert main(["crowd", "certify", "--graph", "ring", "--n", str(n), "--k", "1", "--md", "1", "--alpha", "2"]) == 1
    out = capsys.readouterr().out
    assert f"λ⁺ = {2 * (1 - np.cos(2 * np.pi / n)):.6g}" in out and "λ_max = 4" in out
    assert "phase_coupling" in out and "hopf_diffusive" in out and "step_frequency" in out
    graph = CouplingGraph.named("ring", n)
    with pytest.raises(ValueError, match="dense Laplacian of 100000 agents"):
        graph.laplacian
    from robot_ctrl.crowd.hopf_network import simulate_crowd

    out = simulate_crowd(GaitCoupling(graph, k=0.5, m_z=0.1, m_psi=0.5), 0.05, runs=1, dt=0.01)
    assert out.phases.shape == (6, 1, n) and np.isfinite(out.z).all()
