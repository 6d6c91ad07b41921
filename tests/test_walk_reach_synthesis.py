"""Walk-and-reach synthesis (thesis 3.3.3-3.4.2, 3.7): demonstrations, dynamic primitives,
planning, blending and the online synthesizer, learned from the versioned demonstration set."""

import math

import numpy as np
import pytest

from robot_ctrl.eval.campaigns.feasible_demonstrations import demonstration_from_run, touchdowns
from robot_ctrl.scenarios.walk_reach_synthesis import GoalJump, run_synthesis
from robot_ctrl.synthesis.demonstrations import (
    DemonstrationSet,
    default_dataset_path,
    generate_demonstrations,
    kinematic_dataset_path,
)
from robot_ctrl.synthesis.learned import load_primitives
from robot_ctrl.synthesis.lwr import LocallyWeightedRegression
from robot_ctrl.synthesis.oscillator import phase, star_step
from robot_ctrl.synthesis.source_map import SourceMap, delay_rotations
from robot_ctrl.synthesis.step_planning import (
    GAMMA,
    ActionRanges,
    blend_nonperiodic,
    blend_weight,
    plan_steps,
)
from robot_ctrl.synthesis.synthesizer import Synthesizer, WalkReachGoal


@pytest.fixture(scope="module")
def primitives(talos):
    return load_primitives(talos)


# -- dynamic primitives ---------------------------------------------------------------------------
@pytest.mark.parametrize("start", [(1e-3, 0.0), (0.0, -0.02), (3.0, 4.0), (-0.6, 0.1)])
def test_hopf_oscillator_converges_to_the_unit_cycle_from_any_nonzero_state(start):
    omega, dt = 2 * np.pi / 1.6, 0.005
    x = np.array([start])  # a leader alone
    phases = []
    for _ in range(int(20 / dt)):  # from r = 1e-3, ṙ ≈ r: about 7 s to grow, then rate 2 to the cycle
        x = star_step(x, omega, 10.0, dt)
        phases.append(np.arctan2(x[0, 1], x[0, 0]))
    assert abs(np.hypot(*x[0]) - 1) < 1e-6
    rate = np.diff(np.unwrap(phases[-200:])) / dt
    np.testing.assert_allclose(rate, omega, rtol=1e-6)


def test_star_coupled_followers_lock_onto_the_leader():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(6, 2))
    for _ in range(int(5 / 0.005)):
        x = star_step(x, 4.0, 10.0, 0.005)
    assert np.abs(x[1:] - x[0]).max() < 1e-6


def test_source_map_turns_delays_into_phase_plane_rotations():
    T = 50
    t = np.arange(T)
    S = np.stack([np.cos(2 * np.pi * t / T) + 0.3 * np.sin(6 * np.pi * t / T), np.sin(4 * np.pi * t / T) ** 3])
    f = SourceMap.fit(S)
    tau = np.array([[7.3, 31.0]])
    angle = 1.0
    x = np.array([[math.cos(angle), math.sin(angle)]] * 2)
    got = f.delayed(x, delay_rotations(tau, T))[0]
    shifted = angle - 2 * np.pi * tau[0] / T
    want = [np.cos(shifted[0]) + 0.3 * np.sin(3 * shifted[0]), np.sin(2 * shifted[1]) ** 3]
    np.testing.assert_allclose(got, want, atol=1e-4)


def test_locally_weighted_regression_is_exact_on_affine_data_and_local_on_curved_data():
    x = np.linspace(0, 1, 15)
    lwr = LocallyWeightedRegression.fit(x, 2 * x + 1)
    assert abs(lwr(0.37)[0] - 1.74) < 1e-6
    curved = LocallyWeightedRegression.fit(x, np.sin(3 * x), bandwidth=0.2)
    global_fit = np.polyval(np.polyfit(x, np.sin(3 * x), 1), 0.5)
    assert abs(curved(0.5)[0] - np.sin(1.5)) < 0.1 * abs(global_fit - np.sin(1.5))


# -- planning and blending ------------------------------------------------------------------------
RANGES = ActionRanges(normal=(0.26, 0.42), short=(0.14, 0.46))


def test_step_planning_follows_end_state_comfort():
    c = 0.55
    rho = GAMMA / (1 - GAMMA)
    plan = plan_steps(c + 0.6, c, RANGES)
    assert plan.actions == (1, 2, 3)
    np.testing.assert_allclose(plan.lengths, (0.6 * (1 - GAMMA), 0.6 * GAMMA, 0.0))  # the short cycle is γ
    assert plan.lengths[1] < plan.lengths[0]  # slowing down before the stop
    longer = plan_steps(c + 1.8, c, RANGES)  # D1 would be 1.1 m: three extra normal cycles, same proportion
    assert longer.actions == (1, 1, 1, 1, 2, 3)
    d1 = longer.lengths[0]
    assert RANGES.normal[0] <= d1 <= RANGES.normal[1] and abs(longer.lengths[-2] / d1 - rho) < 1e-9
    assert abs(sum(longer.lengths) - 1.8) < 1e-12
    assert plan_steps(c + 1.0, c, RANGES).actions == (1, 1, 2, 3)  # one extra is enough here
    short = plan_steps(c + 0.35, c, RANGES)  # D1 = 0.215 m is below the normal range: one short cycle
    assert short.actions == (2, 3) and short.lengths == (0.35, 0.0)
    after = plan_steps(c + 1.0, c, RANGES, after_short=True)  # slowing down already: short cycles only
    assert set(after.actions[:-1]) == {2} and abs(sum(after.lengths) - 1.0) < 1e-12
    with pytest.raises(ValueError, match="goal distance = 0.650 m is too close"):
        plan_steps(0.65, c, RANGES)


def test_blending_weight_and_sign_rule_are_continuous():
    b = 0.2
    assert blend_weight(-b * np.pi - 1e-9) == 0 and blend_weight(b * np.pi + 1e-9) == 1
    assert abs(blend_weight(0.0) - 0.5) < 1e-12
    phi = np.linspace(-np.pi / 2, np.pi / 2, 2001)
    assert np.abs(np.diff(blend_weight(phi))).max() < 0.01
    w_prev, w_post = np.array([0.7, -0.4]), np.array([-0.3, 0.9])
    # W s0 across φ = 0, where s0 = cos(φ/2) of the action in progress jumps from −1 to 1.
    before = blend_nonperiodic(-1e-9, w_prev, w_post) * -1.0
    after = blend_nonperiodic(1e-9, w_prev, w_post) * 1.0
    np.testing.assert_allclose(before, after, atol=1e-8)
    np.testing.assert_allclose(after, (w_post - w_prev) / 2, atol=1e-8)
    np.testing.assert_allclose(blend_nonperiodic(-b * np.pi, w_prev, w_post), w_prev)
    np.testing.assert_allclose(blend_nonperiodic(b * np.pi, w_prev, w_post), w_post)


# -- learned model and synthesizer ----------------------------------------------------------------
def test_demonstration_set_is_versioned_and_regenerates_identically(talos):
    stored = DemonstrationSet.load(kinematic_dataset_path("talos"))
    fresh = generate_demonstrations(talos)
    assert stored.provenance["source"] == "kinematic"
    assert stored.channels == fresh.channels and len(stored.trials) == 30
    for a, b in zip(stored.trials, fresh.trials):
        assert a.slot == b.slot
        np.testing.assert_array_equal(a.bounds, b.bounds)
        np.testing.assert_allclose(a.signals, b.signals, atol=1e-5)  # stored as float32
        advance = [b.signals[b.bounds[k] : b.bounds[k + 1], 0].sum() * fresh.dt for k in range(3)]
        np.testing.assert_allclose(advance, b.lengths, atol=1e-9)


def test_mixture_model_quality_per_action(primitives):
    q = {row["action"]: row for row in primitives.quality}
    assert q[1]["sources"] == 4 and q[2]["sources"] == q[3]["sources"] == 6
    assert all(row["Q_anechoic"] > 0.99 for row in q.values())
    assert q[1]["Q_anechoic"] > q[1]["Q_pca"]  # shifted gait shapes: PCA needs more sources


def training_distances(primitives):
    demos = DemonstrationSet.load(default_dataset_path("talos"))
    return np.array([primitives.comfort_distance + t.lengths.sum() for t in demos.trials])


def test_unseen_distances_realize_the_planned_steps_and_end_at_comfort(primitives):
    c = primitives.comfort_distance
    # Spanning what one normal + one short cycle cover, (D − c) from 0.26 (1 + ρ) = 0.423 m to
    # 0.42 (1 + ρ) = 0.683 m (ρ = γ / (1 − γ)), each at least 5 mm away from every training distance.
    distances = c + np.array([0.424, 0.445, 0.455, 0.488, 0.520, 0.552, 0.585, 0.617, 0.649, 0.682])
    assert np.abs(distances[:, None] - training_distances(primitives)[None]).min() > 5e-3
    for k, d in enumerate(distances):
        run = run_synthesis(primitives, WalkReachGoal(float(d), ("front_left", "back_right")[k % 2]))
        r = run.report
        assert r["actions"] == [1, 2, 3]
        np.testing.assert_allclose(r["planned_step_lengths_m"][:2], [(d - c) * (1 - GAMMA), (d - c) * GAMMA])
        assert np.abs(r["step_length_errors_mm"]).max() < 5.0
        assert abs(r["final_pelvis_to_goal_m"] - c) < 0.02
        assert np.all(np.isfinite(run.upper_body_q)) and np.all(np.isfinite(run.pelvis_velocity))
        # Continuous references: at 200 Hz no joint moves more than 0.02 rad (4 rad/s) between samples,
        # including the action transitions, where the weights and means switch.
        assert np.abs(np.diff(run.upper_body_q, axis=0)).max() < 0.02
        assert np.abs(np.diff(run.pelvis_velocity, axis=0)).max() < 0.02
        assert abs(run.pelvis_velocity[-1, 0]) < 0.01  # standing at the end


def test_transitions_have_no_jump_in_joint_angles(primitives):
    run = run_synthesis(primitives, WalkReachGoal(primitives.comfort_distance + 0.55, "back_left"))
    assert run.action[-1] == 0 and run.action[-2] == 3  # 0: ended, references held
    boundaries = np.flatnonzero(np.diff(run.action[:-1]))
    steps = np.abs(np.diff(run.upper_body_q, axis=0))  # per 5 ms tick
    assert len(boundaries) == 2
    for k in boundaries:  # at most 1 rad/s around a transition, where the blended actions meet
        assert steps[k - 2 : k + 3].max() <= 0.005


def test_goal_jump_adds_a_step_and_still_ends_at_comfort(primitives):
    c = primitives.comfort_distance
    goal = WalkReachGoal(c + 0.55, "front_right")
    planned = Synthesizer(primitives, goal).plan
    run = run_synthesis(primitives, goal, jump=GoalJump(time=1.0, distance=c + 0.95))
    r = run.report
    assert r["replans"] == 1
    assert len(r["actions"]) == len(planned) + 1 and r["actions"][-2:] == [2, 3]
    assert abs(r["final_pelvis_to_goal_m"] - c) < 0.02
    assert np.abs(np.diff(run.upper_body_q, axis=0)).max() < 0.02


def test_goal_jump_during_the_short_cycle_adds_a_short_cycle(primitives):
    c = primitives.comfort_distance
    run = run_synthesis(primitives, WalkReachGoal(c + 0.55, "back_left"), jump=GoalJump(time=2.4, distance=c + 0.85))
    assert run.report["actions"] == [1, 2, 2, 3]
    assert abs(run.report["final_pelvis_to_goal_m"] - c) < 0.02


def test_the_preview_is_what_the_synthesis_then_does_across_actions_and_a_goal_jump(primitives):
    """Every 0.1 s a 1.6 s preview (kept between calls, extended at its tail) predicts the references
    the synthesis then steps to, through every action's end and a goal jump that replans."""
    c, dt = primitives.comfort_distance, 0.005
    synth = Synthesizer(primitives, WalkReachGoal(c + 0.55, "front_right"))
    predicted, errors, ended = {}, [], set()
    for tick in range(1, 2000):
        index = synth.action_index
        if tick == 200:  # the goal jumps: what was previewed for the old goal no longer holds
            predicted.clear()
        velocity, q, _, _ = synth.step(dt, WalkReachGoal(c + 0.95, "front_right") if tick >= 200 else None)
        if synth.finished:
            break
        ended |= {index} if synth.action_index != index else set()
        if tick in predicted:
            errors.append((np.abs(predicted[tick][0] - velocity).max(), np.abs(predicted[tick][1] - q).max()))
        if tick % 20 == 0:
            p = synth.preview(1.6, 0.02)
            assert 0 < p.t[0] <= 0.02 + 1e-9 and np.allclose(np.diff(p.t), 0.02)
            predicted.update({tick + round(t / dt): (v, u) for t, v, u in zip(p.t, p.pelvis_velocity, p.upper_body_q)})
    assert synth.replans == 1 and len(ended) >= 3 and len(errors) > 300  # every 4th tick
    worst = np.max(errors, axis=0)
    # [m/s, rad]: the rollout's integration error at 0.02 s steps against the synthesis's 5 ms steps,
    # largest across transitions (a rollout rolled anew at every call gives 2.0e-4 and 7.4e-4)
    assert worst[0] < 5e-4 and worst[1] < 1.5e-3, worst


def test_synthesizer_rejects_bad_input(primitives):
    with pytest.raises(ValueError, match="too close"):
        Synthesizer(primitives, WalkReachGoal(0.3))
    with pytest.raises(ValueError, match="slot = 'middle'"):
        Synthesizer(primitives, WalkReachGoal(1.5, "middle"))
    synth = Synthesizer(primitives, WalkReachGoal(1.5))
    with pytest.raises(ValueError, match="dt = nan"):
        synth.step(float("nan"))
    velocity, q, phi, action = synth.step(0.005, WalkReachGoal(1.5))
    assert velocity.shape == (3,) and q.shape == (18,) and 0 < phi < 0.1 and action == 1


def test_phase_helper_wraps_into_one_period():
    assert phase(np.array([1.0, -1e-9])) > 6.28 and phase(np.array([-1.0, 0.0])) == pytest.approx(np.pi)


def test_learned_primitives_are_cached_and_learned_anew_when_the_demonstrations_change(talos, tmp_path,
                                                                                      monkeypatch):
    import dataclasses

    from robot_ctrl.synthesis.learned import load_demonstrations, load_primitives
    from robot_ctrl.synthesis.primitives import WalkReachPrimitives

    monkeypatch.setenv("ROBOT_CTRL_CACHE", str(tmp_path / "cache"))
    learned = []
    learn = WalkReachPrimitives.learn.__func__

    def counting(cls, demos, robot, *args, **kwargs):
        learned.append(demos.comfort_distance)
        return learn(cls, demos, robot, *args, **kwargs)

    monkeypatch.setattr(WalkReachPrimitives, "learn", classmethod(counting))
    first = load_primitives(talos)
    second = load_primitives(talos)  # from the cache: not learned again, and the same model
    assert len(learned) == 1
    for action, length in ((1, 0.35), (2, 0.2), (3, 0.2)):
        a, b = first.action(action, length, "back_left"), second.action(action, length, "back_left")
        assert a.duration == b.duration and all(np.array_equal(getattr(a, f), getattr(b, f))
                                                for f in ("means", "w0", "weights"))
    assert np.array_equal(first.rotations, second.rotations) and first.quality == second.quality
    assert len(list((tmp_path / "cache").glob("talos-primitives-*.pickle"))) == 1
    demos = load_demonstrations(talos)
    changed = tmp_path / "changed_demos.npz"
    dataclasses.replace(demos, comfort_distance=demos.comfort_distance + 0.01).save(changed)
    third = load_primitives(talos, changed)
    assert learned == [demos.comfort_distance, demos.comfort_distance + 0.01]
    assert third.comfort_distance == first.comfort_distance + 0.01


def test_touchdowns_are_contacts_after_a_swing():
    """A touch-down is a foot's force rising through a tenth of the weight after 0.1 s without
    contact: a heel bouncing on landing is one touch-down, a foot that was down from the start none."""
    t = np.arange(0.0, 2.0, 0.005)
    left = np.where((t < 0.5) | (t >= 0.9), 400.0, 0.0)  # swing 0.5-0.9 s, lands at 0.9 s
    left[(t >= 0.92) & (t < 0.93)] = 0.0  # bounces once, 20 ms after landing
    right = np.where(t < 1.2, 400.0, np.where(t >= 1.6, 300.0, 50.0))  # swing 1.2-1.6 s (50 N: below contact)
    np.testing.assert_allclose(touchdowns(t, np.stack([left, right], axis=1), 1000.0), [0.9, 1.6])


def test_a_run_without_a_finished_sequence_is_not_a_demonstration():
    talos_upper = np.arange(3)
    series = {"action_starts": np.array([[2.7, 1], [4.7, 2], [7.5, 3]])}  # no end: the run stopped while standing
    with pytest.raises(ValueError, match="do not end with a normal cycle, a short cycle and standing"):
        demonstration_from_run(series | {"drawer_t": np.zeros(1), "drawer_grf": np.zeros((1, 2))}, "front_left",
                               talos_upper, 1000.0)


def test_source_counts_compare_and_the_step_before_shapes_the_final_posture(capsys):
    """synth-quality compares source counts (thesis Fig. 3.14/3.41): more sources, a better gait
    cycle; synth-transition (Fig. 3.38): two short cycles of different lengths before standing give
    different postures at the switch."""
    from robot_ctrl.cli import main

    assert main(["synth-quality", "--sources", "3+2,5+4"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines() if line.split()[:1] in (["3+2"], ["5+4"])]
    q = {(r[0], int(r[1])): float(r[3]) for r in rows}
    assert len(rows) == 6 and q[("5+4", 1)] > q[("3+2", 1)] > 0.99
    assert main(["synth-transition", "--distances", "1.15,1.35"]) == 0
    out = capsys.readouterr().out
    assert "short cycles 0.175 and 0.252 m before standing" in out
    hand_mm = float(out.split("the left hand by ")[1].split(" mm")[0])
    assert 5.0 < hand_mm < 50.0  # the postures differ, by a reach's fraction
    assert main(["synth-quality", "--sources", "3+2,0+9"]) == 2


def test_a_query_beyond_the_demonstrations_is_held_inside_them(talos):
    """The feasible set's front_left stand model is fitted on three short-cycle lengths at three
    speeds: extrapolated a few millimetres below them, its local linear fit predicted a negative
    duration and the synthesis never ended. Held inside what was demonstrated, every goal plans."""
    from robot_ctrl.synthesis.demonstrations import feasible_dataset_path

    feasible = load_primitives(talos, feasible_dataset_path("talos"))
    demos = DemonstrationSet.load(feasible_dataset_path("talos"))
    stands = [t.durations[2] for t in demos.trials if t.slot == "front_left"]
    for distance in (1.10, 1.15, 1.25):
        plan = Synthesizer(feasible, WalkReachGoal(distance, "front_left")).plan
        assert min(stands) - 1e-9 <= plan[-1].duration <= max(stands) + 1e-9


def test_the_commanders_posture_ahead_interpolates_the_rollout_as_np_interp():
    """The posture the IK and the dynamic filter follow ahead of now, interpolated from the preview
    for all joints at once, equals np.interp joint by joint: between samples, at them, outside."""
    from robot_ctrl.control.commanders.walk_reach_commander import interpolated_row

    rng = np.random.default_rng(0)
    times = np.cumsum(rng.uniform(0.001, 0.02, 80))
    values = rng.normal(size=(80, 14))
    values[:, 3] = 0.25  # a joint that holds still
    for t in [*rng.uniform(times[0] - 0.1, times[-1] + 0.1, 2000), *times, times[0] - 1.0, times[-1] + 1.0]:
        expected = [np.interp(t, times, values[:, j]) for j in range(values.shape[1])]
        np.testing.assert_array_equal(interpolated_row(t, times, values), expected)
