"""Walking pattern generator: MPC constraints, velocity tracking, footstep reachability, start/stop."""

import dataclasses

import numpy as np
import pytest

from robot_ctrl.geometry import PlanarMove, rotation
from robot_ctrl.wpg.footstep import Footstep
from robot_ctrl.wpg.generator import STOP_TOLERANCE, WalkingPatternGenerator
from robot_ctrl.wpg.lipm import com_at, horizon_matrices
from robot_ctrl.wpg.mpc import WalkingMPC
from robot_ctrl.wpg.params import WalkParams

PARAMS = WalkParams(com_height=0.88, step_width=0.17, foot_length=0.21, foot_width=0.13)


def standing_generator(params=PARAMS):
    return WalkingPatternGenerator(params, Footstep("left", 0.0, 0.085, 0.0), Footstep("right", 0.0, -0.085, 0.0),
                                   np.zeros(2))


def test_horizon_matrices_match_integration():
    m = horizon_matrices(0.1, 16, 0.88)
    rng = np.random.default_rng(0)
    state, jerks = rng.normal(size=3), rng.normal(size=16)
    s = state.copy()
    for j, u in enumerate(jerks):
        s = com_at(s, u, 0.1)
        assert m.Pps[j] @ state + m.Ppu[j] @ jerks == pytest.approx(s[0])
        assert m.Pvs[j] @ state + m.Pvu[j] @ jerks == pytest.approx(s[1])
        assert m.Pzs[j] @ state + m.Pzu[j] @ jerks == pytest.approx(s[0] - 0.88 / 9.81 * s[2])


def in_reach(params, previous: Footstep, step: Footstep, tol=1e-6) -> bool:
    local = rotation(previous.yaw).T @ (step.xy - previous.xy)
    w, (lo, hi) = params.step_width, params.reach_y
    y_lo, y_hi = (w + lo, w + hi) if step.side == "left" else (-w - hi, -w - lo)
    return (params.reach_x[0] - tol <= local[0] <= params.reach_x[1] + tol) and (y_lo - tol <= local[1] <= y_hi + tol)


def test_constraints_hold_over_random_references():
    """Random velocity references changing every 0.8 s, with a ZMP-centring weight low enough that
    the constraints bind: every predicted ZMP lies in its support polygon (with the margin), every
    footstep in the reach region of the previous foot."""
    rng = np.random.default_rng(3)
    gen = standing_generator(dataclasses.replace(PARAMS, w_zmp=0.01))
    for k in range(120):
        if k % 8 == 0:
            gen.set_velocity(rng.uniform(-0.1, 0.3), rng.uniform(-0.1, 0.1), rng.uniform(-0.3, 0.3))
        prob = gen.problem()
        gen.update()
        sol = gen.solution
        for j, sample in enumerate(gen.preview().samples[1:]):  # the polygons rebuilt from the planned feet
            assert zmp_in_support(sol.zmp[j], sample), (k, j, sol.zmp[j], sample)
        for reach in prob.reach:
            step = Footstep("left" if reach.box[2] > 0 else "right", *sol.footsteps[2 * reach.index: 2 * reach.index + 2],
                            0.0)
            local = rotation(reach.previous.yaw).T @ (step.xy - reach.previous.position(sol.footsteps))
            assert reach.box[0] - 1e-6 <= local[0] <= reach.box[1] + 1e-6
            assert reach.box[2] - 1e-6 <= local[1] <= reach.box[3] + 1e-6
    landed = gen.touchdowns
    assert len(landed) >= 10
    feet = {"left": Footstep("left", 0.0, 0.085, 0.0), "right": Footstep("right", 0.0, -0.085, 0.0)}
    for td in landed:  # each landing is reachable from the foot that stood while it swung
        previous = feet["right" if td.planned.side == "left" else "left"]
        assert in_reach(PARAMS, previous, td.planned)
        assert abs(np.arctan2(np.sin(td.planned.yaw - previous.yaw), np.cos(td.planned.yaw - previous.yaw))) \
            <= PARAMS.max_yaw_step + 1e-9
        feet[td.planned.side] = td.planned


def zmp_in_support(zmp, sample, params=PARAMS):
    """Whether ``zmp`` lies in the soles on the floor at a preview sample (with the ZMP margin): in
    single support the sole of the foot down (either one at a lift-off or touch-down instant), in
    double support the convex hull of both soles. Built here from the feet, not by the generator."""
    from scipy.spatial import ConvexHull

    half = np.array([params.foot_length, params.foot_width]) / 2 - params.zmp_margin
    feet = list(sample.feet.values())
    if sample.single_support:
        down = [f for f in feet if f.position[2] < 1e-9]
        return any(np.all(np.abs(rotation(f.yaw).T @ (zmp - f.position[:2])) <= half + 1e-6) for f in down)
    corners = [f.position[:2] + rotation(f.yaw) @ (half * [sx, sy]) for f in feet for sx in (-1, 1) for sy in (-1, 1)]
    hull = ConvexHull(np.array(corners))
    return bool(np.all(hull.equations[:, :2] @ zmp + hull.equations[:, 2] <= 1e-6))


@pytest.mark.parametrize("velocity", [(0.25, 0.0, 0.0), (0.0, 0.05, 0.0), (0.1, -0.04, 0.0), (0.2, 0.0, 0.2)])
def test_com_velocity_tracks_the_reference_in_steady_state(velocity):
    """Mean CoM velocity over whole gait cycles matches the reference (heading frame) to 0.02 m/s.
    (Sideways speed is bounded by the reach region: at most 0.15 m per 1.6 s cycle.)"""
    gen = standing_generator()
    gen.set_velocity(*velocity)
    samples = []
    for k in range(120):
        gen.update()
        if k >= 40:  # after start-up
            local = rotation(gen.heading).T @ np.array([gen.com_x[1], gen.com_y[1]])
            samples.append(local)
    mean = np.mean(samples[: len(samples) // 16 * 16], axis=0)  # whole 1.6 s cycles
    np.testing.assert_allclose(mean, velocity[:2], atol=0.02)
    if velocity[2]:
        assert gen.heading == pytest.approx(velocity[2] * 120 * PARAMS.sample_time, rel=0.01)


def test_starts_from_standing_and_stops_into_double_support():
    gen = standing_generator()
    for _ in range(5):
        gen.update()
    assert gen.standing and not gen.touchdowns
    gen.set_velocity(0.2, 0.0, 0.0)
    for _ in range(40):
        gen.update()
    assert gen.phase in ("single", "double") and gen.touchdowns
    gen.set_velocity(0.0, 0.0, 0.0)
    for _ in range(40):
        gen.update()
    assert gen.standing
    left, right = gen.feet["left"], gen.feet["right"]
    assert abs(left.x - right.x) < 1e-9 and np.linalg.norm(left.xy - right.xy) == pytest.approx(0.17)  # side by side
    com = np.array([gen.com_x[0], gen.com_y[0]])
    np.testing.assert_allclose(com, (left.xy + right.xy) / 2, atol=0.01)  # CoM settles between the feet
    assert abs(gen.com_x[1]) < 0.01 and abs(gen.com_y[1]) < 0.01


def test_stop_at_puts_the_feet_on_the_goal():
    gen = standing_generator()
    gen.set_velocity(0.0, 0.15, 0.0)
    for _ in range(30):
        gen.update()
    goal = {"left": Footstep("left", 0.0, 0.485, 0.0), "right": Footstep("right", 0.0, 0.315, 0.0)}
    gen.stop_at(goal["left"], goal["right"])
    for _ in range(60):
        gen.update()
    assert gen.standing
    for side in ("left", "right"):
        np.testing.assert_allclose(gen.feet[side].xy, goal[side].xy, atol=1e-9)


def test_a_walk_from_standing_at_turned_footsteps_goes_the_way_the_feet_stand():
    """A stop at footsteps turned from the walk's heading leaves the robot facing their way: the next
    walk goes straight ahead of the feet, not along the heading it walked before."""
    gen = standing_generator()
    gen.set_velocity(0.15, 0.0, 0.0)
    for _ in range(30):
        gen.update()
    turn = 0.4  # [rad] the stop footsteps' yaw, the walk's heading 0
    ahead = rotation(turn)
    goal = [Footstep(side, *(np.array([0.6, 0.0]) + ahead @ [0.0, y]), turn) for side, y in (("left", 0.085),
                                                                                           ("right", -0.085))]
    gen.stop_at(*goal)
    for _ in range(80):
        gen.update()
    assert gen.standing and gen.feet["left"].yaw == pytest.approx(turn)
    before = [gen.feet[s].xy.copy() for s in ("left", "right")]
    gen.set_velocity(0.2, 0.0, 0.0)
    for _ in range(60):
        gen.update()
    walked = np.mean([gen.feet[s].xy for s in ("left", "right")], axis=0) - np.mean(before, axis=0)
    assert np.linalg.norm(walked) > 0.3
    assert abs(np.arctan2(walked[1], walked[0]) - turn) < 0.02 and gen.heading == pytest.approx(turn, abs=1e-9)


def test_stop_at_stands_although_every_landed_sole_turns_a_little():
    """A real sole lands a few milliradians off its footstep's yaw and the plan follows it
    (``shift``): the stop must still end on the goal footsteps within the stop tolerances instead of
    stepping in place to take out what the next landing brings back."""
    gen = standing_generator()
    gen.set_velocity(0.2, 0.0, 0.0)
    for _ in range(30):
        gen.update()
    ahead = gen.feet[gen.stance].x + 0.3
    goal = {"left": Footstep("left", ahead, 0.085, 0.0), "right": Footstep("right", ahead, -0.085, 0.0)}
    gen.stop_at(goal["left"], goal["right"])
    landed = len(gen.touchdowns)
    for _ in range(100):
        before = len(gen.touchdowns)
        gen.update()
        if len(gen.touchdowns) > before:  # the sole turned on landing by 9 mrad, alternately
            foot = gen.touchdowns[-1].planned
            gen.shift(PlanarMove(np.zeros(2), 0.009 * (-1) ** len(gen.touchdowns), foot.xy))
    assert gen.standing
    assert len(gen.touchdowns) - landed <= 4
    for side in ("left", "right"):
        np.testing.assert_allclose(gen.feet[side].xy, goal[side].xy, atol=STOP_TOLERANCE)


def test_a_pushed_plan_moves_a_frozen_landing():
    """``add_com_velocity`` inside the swing's last ``swing_freeze`` seconds: the plan's CoM
    velocity takes the change and the MPC moves the landing the MPC alone no longer moves."""
    plans = [standing_generator(), standing_generator()]
    for gen in plans:
        gen.set_velocity(0.2, 0.0, 0.0)
        for _ in range(13):  # the transfer, then 0.5 s into the first single support (the left foot swings)
            gen.update()
    pushed, plain = plans
    assert plain.phase == "single" and plain.phase_time == pytest.approx(PARAMS.single_support - PARAMS.swing_freeze)
    before = plain.swing.landing
    pushed.add_com_velocity(np.array([0.0, 0.3]))  # to the left
    for gen in plans:
        gen.update()
    assert plain.swing.landing == before  # frozen
    assert pushed.sample(0.0).com_velocity == pytest.approx(plain.sample(0.0).com_velocity + [0.0, 0.3])
    assert pushed.swing.landing.y > before.y + 0.03 and pushed.swing.landing.x == pytest.approx(before.x, abs=0.02)


def test_the_plans_dcm_diverges_from_its_zmp():
    """The plan's DCM ξ obeys the LIP's ξ̇ = ω (ξ − z) with its cart-table ZMP z: integrated over
    each sample of a walk, within 0.1 mm (an ω 5 % off breaks it)."""
    gen = standing_generator()
    gen.set_velocity(0.3, 0.05, 0.2)
    steps = 200
    for _ in range(20):
        start = gen.dcm()
        gen.update()
        T = gen.sample_duration
        omega, xi = np.sqrt(9.81 / PARAMS.com_height), start.copy()
        for k in range(steps):  # midpoint rule on ξ̇ = ω (ξ − z)
            ref = gen.sample((k + 0.5) * T / steps)
            xi_mid = xi + 0.5 * T / steps * omega * (xi - ref.zmp)
            xi = xi + T / steps * omega * (xi_mid - ref.zmp)
        assert gen.dcm() == pytest.approx(xi, abs=1e-4)


def test_a_planar_move_turns_about_its_pivot_then_translates():
    move = PlanarMove(np.array([0.0, 1.0]), np.pi / 2, np.array([1.0, 0.0]))
    np.testing.assert_allclose(move.point([2.0, 0.0]), [1.0, 2.0], atol=1e-12)
    np.testing.assert_allclose(move.point([[1.0, 0.0], [1.0, -1.0]]), [[1.0, 1.0], [2.0, 1.0]], atol=1e-12)
    np.testing.assert_allclose(move.direction([1.0, 0.0]), [0.0, 1.0], atol=1e-12)
    step = Footstep("left", 2.0, 0.0, 0.1).moved(move)
    assert (step.x, step.y, step.yaw) == pytest.approx((1.0, 2.0, 0.1 + np.pi / 2))


@pytest.mark.parametrize("turn", [0.0, 0.05])
def test_a_shifted_plan_is_the_same_plan_moved(turn):
    """``shift`` mid-swing turns and moves the CoM, the feet, the swing under way and the heading,
    and the MPC then plans the same motion from there (its problem is invariant under rigid moves of
    the plane)."""
    plans = [standing_generator(), standing_generator()]
    for gen in plans:
        gen.set_velocity(0.2, 0.0, 0.1)
        for _ in range(13):  # into a single support
            gen.update()
    moved, kept = plans
    assert moved.phase == "single"
    delta, pivot = np.array([0.004, -0.003]), moved.feet[moved.stance].xy
    R = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    moved.shift(PlanarMove(delta, turn, pivot))
    assert moved.heading == pytest.approx(kept.heading + turn)
    for _ in range(7):  # across a landing
        for gen in plans:
            gen.update()
        for tau in (0.0, 0.05):
            a, b = kept.sample(tau), moved.sample(tau)
            np.testing.assert_allclose(b.com, pivot + R @ (a.com - pivot) + delta, atol=1e-7)
            np.testing.assert_allclose(b.com_velocity, R @ a.com_velocity, atol=1e-7)
            np.testing.assert_allclose(b.zmp, pivot + R @ (a.zmp - pivot) + delta, atol=1e-7)
            for side in ("left", "right"):
                np.testing.assert_allclose(b.feet[side].position[:2],
                                           pivot + R @ (a.feet[side].position[:2] - pivot) + delta, atol=1e-7)
                np.testing.assert_allclose(b.feet[side].position[2], a.feet[side].position[2], atol=1e-12)
                assert b.feet[side].yaw == pytest.approx(a.feet[side].yaw + turn, abs=1e-9)


@pytest.mark.parametrize("field,value", [("horizon", 1), ("single_support", 0.75), ("zmp_margin", 0.1),
                                         ("com_height", float("nan"))])
def test_bad_parameters_name_the_field(field, value):
    with pytest.raises(ValueError, match=f"WalkParams.{field}"):
        dataclasses.replace(PARAMS, **{field: value})


def test_velocity_reference_must_be_finite():
    with pytest.raises(ValueError, match="finite"):
        standing_generator().set_velocity(np.nan, 0.0, 0.0)


@pytest.mark.parametrize("scale", [0.8, 1.25])
def test_time_scale_stretches_the_step_period_and_keeps_the_speed(scale):
    gen = standing_generator()
    gen.set_time_scale(scale)
    gen.set_velocity(0.2, 0.0, 0.0)
    phases, com = [], []
    while gen.t < 12.0:
        gen.update()
        com.append((gen.t, gen.com_x[0]))
        for tau in np.linspace(0.0, gen.sample_duration, 4, endpoint=False):
            phases.append(gen.gait_phase(tau))
    landings = np.array([td.t for td in gen.touchdowns])
    np.testing.assert_allclose(np.diff(landings), scale * PARAMS.step_period, atol=1e-9)
    (t0, x0), (t1, x1) = com[-40], com[-1]
    assert (x1 - x0) / (t1 - t0) == pytest.approx(0.2, abs=0.01)  # the mean speed still follows the reference
    steps = np.diff([f.x for f in (td.planned for td in gen.touchdowns[-4:])])
    np.testing.assert_allclose(steps, 0.2 * scale * PARAMS.step_period, atol=0.02)  # longer steps when slower
    known = np.array([p for p in phases if p is not None])
    assert np.all(np.diff(known) > 0) and np.diff(known).max() < 0.2  # continuous, increasing
    assert known[-1] == pytest.approx(np.pi * len(landings) + np.pi * 0.5, abs=np.pi)  # π per step


def test_time_scale_range_is_checked():
    with pytest.raises(ValueError, match=r"time_scale = 3.0 is outside the allowed range \[0.5, 2.0\]"):
        standing_generator().set_time_scale(3.0)


def test_daqp_called_directly_solves_the_qp_casadi_solves():
    """The MPC hands daqp its arrays itself (only the rows in use, equality rows for fixed footsteps);
    over a walk, a turn and a stop onto fixed footsteps, every sample's solution is the one of the same
    solver behind CasADi's interface."""
    problems = []
    gen = standing_generator()
    solve = gen.mpc.solve
    gen.mpc.solve = lambda prob: problems.append(prob) or solve(prob)
    gen.set_velocity(0.25, 0.05, 0.2)
    for _ in range(25):
        gen.update()
    gen.stop_at(Footstep("left", 0.6, 0.3, 0.3), Footstep("right", 0.65, 0.13, 0.3))
    for _ in range(25):
        gen.update()
    assert any(p.fixed for p in problems)
    through_casadi = WalkingMPC(dataclasses.replace(PARAMS, solver="casadi-daqp"))
    for prob in problems:
        direct, reference = solve(prob), through_casadi.solve(prob)
        np.testing.assert_allclose(direct.footsteps, reference.footsteps, atol=1e-6)
        np.testing.assert_allclose(direct.zmp, reference.zmp, atol=1e-6)
        np.testing.assert_allclose(direct.com, reference.com, atol=1e-6)


def test_a_landing_beyond_the_plan_repeats_the_last_step_mirrored():
    """A swing whose landing the plan does not hold yet lands as the last step went: the lift foot
    mirrored through the stance foot's heading line and carried the step's length ahead, so it stays
    on its own side of the stance foot (the dynamic filter previews the legs with it)."""
    from robot_ctrl.wpg.footstep import FootRef
    from robot_ctrl.wpg.segments import Segment, swing_point

    yaw = 0.3
    R = rotation(yaw)
    stance = FootRef("right", yaw, R @ [0.0, -0.1], np.zeros((2, 4)))
    lift = FootRef("left", yaw, R @ [-0.2, 0.1], np.zeros((2, 4)))
    segments = [Segment(0.1, [lift, stance], lift), Segment(0.7, [stance], stance)]
    fallback = Footstep("left", *(R @ [-0.2, 0.1]), yaw)
    start = swing_point(segments, 1, "left", np.zeros(4), 0.0, 0.05, fallback)
    end = swing_point(segments, 1, "left", np.zeros(4), 1.0, 0.05, fallback)
    np.testing.assert_allclose(start[0][:2], R @ [-0.2, 0.1], atol=1e-12)
    np.testing.assert_allclose(end[0][:2], R @ [0.2, 0.1], atol=1e-12)  # ahead, still on the left
    assert end[1] == pytest.approx(yaw) and end[0][2] == pytest.approx(0.0)
