"""Contraction certificates are never optimistic: every certified rate is at most the condition's
brute-force worst case, and at most what simulation shows (issue: certificates that are never optimistic).

The brute force here is written independently of ``crowd.worst_case``: an explicit loop over the
corners of the parameter box and over random interior points, one eigenvalue problem at a time.
"""

import itertools

import numpy as np
import pytest

from robot_ctrl.cli import main
from robot_ctrl.crowd.audit import random_adjacency
from robot_ctrl.crowd.certificates import CouplingConfig, certify
from robot_ctrl.crowd.coupling_graph import TOPOLOGIES, CouplingGraph
from robot_ctrl.crowd.experiments import run_group
from robot_ctrl.crowd.gait_coupling import GaitCoupling


def by_name(conditions):
    return {c.name: c for c in conditions}


def basis(n):
    """Orthonormal rows spanning 1⊥ (Gram-Schmidt, not the library's QR)."""
    rows = []
    for i in range(n - 1):
        v = np.zeros(n)
        v[: i + 1] = 1.0
        v[i + 1] = -(i + 1)
        rows.append(v / np.linalg.norm(v))
    return np.array(rows)


def top_eigenvalue(J, V):
    return float(np.linalg.eigvalsh(V @ ((J + J.T) / 2) @ V.T)[-1])


def worst_profile_rate(L, gain, g_low, g_high, side, rng, interior=20):
    """−max λ_max over the box's corners and random interior points, one matrix at a time."""
    n, V = L.shape[0], basis(L.shape[0])
    points = [np.array(c) for c in itertools.product((g_low, g_high), repeat=n)]
    points += list(rng.uniform(g_low, g_high, (interior, n)))
    worst = -np.inf
    for g in points:
        J = -gain * (L @ np.diag(g) if side == "right" else np.diag(g) @ L)
        worst = max(worst, top_eigenvalue(J, V))
    return -worst


def test_closed_forms_for_every_size_and_weight():
    for topology, n, w in itertools.product(TOPOLOGIES, range(2, 31), (0.1, 1.0, 2.5)):
        graph = CouplingGraph.named(topology, n, weight=w)
        spectrum = graph.projected_eigenvalues  # numerical, from the dense Laplacian
        assert graph.closed_form_lambda_plus() == pytest.approx(spectrum[0], rel=1e-9, abs=1e-12), (topology, n)
        assert graph.closed_form_lambda_top() == pytest.approx(spectrum[-1], rel=1e-9), (topology, n)
        assert graph.lambda_max == pytest.approx(np.linalg.eigvalsh(graph.laplacian)[-1], rel=1e-9), (topology, n)


def test_the_reported_cases_are_certified_correctly(capsys):
    # A ring of two is one link: λ⁺ = 2, so k = 0.3 does not contract (k λ⁺ − 1 = −0.4).
    assert main(["crowd", "certify", "--graph", "ring", "--n", "2", "--k", "0.3"]) == 1
    out = capsys.readouterr().out
    assert "λ⁺ = 2," in out and "hopf_diffusive" in out and "violated" in out.split("hopf_diffusive")[1].split("\n")[0]
    hopf = by_name(certify(CouplingConfig(CouplingGraph.named("all", 6, weight=0.1), k=0.3)))["hopf_diffusive"]
    assert not hopf.holds and hopf.margin == pytest.approx(0.3 * 0.6 - 1) and hopf.exact
    assert by_name(certify(CouplingConfig(CouplingGraph.named("star", 2), k=0.3)))["phase_coupling"].rate == pytest.approx(0.6)
    assert main(["crowd", "certify", "--graph", "all", "--n", "6", "--weight", "0.1", "--k", "0.3"]) == 1
    assert "λ⁺ = 0.6," in capsys.readouterr().out


def test_no_certificate_is_optimistic_against_the_exhaustive_worst_case():
    """1000 random graphs, N = 2..12, symmetric and asymmetric, weighted: the step-frequency and
    step-length rates never exceed the corner-and-interior brute force; exact ones equal it."""
    rng = np.random.default_rng(7)
    ratios = {"step_frequency": [], "step_length": []}
    for trial in range(1000):
        n = int(rng.integers(2, 13)) if trial % 4 else int(rng.integers(2, 7))
        A = random_adjacency(rng, n, symmetric=bool(trial % 2))
        graph = CouplingGraph.from_adjacency(A)
        g = rng.uniform(0.1, 2.0, int(rng.integers(2, 6)))
        m_d, m_z = rng.uniform(0.1, 2.0, 2)
        conditions = by_name(certify(CouplingConfig(graph, m_d=m_d, m_z=m_z, g=g)))
        for name, gain, side in (("step_frequency", m_d, "right"), ("step_length", m_z, "left")):
            c = conditions[name]
            truth = worst_profile_rate(graph.laplacian, gain, g.min(), g.max(), side, rng, interior=5 if n > 8 else 20)
            assert c.margin <= truth + 1e-9, (name, n, c.margin, truth)
            if c.exact:
                assert c.margin == pytest.approx(truth, abs=1e-9)
            if c.holds:
                assert c.rate <= truth + 1e-9
                ratios[name].append(c.rate / truth)
    for name, r in ratios.items():
        assert len(r) > 50 and max(r) <= 1 + 1e-9


def test_bounds_above_the_exact_size_are_conservative():
    rng = np.random.default_rng(3)
    for n in (13, 14):
        for symmetric in (True, False):
            graph = CouplingGraph.from_adjacency(random_adjacency(rng, n, symmetric))
            g = np.array([0.8, 1.2])
            c = by_name(certify(CouplingConfig(graph, m_d=1.0, g=g)))["step_frequency"]
            truth = worst_profile_rate(graph.laplacian, 1.0, 0.8, 1.2, "right", rng, interior=0)
            assert not c.exact and c.margin <= truth + 1e-9


def test_sine_and_hopf_certificates_are_never_optimistic_against_sampled_states():
    rng = np.random.default_rng(11)
    for trial in range(200):
        n = int(rng.integers(2, 9))
        A = random_adjacency(rng, n, symmetric=bool(trial % 2))
        graph, V = CouplingGraph.from_adjacency(A), basis(n)
        spread, k = rng.uniform(0.2, 1.5), rng.uniform(0.1, 2.0)
        conditions = by_name(certify(CouplingConfig(graph, k=k, k_sine=k, heading_spread=spread)))
        sine, hopf = conditions["schoener_dose"], conditions["hopf_diffusive"]
        for _ in range(30):  # angle sets of spread ≤ Δ, their extremes among them
            psi = rng.choice([-spread / 2, spread / 2], n) if rng.random() < 0.5 else rng.uniform(-spread / 2, spread / 2, n)
            W = A * np.cos(psi[:, None] - psi[None, :])
            assert sine.margin <= -top_eigenvalue(-k * (np.diag(W.sum(axis=1)) - W), V) + 1e-9
        VV = np.kron(V, np.eye(2))
        for radius in (np.zeros(n), rng.uniform(0, 1.5, n)):  # oscillator states; r = 0 is the worst
            angle = rng.uniform(-np.pi, np.pi, n)
            x, y = radius * np.cos(angle), radius * np.sin(angle)
            D = np.zeros((2 * n, 2 * n))
            for i in range(n):
                r2 = x[i] ** 2 + y[i] ** 2
                D[2 * i: 2 * i + 2, 2 * i: 2 * i + 2] = [[1 - r2 - 2 * x[i] ** 2, -2 * x[i] * y[i] - 1],
                                                         [-2 * x[i] * y[i] + 1, 1 - r2 - 2 * y[i] ** 2]]
            value = -top_eigenvalue(D - k * np.kron(graph.laplacian, np.eye(2)), VV)
            assert hopf.margin <= value + 1e-9
            if not radius.any():
                assert hopf.margin == pytest.approx(value, abs=1e-9)  # exact: attained at r = 0


@pytest.mark.parametrize("n,symmetric,seed", [(2, True, 0), (7, False, 1), (30, True, 2), (30, False, 3)])
def test_simulated_phase_rates_are_never_below_the_certified_rate(n, symmetric, seed):
    """Hopf oscillators with diffusive coupling on random weighted graphs up to N = 30: the
    dispersion R̂ decays at least at the certified rate k λ⁺ − 1."""
    rng = np.random.default_rng(seed)
    graph = CouplingGraph.from_adjacency(random_adjacency(rng, n, symmetric))
    k = 1.5 / graph.lambda_plus  # certified rate 0.5 1/s
    result = run_group(GaitCoupling(graph, k=k), duration=12.0, runs=10, seed=seed)
    certified = by_name(result.conditions)["hopf_diffusive"].rate
    assert certified == pytest.approx(0.5) and result.empirical_rate >= certified


@pytest.mark.parametrize("n,symmetric,density,a", [(4, True, 0.5, 0.4), (6, False, 0.5, 0.4), (9, False, 0.7, 0.3),
                                                    (30, True, 1.0, 0.05), (30, False, 1.0, 0.05)])
def test_simulated_step_frequency_convergence_is_never_below_the_certified_rate(n, symmetric, density, a):
    """φ̇ = ω₀ − m_d L G(φ) with g(φ) = 1 + a cos φ, from small phase differences: the distance to
    synchrony ‖V φ‖ shrinks at least at the certified rate (exact up to 12 agents, bound above)."""
    rng = np.random.default_rng(n)
    A = random_adjacency(rng, n, symmetric)
    A = np.where(rng.random((n, n)) < density, np.maximum(A, rng.uniform(0.5, 1.5, (n, n))), A)
    np.fill_diagonal(A, 0.0)
    graph, V, m_d = CouplingGraph.from_adjacency(A), basis(n), 0.6
    phi_grid = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    c = by_name(certify(CouplingConfig(graph, m_d=m_d, g=1 + a * np.cos(phi_grid))))["step_frequency"]
    assert c.holds and c.exact == (n <= 12)
    dt = 0.2 / (m_d * (1 + a) * np.abs(graph.laplacian).sum(axis=1).max())  # well inside Euler's stability
    phi, distances, times = rng.uniform(0, 0.3, n), [], []
    for step in range(int(4.0 / dt)):
        if step % 10 == 0:
            distances.append(np.linalg.norm(V @ phi))
            times.append(step * dt)
        phi = phi + dt * (2 * np.pi - m_d * graph.laplacian @ (phi + a * np.sin(phi)))
    ok = np.array(distances) > 1e-9 * distances[0]
    rate = -np.polyfit(np.array(times)[ok], np.log(np.array(distances)[ok]), 1)[0]
    assert rate >= c.rate * 0.98, (n, rate, c.rate)  # 2 %: Euler's own error


def test_the_audit_command(capsys):
    assert main(["crowd", "audit", "--graphs", "30", "--max-n", "6"]) == 0
    rows = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines()[1:]}
    assert set(rows) == {"phase_coupling", "hopf_diffusive", "step_frequency", "step_length", "schoener_dose"}
    assert all(row[-1] == "0" for row in rows.values())  # no optimistic certificate
    assert rows["step_frequency"][3] == rows["step_frequency"][1] and float(rows["step_frequency"][4]) == 1.0
    assert main(["crowd", "audit", "--graphs", "0"]) == 2
    assert "--graphs 0 is outside the allowed range [1, 100000]" in capsys.readouterr().err


def test_above_twelve_agents_the_relaxation_certifies_what_contracts(capsys):
    """13 to 16 agents: no corner enumeration; the relaxation certifies every gait-profile case the
    sampled worst case says contracts (Weyl's bound: a third), and is never optimistic."""
    assert main(["crowd", "audit", "--graphs", "30", "--min-n", "13", "--max-n", "16"]) == 0
    rows = {line.split()[0]: [int(v) for v in line.split()[1:4]] + [int(line.split()[-1])]
            for line in capsys.readouterr().out.splitlines()[1:]}
    for name in ("step_frequency", "step_length", "schoener_dose"):
        holds, contracting, exact, optimistic = rows[name]
        assert optimistic == 0 and exact == 0 and holds >= 0.9 * contracting > 5, (name, rows[name])


def test_the_relaxation_is_within_a_thousandth_of_the_corners_and_never_above():
    """Where the corners can be enumerated (8-12 agents), the relaxation used above 12 against
    the exact worst case, both gait-profile sides, both signs."""
    import robot_ctrl.crowd.worst_case as worst_case

    rng = np.random.default_rng(11)
    for trial in range(12):
        graph = CouplingGraph.from_adjacency(random_adjacency(rng, int(rng.integers(8, 13)), bool(trial % 2)))
        gain, side = (1.0 if trial % 3 else -0.5), ("right", "left")[trial % 2]
        exact, is_exact = worst_case.profile_coupling_rate(graph, gain, 0.7, 1.3, side)
        limit, worst_case.EXACT_UP_TO = worst_case.EXACT_UP_TO, 0
        try:
            relaxed, relaxed_exact = worst_case.profile_coupling_rate(graph, gain, 0.7, 1.3, side)
        finally:
            worst_case.EXACT_UP_TO = limit
        assert is_exact and not relaxed_exact
        assert exact - 1e-3 * max(1.0, abs(exact)) <= relaxed <= exact + 1e-12, (trial, exact, relaxed)
    for trial in range(6):  # the sine coupling's box of coupled cosines, against its corners
        n = int(rng.integers(4, 6))  # at most 10 coupled pairs: the corners are enumerated
        A = random_adjacency(rng, n, symmetric=False)
        corners, _ = worst_case.sine_coupling_rate(A, 1.0 if trial % 2 else -1.0, 0.9)
        limit, worst_case.EXACT_UP_TO = worst_case.EXACT_UP_TO, 0
        try:
            relaxed, how = worst_case.sine_coupling_rate(A, 1.0 if trial % 2 else -1.0, 0.9)
        finally:
            worst_case.EXACT_UP_TO = limit
        assert "relaxation" in how and corners - 1e-3 * max(1.0, abs(corners)) <= relaxed <= corners + 1e-12


def directed_with_negative_lambda_plus(rng, n):
    """A weakly connected directed graph whose projected symmetric Laplacian is negative definite
    (λ⁺ < 0 and its largest eigenvalue < 0 too, the case a negative gain could contract)."""
    while True:
        A = random_adjacency(rng, n, symmetric=False)
        graph = CouplingGraph.from_adjacency(A)
        if graph.lambda_plus < 0:
            return A, graph


def test_negative_gains_meet_the_largest_eigenvalue(tmp_path, capsys):
    """Issue cases 1-3: with k < 0 the coupling −k L meets the projected symmetric Laplacian's
    largest eigenvalue, not λ⁺; every certificate for every sign is at most the brute force."""
    rng = np.random.default_rng(5)
    A, graph = directed_with_negative_lambda_plus(rng, 6)
    assert graph.lambda_top > 0  # some direction is still pulled apart by a negative gain
    V = basis(graph.n)
    for k in (-10.0, -0.5, 0.5, 10.0):
        c = by_name(certify(CouplingConfig(graph, k=k)))
        truth = -top_eigenvalue(-k * graph.laplacian, V)
        assert c["phase_coupling"].margin == pytest.approx(truth, abs=1e-9)
        assert c["hopf_diffusive"].margin == pytest.approx(truth - 1, abs=1e-9)
        assert c["phase_coupling"].holds == (truth > 0)
    path = tmp_path / "directed.txt"
    np.savetxt(path, A)
    assert main(["crowd", "certify", "--adjacency", str(path), "--k", "-10"]) == 1
    out = capsys.readouterr().out
    assert "hopf_diffusive" in out and "holds" not in out.split("hopf_diffusive")[1].split("\n")[0]
    assert main(["crowd", "run", "--adjacency", str(path), "--k", "-10", "--runs", "2", "--duration", "1"]) == 2
    assert "violated" in capsys.readouterr().err
    # Above the exactly enumerated sizes: step frequency and length with negative gains, and the
    # sine coupling with more than 12 coupled pairs, stay at or below the sampled worst case.
    for symmetric in (True, False):
        graph = CouplingGraph.from_adjacency(random_adjacency(rng, 13, symmetric))
        c = by_name(certify(CouplingConfig(graph, m_d=-5.0, m_z=-5.0, k_sine=-1.0, g=np.array([0.8, 1.2]),
                                           heading_spread=np.radians(80))))
        for name, side in (("step_frequency", "right"), ("step_length", "left")):
            truth = worst_profile_rate(graph.laplacian, -5.0, 0.8, 1.2, side, rng, interior=0)
            assert not c[name].exact and not c[name].holds and c[name].margin <= truth + 1e-9, (name, symmetric)
        assert not c["schoener_dose"].holds


def test_a_rescaled_graph_is_judged_as_the_original(capsys):
    """Issue case 4: a directed graph with its weights scaled by 1e-9 and the gain by 1e9 is the
    same dynamics: not symmetric, still connected, the same certificate."""
    rng = np.random.default_rng(9)
    A = random_adjacency(rng, 7, symmetric=False)
    original = CouplingGraph.from_adjacency(A)
    tiny = CouplingGraph.from_adjacency(1e-9 * A)
    assert not original.symmetric and not tiny.symmetric and tiny.connected
    g = np.array([0.5, 1.5])
    for name in ("step_frequency", "schoener_dose", "phase_coupling"):
        a = by_name(certify(CouplingConfig(original, k=1.0, m_d=1.0, k_sine=1.0, g=g)))[name]
        b = by_name(certify(CouplingConfig(tiny, k=1e9, m_d=1e9, k_sine=1e9, g=g)))[name]
        assert a.holds == b.holds and b.margin == pytest.approx(a.margin, rel=1e-6), name
        assert a.method == b.method


def test_certify_needs_a_gain_and_the_low_pass_needs_md(capsys):
    assert main(["crowd", "certify", "--graph", "ring", "--n", "5"]) == 2
    err = capsys.readouterr().err
    assert "give at least one coupling gain (--k, --alpha, --md, --mz, --mpsi, --ksine)" in err
    assert len(err.strip().splitlines()) == 1
    assert main(["crowd", "certify", "--graph", "ring", "--n", "5", "--k", "1", "--lowpass", "2"]) == 2
    err = capsys.readouterr().err
    assert "--lowpass is the step-frequency coupling's position filter: it needs --md" in err


def test_the_walking_groups_step_length_certificate_covers_every_gait_frequency_the_bridge_allows():
    """Each robot's gait frequency may be anywhere in ω₀/1.25 .. ω₀/0.8 (the bridge's time-scale
    clamp): the step-length Jacobian −m_z D_ω D_g L over that box of ω_i g_i, brute-forced here at
    its 256 corners for a chain of 8 with Talos's profile, is what is certified (it does not
    contract: certifying at the lowest frequency alone said it did, at 0.0101 1/s)."""
    from robot_ctrl.crowd.gait_bridge import GaitBridge
    from robot_ctrl.crowd.gait_coupling import GaitCoupling
    from robot_ctrl.crowd.gait_profile import GaitProfile
    from robot_ctrl.crowd.group_walk_settings import GroupWalk, certified_coupling

    settings = GroupWalk(n=8, graph="chain")
    bridge = GaitBridge(0.8, settings.speed)
    profile = GaitProfile.load_or_constant("talos", bridge.omega0, settings.speed)
    graph = CouplingGraph.named("chain", 8)
    lo, hi = bridge.omega0 / 1.25 * profile.g.min(), bridge.omega0 / 0.8 * profile.g.max()
    V = basis(8)
    worst = max(top_eigenvalue(-settings.m_z * np.diag(h) @ graph.laplacian, V)
                for h in itertools.product((lo, hi), repeat=8))
    law = GaitCoupling(graph, k=settings.k, m_z=settings.m_z, m_psi=settings.m_psi)
    found = {c.name: c for c in law.certify(profile.g, bridge.omega0 / 1.25, omega_max=bridge.omega0 / 0.8)}
    assert found["step_length"].margin == pytest.approx(-worst, abs=1e-9) and worst > 0.01
    assert not found["step_length"].holds
    with pytest.raises(ValueError, match="step_length"):
        certified_coupling("talos", settings, 0.8, lambda line: None)


def test_the_lowpass_line_holds_only_where_the_papers_argument_does():
    """Paper 003's low-pass argument drops off-diagonal blocks ±(m_d/α) V L D_g Vᵀ from the
    symmetric part, which vanish for all-to-all coupling or a constant profile only: a chain of 8
    with Talos's profile is not covered (its unfiltered step-frequency condition holds, the line
    does not), the same chain with a constant profile and all-to-all with Talos's profile are."""
    from robot_ctrl.crowd.gait_profile import GaitProfile

    g = GaitProfile.load_or_constant("talos", np.pi / 0.8, 0.2).g
    chain = CouplingGraph.named("chain", 8)
    V = basis(8)
    asymmetric = V @ chain.laplacian @ np.diag(g[:8]) @ V.T
    assert np.abs(asymmetric - asymmetric.T).max() > 1e-3  # the blocks the argument drops are not zero
    for graph, profile, covered in ((chain, g, False), (chain, np.full(4, 0.2), True), (CouplingGraph.named("all", 8), g, True)):
        found = {c.name: c for c in certify(CouplingConfig(graph, m_d=1.0, lowpass=100.0, g=profile))}
        assert found["step_frequency"].holds and found["lowpass_filter"].holds == covered
