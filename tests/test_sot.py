"""Stack-of-tasks IK: strict priorities, joint limits at every level, typed infeasibility."""

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from robot_ctrl.sot import (
    ComTask,
    FrameTask,
    HierarchicalQP,
    InfeasibleError,
    JointLimits,
    PostureTask,
    WholeBodyIK,
    kkt_fast_path,
)
from robot_ctrl.sot.servo_bounds import servo_velocity_bounds
from robot_ctrl.sot.whole_body_ik import upper_body_dofs

DT = 0.005


@pytest.fixture
def tasks(talos):
    ids = talos.frame_ids
    feet = [FrameTask(f"{s}_foot", ids[f"{s}_foot"]) for s in ("left", "right")]
    com = ComTask()
    hand = FrameTask("right_hand", ids["right_hand"], axes=("x", "y", "z"))
    posture = PostureTask("posture", talos.q_index, talos.v_index, talos.pin.nv, weight=0.1)
    return feet, com, hand, posture


def perturbed_half_sitting(talos, rng):
    q = talos.q_half_sitting.copy()
    q[talos.q_index] = np.clip(q[talos.q_index] + rng.uniform(-0.2, 0.2, talos.nj),
                               talos.lower + 0.03, talos.upper - 0.03)
    return q


def set_conflicting_targets(talos, q, feet, com, hand, rng):
    """Targets that the robot cannot meet all at once: feet moved apart, CoM and hand far away."""
    data = talos.pin.createData()
    pin.framesForwardKinematics(talos.pin, data, q)
    for f in feet:
        pose = data.oMf[f.frame_id].copy()
        pose.translation += rng.uniform(-0.02, 0.02, 3)
        f.set_target(pose)
    com.set_target(pin.centerOfMass(talos.pin, data, q) + rng.uniform(-0.05, 0.05, 3))
    hand.set_target(pin.SE3(np.eye(3), data.oMf[hand.frame_id].translation + rng.uniform(-0.5, 0.5, 3)))


def held_feet_and_moved_com(talos, data, q, feet, com, shift):
    """Targets every higher level can meet: the feet where they are at ``q``, the CoM moved by ``shift``
    [m] (world frame). Leaves ``data``'s frames at ``q``."""
    pin.framesForwardKinematics(talos.pin, data, q)
    for f in feet:
        f.set_target(data.oMf[f.frame_id].copy())
    com.set_target(pin.centerOfMass(talos.pin, data, q) + shift)


def test_lower_levels_never_change_higher_levels(talos, tasks):
    feet, com, hand, posture = tasks
    limits = JointLimits.from_robot(talos)
    data = talos.pin.createData()
    rng = np.random.default_rng(1)
    improved = 0
    for _ in range(10):
        q = perturbed_half_sitting(talos, rng)
        set_conflicting_targets(talos, q, feet, com, hand, rng)
        posture.set_target(talos.q_half_sitting[talos.q_index] + rng.uniform(-0.5, 0.5, talos.nj))
        stacks = [[feet], [feet, [com]], [feet, [com], [hand]], [feet, [com], [hand], [posture]]]
        solutions = [HierarchicalQP(levels, limits).solve(talos.pin, data, q, DT) for levels in stacks]
        for k, level in enumerate(stacks[-1][:-1]):
            A = np.vstack([t.rows(talos.pin, data, q)[0] for t in level])
            reference = A @ solutions[k + 1]  # the first stack in which level k is above the last
            scale = max(1.0, np.abs(reference).max())
            for v in solutions[k + 2:]:
                np.testing.assert_allclose(A @ v, reference, atol=1e-6 * scale)
            # As the last level it is regularized (μ = 1e-5): the same up to O(μ).
            np.testing.assert_allclose(A @ solutions[k], reference, atol=1e-3 * scale)
        A_hand, b_hand = hand.rows(talos.pin, data, q)
        improved += np.linalg.norm(A_hand @ solutions[2] - b_hand) < np.linalg.norm(A_hand @ solutions[1] - b_hand) - 1e-6
    # The lowest level still does work in the freedom left to it (unless limits use all of it up).
    assert improved >= 7


def test_joint_limits_hold_at_every_step(talos):
    """Drive the right hand far out of reach for 2 s: every joint hits a limit, none crosses it."""
    q0 = talos.q_half_sitting.copy()
    ik = WholeBodyIK(talos, q0)
    hand = ik.hands["right"]
    hand.active = True
    hand.set_target(pin.SE3(np.eye(3), np.array([1.5, -1.5, 2.5])))
    ik.com.set_target(ik.com_position() + [0.0, 0.0, 0.3])  # unreachable: forces leg limits
    limits = ik.solver.limits
    v_max = limits.v_max
    at_limit = np.zeros(talos.nj, bool)
    for _ in range(400):
        q_before = ik.q.copy()
        qj_before = q_before[talos.q_index]
        v = ik.step(DT)
        qj = ik.q[talos.q_index]
        # Soft limits hold, except that a joint already inside the margin (the grippers start on their
        # URDF limit) may stay there without going deeper; the hard URDF limits always hold.
        assert np.all(qj >= np.minimum(limits.q_min, qj_before) - 1e-9)
        assert np.all(qj <= np.maximum(limits.q_max, qj_before) + 1e-9)
        assert np.all(qj >= limits.hard_min) and np.all(qj <= limits.hard_max)
        assert np.all(np.abs(v[talos.v_index]) <= v_max + 1e-9)
        assert np.all(np.isfinite(ik.q))
        at_limit |= (qj <= limits.q_min + 1e-6) | (qj >= limits.q_max - 1e-6)
        assert np.allclose(ik.q[talos.q_index], q_before[talos.q_index] + v[talos.v_index] * DT)
    assert at_limit.sum() >= 3  # the test really pushed joints onto their limits


def test_infeasible_problem_raises_a_typed_error(talos, tasks):
    feet, com, hand, posture = tasks
    solver = HierarchicalQP([feet, [com]], JointLimits.from_robot(talos))
    q = talos.q_half_sitting.copy()
    q[talos.q_index[3]] = -0.3  # left knee beyond its hard limit [0, 2.618]
    with pytest.raises(InfeasibleError, match=r"leg_left_4_joint = -0.3000 not in \[0.0000, 2.6180\]") as info:
        solver.solve(talos.pin, talos.pin.createData(), q, DT)
    assert info.value.level == 0
    q[talos.q_index[3]] = np.nan
    with pytest.raises(InfeasibleError, match="NaN"):
        solver.solve(talos.pin, talos.pin.createData(), q, DT)


def test_the_feet_hold_exactly_when_the_com_target_is_out_of_reach(talos):
    """Feet above balance, strictly: with a CoM target a metre ahead (beyond any posture over these
    feet, and beyond the joints' velocity limits at the task's gain), every solve still gives the
    soles exactly the velocity their task asks for, while the CoM moves as far as the legs allow."""
    ik = WholeBodyIK(talos, talos.q_half_sitting)
    data = talos.pin.createData()
    com0 = ik.com_position()
    ik.com.set_target(com0 + [1.0, 0.0, 0.0])
    for k in range(60):
        q = ik.q.copy()
        v = ik.step(DT)
        pin.computeJointJacobians(talos.pin, data, q)
        pin.updateFramePlacements(talos.pin, data)
        for s in ("left", "right"):
            A, b = ik.feet[s].rows(talos.pin, data, q)
            np.testing.assert_allclose(A @ v, b, atol=1e-6 * max(1.0, np.abs(b).max()))
        A_com, b_com = ik.com.rows(talos.pin, data, q)
        assert np.linalg.norm(A_com @ v - b_com) > 1.0  # the balance level could not be met
    assert ik.com_position()[0] - com0[0] > 0.05  # ... and did act, as far as the feet let it


def test_whole_body_ik_reaches_the_demo_hand_target(talos):
    """Kinematically, the balance demo's reach is feasible with feet fixed and the CoM held."""
    ik = WholeBodyIK(talos, talos.q_half_sitting, acceleration_limits=False)
    feet0 = {s: ik.pose(f"{s}_foot") for s in ("left", "right")}
    com0 = ik.com_position()
    # 0.4 m ahead, 0.2 m right, 0.8 m above the soles, from midway between the feet.
    target = (feet0["left"].translation + feet0["right"].translation) / 2 + [0.4, -0.2, 0.8]
    ik.hands["right"].active = True
    ik.hands["right"].set_target(pin.SE3(np.eye(3), target))
    for _ in range(600):
        ik.step(DT)
    assert np.linalg.norm(ik.pose("right_hand").translation - target) < 0.005
    assert np.linalg.norm(ik.com_position() - com0) < 1e-6
    for s in ("left", "right"):
        assert np.linalg.norm(pin.log6(feet0[s].actInv(ik.pose(f"{s}_foot"))).vector) < 1e-6


def test_fast_path_gives_the_level_by_level_solution(talos, tasks, monkeypatch):
    """Reachable feet and CoM targets: the one-KKT solve equals the level-by-level hierarchy."""
    feet, com, hand, posture = tasks
    data = talos.pin.createData()
    rng = np.random.default_rng(2)
    q = perturbed_half_sitting(talos, rng)
    held_feet_and_moved_com(talos, data, q, feet, com, [0.002, -0.001, 0.0])
    posture.set_target(q[talos.q_index] + rng.uniform(-0.01, 0.01, talos.nj))  # well inside the velocity limits
    solver = HierarchicalQP([feet, [com], [posture]], JointLimits.from_robot(talos))
    taken = []
    accepts = kkt_fast_path.meets_higher_levels
    monkeypatch.setattr(kkt_fast_path, "meets_higher_levels", lambda *args: taken.append(accepts(*args)) or taken[-1])
    fast = solver.solve(talos.pin, data, q, DT)
    assert taken == [True]  # the fast path applied
    monkeypatch.setattr(solver, "_fast_path", lambda *args: None)
    by_level = solver.solve(talos.pin, data, q, DT)
    assert np.linalg.norm(fast) > 0.1  # the CoM and posture tasks really move the robot
    np.testing.assert_allclose(fast, by_level, atol=1e-8)


def test_a_higher_level_is_met_exactly_when_its_minimum_norm_step_breaks_a_bound(talos, tasks):
    """The torso joints nearly held (velocity bound 1e-4 rad/s): the CoM's minimum-norm step, which
    bends the torso too, breaks their bound, yet the legs alone can move the CoM. The balance level
    is met exactly, not as a regularized least-squares (which left it 1e-4 short)."""
    feet, com, _, posture = tasks
    data = talos.pin.createData()
    q = perturbed_half_sitting(talos, np.random.default_rng(4))
    held_feet_and_moved_com(talos, data, q, feet, com, [0.004, 0.002, 0.0])
    posture.set_target(q[talos.q_index])
    limits = JointLimits.from_robot(talos)
    torso = np.isin(talos.v_index, [talos.pin.joints[talos.pin.getJointId(n)].idx_v
                                    for n in ("torso_1_joint", "torso_2_joint")])
    limits = dataclasses.replace(limits, v_max=np.where(torso, 1e-4, limits.v_max))
    solver = HierarchicalQP([feet, [com], [posture]], limits)
    solver._fast_path = lambda *args, **kwargs: None  # the level-by-level solve itself
    v = solver.solve(talos.pin, data, q, DT)
    A, b = com.rows(talos.pin, data, q)
    assert np.linalg.norm(b) > 0.1  # the CoM really moves
    assert np.linalg.norm(A @ v - b) < 1e-8 * np.linalg.norm(b)
    assert np.all(np.abs(v[talos.v_index][torso]) <= 1e-4 + 1e-12)


def test_fast_path_with_bounds_held_active_gives_the_level_by_level_solution(talos, tasks, monkeypatch):
    """A posture target far beyond what the joints' velocity bounds allow in one step: the last
    level's solution lies on many bounds. From the second tick the fast path holds the bounds the
    last solution lay on as equalities (checked by its multipliers' signs) and gives the level-by-level
    solution, where it used to fall back to it."""
    feet, com, _, posture = tasks
    data = talos.pin.createData()
    rng = np.random.default_rng(5)
    q = perturbed_half_sitting(talos, rng)
    held_feet_and_moved_com(talos, data, q, feet, com, [0.002, -0.001, 0.0])
    posture.set_target(q[talos.q_index] + rng.choice([-1.0, 1.0], talos.nj))
    solver = HierarchicalQP([feet, [com], [posture]], JointLimits.from_robot(talos))
    first = solver.solve(talos.pin, data, q, DT)
    active, _ = solver._active
    assert active.size >= 10  # many joints on a bound
    level_by_level = []
    monkeypatch.setattr(solver, "_solve_level", lambda *args: level_by_level.append(1))
    fast = solver.solve(talos.pin, data, q, DT)
    assert not level_by_level  # the fast path gave it
    np.testing.assert_allclose(fast, first, atol=1e-8)

def test_the_feet_eliminated_kkt_solve_equals_the_full_one(talos, tasks):
    """The fast path's KKT system with the feet eliminated (the legs' velocities from the base's) has
    the full system's solution: the velocity and the bounds' multipliers, for the targets, for unit
    changes of feet and CoM rows, with bounds held on a leg, a torso and an arm joint."""
    feet, com, _, posture = tasks
    data = talos.pin.createData()
    rng = np.random.default_rng(6)
    q = perturbed_half_sitting(talos, rng)
    held_feet_and_moved_com(talos, data, q, feet, com, [0.003, 0.001, 0.0])
    posture.set_target(q[talos.q_index] + rng.uniform(-0.05, 0.05, talos.nj))
    pin.computeJointJacobians(talos.pin, data, q)
    pin.updateFramePlacements(talos.pin, data)
    rows = [t.rows(talos.pin, data, q) for t in (*feet, com)]
    E, f = np.vstack([A for A, _ in rows]), np.concatenate([b for _, b in rows])
    A, b = posture.rows(talos.pin, data, q)
    elimination = kkt_fast_path.first_level_elimination(E[:12], 6)
    legs = [talos.pin.joints[talos.pin.getJointId(f"leg_{s}_{i}_joint")].idx_v
            for s in ("left", "right") for i in range(1, 7)]
    np.testing.assert_array_equal(elimination[0], sorted(legs))
    np.testing.assert_array_equal(elimination[1], np.arange(6))
    dofs = np.array([legs[3], legs[8], 20, 30])
    beta, unit_rows = rng.uniform(-0.1, 0.1, dofs.size), np.array([0, 7, 12, 14])
    full = kkt_fast_path.kkt_solution(E, f, A, b, 1e-5, dofs, beta, unit_rows,
                                      *kkt_fast_path.no_elimination(talos.pin.nv))
    reduced = kkt_fast_path.kkt_solution(E, f, A, b, 1e-5, dofs, beta, unit_rows, *elimination)
    assert np.abs(full[:, 0]).max() > 0.1  # the targets move the robot
    np.testing.assert_allclose(reduced, full, rtol=0, atol=1e-10 * np.abs(full).max())


def test_the_kkt_solves_lu_equals_lapacks_and_refuses_a_singular_matrix():
    """kkt_fast_path.lu_solve, the KKT systems' elimination, against LAPACK (numpy) on a KKT matrix
    that needs row exchanges (its zero block), with several right-hand sides; a singular matrix or
    a NaN pivot raises LinAlgError as numpy's solve does."""
    rng = np.random.default_rng(3)
    J = rng.normal(size=(20, 14))
    constraints = rng.normal(size=(6, 14))
    M = np.block([[J.T @ J + 1e-5 * np.eye(14), constraints.T], [constraints, np.zeros((6, 6))]])
    B = rng.normal(size=(20, 4))
    X = kkt_fast_path.lu_solve(M, B)
    np.testing.assert_allclose(X, np.linalg.solve(M, B), rtol=0, atol=1e-12 * np.abs(X).max())
    np.testing.assert_allclose(M @ X, B, rtol=0, atol=1e-10)
    singular = M.copy()
    singular[-1] = singular[-2]
    with pytest.raises(np.linalg.LinAlgError):
        kkt_fast_path.lu_solve(singular, B)
    with pytest.raises(np.linalg.LinAlgError):
        kkt_fast_path.lu_solve(np.full((3, 3), np.nan), B[:3])


def test_prepared_solve_with_a_moved_target_equals_a_fresh_solve(talos, tasks):
    """prepare, move the CoM target, finish naming it: the solve that had the final target from the start
    (whether prepare was told the CoM would move or not, and for a task of the last level)."""
    feet, com, _, posture = tasks
    data = talos.pin.createData()
    q = perturbed_half_sitting(talos, np.random.default_rng(3))
    pin.framesForwardKinematics(talos.pin, data, q)
    for f in feet:
        f.set_target(data.oMf[f.frame_id].copy())
    com0 = pin.centerOfMass(talos.pin, data, q)
    posture.set_target(q[talos.q_index])
    solver = HierarchicalQP([feet, [com], [posture]], JointLimits.from_robot(talos))
    moved = []
    for retargetable in ((com,), ()):  # x₀ + Z δf, and a solve of the KKT system again
        com.set_target(com0)
        solver.prepare(talos.pin, data, q, DT, retargetable)
        com.set_target(com0 + [0.003, -0.002, 0.0])
        moved.append(solver.finish(retargeted=(com,)))
    fresh = solver.solve(talos.pin, talos.pin.createData(), q, DT)
    for prepared in moved:
        np.testing.assert_allclose(prepared, fresh, rtol=0, atol=1e-12)
    assert np.linalg.norm(fresh) > 0.1  # the moved target moves the robot
    with pytest.raises(RuntimeError, match="finish without prepare"):
        solver.finish()
    solver.prepare(talos.pin, data, q, DT)
    posture.set_target(q[talos.q_index] + 0.01)
    np.testing.assert_allclose(solver.finish(retargeted=(posture,)), solver.solve(talos.pin, data, q, DT),
                               rtol=0, atol=1e-12)
    solver.prepare(talos.pin, data, q, DT)
    with pytest.raises(ValueError, match="'right_hand' is not an active task of the prepared stack"):
        solver.finish(retargeted=(tasks[2],))


def test_the_ik_changes_an_upper_body_joints_velocity_no_faster_than_its_servo_can(talos):
    """A hand target 0.4 m away at once: without acceleration limits the arm's velocity jumps in
    one step (a torque the servo's damping asks for and cannot give); with them every upper-body
    joint's velocity changes by at most a_max dt per step (up to 15 % more on the last step into
    a soft position limit, where the position wins; the discrete braking bound keeps that small),
    the feet hold exactly, and the hand still gets there."""
    robot = dataclasses.replace(talos, config=dataclasses.replace(talos.config, acceleration_fraction=0.12))
    jumps = {}
    for limited in (False, True):
        ik = WholeBodyIK(robot, talos.q_half_sitting, acceleration_limits=limited)
        feet0 = {s: ik.pose(f"{s}_foot") for s in ("left", "right")}
        target = ik.pose("right_hand").translation + [0.3, 0.0, 0.25]
        ik.hands["right"].active = True
        ik.hands["right"].set_target(pin.SE3(np.eye(3), target))
        previous = np.zeros(talos.pin.nv)
        worst = np.zeros(talos.nj)
        for _ in range(800):
            v = ik.step(DT)
            worst = np.maximum(worst, np.abs(v - previous)[talos.v_index] / DT)
            previous = v
        jumps[limited] = worst
        assert np.linalg.norm(ik.pose("right_hand").translation - target) < 0.005
        for s in ("left", "right"):
            assert np.linalg.norm(pin.log6(feet0[s].actInv(ik.pose(f"{s}_foot"))).vector) < 1e-6
    limits = JointLimits.from_robot(robot, np.arange(talos.pin.nv))
    upper = np.isfinite(WholeBodyIK(robot, talos.q_half_sitting).solver.limits.a_max)
    assert upper.sum() == 20 and not upper[:12].any()  # torso, arms, grippers, head; not the legs
    assert (jumps[True][upper] <= 1.15 * limits.a_max[upper]).all()
    assert (jumps[False][upper] > 2 * limits.a_max[upper]).any()


def test_servo_velocity_bounds_hold_the_servos_torque_to_its_budget():
    """τ(v) = kp (q_ref + v dt − q) + kd (v − dq) + τ_ff is affine in v: the bounds are where it
    meets ∓budget; a joint whose reference ran far from it gets an interval that excludes 0."""
    rng = np.random.default_rng(3)
    n = 50
    q_ref, q, dq = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(-2, 2, n)
    kp, kd = rng.uniform(10, 2000, n), rng.uniform(0.5, 100, n)
    tau_ff, budget = rng.uniform(-5, 5, n), rng.uniform(6, 50, n)
    lo, hi = servo_velocity_bounds(q_ref, q, dq, tau_ff, kp, kd, budget, DT)

    def torque(v):
        return kp * (q_ref + v * DT - q) + kd * (v - dq) + tau_ff

    np.testing.assert_allclose(torque(lo), -budget, rtol=0, atol=1e-9)
    np.testing.assert_allclose(torque(hi), budget, rtol=0, atol=1e-9)
    assert (np.abs(torque(lo + (hi - lo) * rng.uniform(0, 1, n))) <= budget + 1e-9).all()
    assert ((lo > 0) | (hi < 0)).any()  # some references lag too far to hold still
    free = servo_velocity_bounds(q_ref, q, dq, tau_ff, 0 * kp, 0 * kd, budget, DT)
    assert np.isneginf(free[0]).all() and np.isposinf(free[1]).all()


def test_a_servo_bounded_ik_asks_its_arm_servos_for_no_more_than_their_effort(talos):
    """A hand target 0.3 m away at once, the arm's servos played by each joint's own inertia M_ii
    under the PD law, their torque saturated at the effort (a diagonal stand-in for the arm's
    dynamics, enough for the IK's side of the bargain). Without the bounds the first steps ask the
    shoulder and elbow servos for several times their effort (``kd Δv``); with them every
    upper-body servo's demanded torque stays within the budget at every step, the feet hold
    exactly and the hand still arrives."""
    robot = talos
    upper = np.isin(robot.v_index, upper_body_dofs(robot))
    budget = np.where(upper, 0.95 * robot.effort, np.inf)
    worst = {}
    for bounded in (False, True):
        ik = WholeBodyIK(robot, robot.q_half_sitting)
        feet0 = {s: ik.pose(f"{s}_foot") for s in ("left", "right")}
        target = ik.pose("right_hand").translation + [0.3, 0.0, 0.2]
        ik.hands["right"].active = True
        ik.hands["right"].set_target(pin.SE3(np.eye(3), target))
        q, dq = robot.joints_from_q(ik.q), np.zeros(robot.nj)
        ratio = np.zeros(robot.nj)
        for _ in range(600):
            q_ref = robot.joints_from_q(ik.q)
            ik.prepare(DT)
            within = (servo_velocity_bounds(q_ref, q, dq, np.zeros(robot.nj), robot.kp, robot.kd, budget, DT)
                      if bounded else None)
            v = ik.finish(tighter=within)[robot.v_index]
            tau = robot.kp * (robot.joints_from_q(ik.q) - q) + robot.kd * (v - dq)
            ratio = np.maximum(ratio, np.abs(tau) / robot.effort)
            dq = dq + np.clip(tau, -robot.effort, robot.effort) / robot.joint_inertia * DT
            q = q + dq * DT
        worst[bounded] = ratio
        assert np.linalg.norm(ik.pose("right_hand").translation - target) < 0.005
        for s in ("left", "right"):
            assert np.linalg.norm(pin.log6(feet0[s].actInv(ik.pose(f"{s}_foot"))).vector) < 1e-6
    assert worst[True][upper].max() <= 0.95 + 1e-9
    assert worst[False][upper].max() > 2.0


def test_a_braking_bound_slows_a_joint_before_its_soft_limit_without_bounding_its_acceleration(talos):
    """``braking_fraction`` alone: the approach to a soft limit is capped at b(d) (the velocity
    from which steps decelerating by a_brake stop within d), the acceleration is not."""
    robot = dataclasses.replace(talos, config=dataclasses.replace(talos.config, acceleration_fraction=None,
                                                                  braking_fraction=0.5))
    limits = JointLimits.from_robot(robot, upper_body_dofs(robot))
    assert limits.a_max is None and np.isfinite(limits.a_brake).sum() == 20
    j = robot.joint_names.index("arm_left_2_joint")
    q = robot.q_half_sitting.copy()
    a = limits.a_brake[j]
    for d in (0.001, 0.01, 0.05):
        q[robot.q_index[j]] = limits.q_max[j] - d
        lo, hi = limits.bounds(q, DT, previous=np.zeros(robot.nj))
        b = a * (np.sqrt(DT**2 / 4 + 2 * d / a) - DT / 2)
        assert hi[j] == pytest.approx(b, rel=1e-12) and b < d / DT
        assert (b - DT * a) ** 2 / (2 * a) <= d  # from b, braking at a after one step stops in time
    free = JointLimits.from_robot(dataclasses.replace(robot, config=dataclasses.replace(robot.config,
                                                                                        braking_fraction=None)))
    assert free.bounds(q, DT)[1][j] == min(0.05 / DT, free.v_max[j]) > hi[j]


def test_a_configs_ik_range_keeps_an_arm_off_the_torso():
    """G1's config narrows the shoulder roll the IK may use (``limits.ik_ranges``): a right hand sent
    low in front of the belly reaches it without rolling its shoulder in (positive on the right);
    with the URDF's range alone the IK rolls it in."""
    from robot_ctrl.robot import load_robot

    g1 = load_robot("g1")
    roll = g1.joint_names.index("right_shoulder_roll_joint")
    assert g1.config.ik_ranges["right_shoulder_roll_joint"] == (-2.2515, 0.0)
    rolls = {}
    for name, robot in (("config", g1), ("urdf", dataclasses.replace(
            g1, config=dataclasses.replace(g1.config, ik_ranges={})))):
        ik = WholeBodyIK(robot, robot.q_half_sitting, acceleration_limits=False)
        assert ik.solver.limits.q_max[roll] == (0.0 if name == "config" else pytest.approx(robot.upper[roll] - 0.02))
        target = ik.pose("waist").translation + [0.2, -0.05, 0.0]
        ik.hands["right"].active = True
        ik.hands["right"].set_target(pin.SE3(np.eye(3), target))
        for _ in range(400):
            ik.step(DT)
        rolls[name] = ik.q[robot.q_index][roll]
        assert np.linalg.norm(ik.pose("right_hand").translation - target) < 0.005
    assert rolls["config"] <= 1e-9 and rolls["urdf"] > 0.1, rolls


def test_the_compiled_task_rows_equal_pinocchios_jacobians_and_log3(talos):
    """The frame and CoM tasks build their rows from data.J and a log3 of their own: the Jacobians
    must equal Pinocchio's getFrameJacobian / jacobianCenterOfMass (of whichever data they are
    given), and the rotation error its log3, at generic angles, near 0 and near π."""
    model, data = talos.pin, talos.pin.createData()
    rng = np.random.default_rng(3)
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    q[3:7] /= np.linalg.norm(q[3:7])
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    hand = FrameTask("right_hand", talos.frame_ids["right_hand"], weight=2.0, gain=3.0)
    current = data.oMf[hand.frame_id]
    for angle in (1e-9, 1e-4, 0.7, 2.5, np.pi - 1e-3, np.pi - 1e-7):
        axis = rng.normal(size=3)
        rotation = pin.exp3(angle * axis / np.linalg.norm(axis)) @ current.rotation
        hand.set_target(pin.SE3(rotation, current.translation + [0.1, -0.2, 0.3]), velocity=rng.normal(size=6))
        A, b = hand.rows(model, data, q)
        e = np.concatenate([hand.target.translation - current.translation,
                            pin.log3(hand.target.rotation @ current.rotation.T)])
        np.testing.assert_array_equal(A, 2.0 * pin.getFrameJacobian(model, data, hand.frame_id, pin.LOCAL_WORLD_ALIGNED))
        np.testing.assert_allclose(b, 2.0 * (3.0 * e + hand.target_velocity), rtol=0, atol=1e-12 / (np.pi - angle))
    other = model.createData()  # a frame task keeps the Jacobians of the data it last read: another one's are its own
    q_other = pin.integrate(model, q, rng.uniform(-0.3, 0.3, model.nv))
    pin.computeJointJacobians(model, other, q_other)
    hand.target_velocity = [0.1, 0.0, 0.0, 0.0, 0.0, 0.0]  # a list: stored as the float array the rows need
    A_other, _ = hand.rows(model, other, q_other)
    np.testing.assert_array_equal(A_other, 2.0 * pin.getFrameJacobian(model, other, hand.frame_id,
                                                                      pin.LOCAL_WORLD_ALIGNED))
    assert not np.array_equal(A_other, hand.rows(model, data, q)[0])
    com = ComTask(axes=(0, 2), locked_dofs=[7, 30])
    with pytest.raises(AttributeError):  # its axes fix its number of rows, which the solver lays out once
        com.axes = np.array([0])
    com.set_target(np.array([0.1, 0.2, 0.3]))
    e, J = com.error_and_jacobian(model, data, q)
    expected = pin.jacobianCenterOfMass(model, data, False)[[0, 2]]  # from the same data.J, as the task's
    expected[:, [7, 30]] = 0.0
    np.testing.assert_array_equal(J, expected)
    np.testing.assert_array_equal(e, (com.target - data.com[0])[[0, 2]])
    np.testing.assert_allclose(data.com[0], pin.centerOfMass(model, data, q), rtol=0, atol=1e-15)


def test_a_joint_inside_its_soft_margin_may_stay_there():
    """Between its hard and soft limit a joint may stay or move out, never be pushed out: the
    bound on the side of the margin is 0, not the velocity that would leave it within one step."""
    dt, v_max = 0.005, 3.0
    limits = JointLimits(q_index=np.array([0, 1]), v_index=np.array([0, 1]), names=("low", "high"),
                         hard_min=np.array([-1.0, -1.0]), hard_max=np.array([1.0, 1.0]),
                         q_min=np.array([-0.9, -0.9]), q_max=np.array([0.9, 0.9]), v_max=np.full(2, v_max))
    lo, hi = limits.bounds(np.array([-0.95, 0.95]), dt)  # joint 0 in its lower margin, joint 1 in its upper
    assert lo[0] == 0.0 and hi[0] == v_max
    assert lo[1] == -v_max and hi[1] == 0.0
