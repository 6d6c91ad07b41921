"""Dynamic filter: multibody ZMP against hand-computed cases, and the filter's Newton passes on a
plan recorded from a MuJoCo walk."""

import os
import pickle
import signal
import threading
import time

import numpy as np
import pinocchio as pin
import pytest

from robot_ctrl.control.controllers.walking_controller import WalkingController
from robot_ctrl.dynfilter.dynamic_filter import DynamicFilter
from robot_ctrl.dynfilter.filter_worker import DynamicFilterWorker
from robot_ctrl.dynfilter.multibody_zmp import multibody_zmp
from robot_ctrl.dynfilter.preview_correction import PreviewCorrection
from robot_ctrl.sim.mujoco_backend import MujocoBackend
from robot_ctrl.wpg.plan import SolePlan


def random_configuration(robot, rng):
    q = robot.q_half_sitting.copy()
    q[robot.q_index] = rng.uniform(robot.lower, robot.upper)
    q[:3] = rng.uniform(-1, 1, 3)
    q[3:7] = pin.Quaternion(pin.utils.rpyToMatrix(*rng.uniform(-0.3, 0.3, 3))).coeffs()
    return q


def test_static_posture_zmp_is_the_com_ground_projection(talos):
    data = talos.pin.createData()
    rng = np.random.default_rng(1)
    zero = np.zeros(talos.pin.nv)
    for _ in range(10):
        q = random_configuration(talos, rng)
        com = pin.centerOfMass(talos.pin, data, q)
        np.testing.assert_allclose(multibody_zmp(talos.pin, data, q, zero, zero), com[:2], atol=1e-9)


def test_translational_acceleration_shifts_the_zmp_like_the_cart_table(talos):
    """A rigid robot accelerated horizontally without rotation: p = c − (c_z / g) a (cart-table)."""
    data = talos.pin.createData()
    q = talos.q_half_sitting.copy()
    q[:3] = [0.3, -0.2, 1.0]
    a = np.zeros(talos.pin.nv)
    a[:2] = [1.5, -0.7]  # base-frame = world-frame linear acceleration (no rotation)
    com = pin.centerOfMass(talos.pin, data, q)
    expected = com[:2] - com[2] / 9.81 * a[:2]
    np.testing.assert_allclose(multibody_zmp(talos.pin, data, q, np.zeros(talos.pin.nv), a), expected, atol=1e-6)


def test_filter_passes_reduce_the_zmp_error_of_a_recorded_plan(talos):
    hw = MujocoBackend(talos)
    hw.configure()
    hw.activate()
    state = hw.read()
    controller = WalkingController(talos, state)
    for _ in range(300):  # 1.5 s: walking, mid-step
        if controller.sample_due:
            controller.wpg.set_velocity(0.25, 0.0, 0.0)
        hw.write(controller.step(state))
        state = hw.read()
    hw.close()
    dynfilter = DynamicFilter(talos, controller.params.horizon, controller.params.com_height, "full", passes=3)
    dynfilter.update(controller.wpg.preview(), controller.ik.q, controller.com_z, controller.sole_height,
                     controller.upper_body)
    first, *_, last = dynfilter.pass_rms
    assert first > 0.005  # the cart-table plan is off by centimetres for the multibody robot
    assert last < 0.5 * first
    offset = dynfilter.offset(0.0).position
    assert np.all(np.abs(offset) < 0.05)


def standing_controller(talos) -> WalkingController:
    """A walking controller built from Talos standing in MuJoCo (its WPG is stepped without physics)."""
    hw = MujocoBackend(talos)
    hw.configure()
    state = hw.read()
    hw.close()
    return WalkingController(talos, state)


def test_worker_applies_the_in_process_filter_chain_one_sample_later(talos):
    """Fed the same plans, the worker's offset in sample k + 1 is the in-process filter's offset
    plan after sample k, carried one sample ahead; a worker that falls behind (stopped for 0.3 s)
    is waited for and changes nothing."""
    controller = standing_controller(talos)
    wpg, p = controller.wpg, controller.params
    inline = DynamicFilter(talos, p.horizon, p.com_height, "full", passes=1)
    worker = DynamicFilterWorker(talos, p.horizon, p.com_height, "full", passes=1)
    try:
        expected = None
        for k in range(12):
            wpg.set_velocity(0.25, 0.0, 0.0)
            wpg.update()
            args = (wpg.preview(), controller.ik.q, controller.com_z, controller.sole_height, controller.upper_body)
            began = time.perf_counter()
            worker.update(*args)
            if k == 4:  # the worker falls behind: stopped for 0.5 s with this request in hand
                os.kill(worker._process.pid, signal.SIGSTOP)
                resume = threading.Timer(0.5, os.kill, (worker._process.pid, signal.SIGCONT))
                resume.start()
            if k == 5:
                resume.join()
                assert time.perf_counter() - began > 0.1  # the next update waited for the late result
            if expected is None:
                np.testing.assert_array_equal(worker.offset(0.05).position, np.zeros(2))  # nothing back yet
            else:
                offset = worker.offset(0.05)
                np.testing.assert_allclose([offset.position, offset.velocity], expected, rtol=0, atol=1e-12)
                assert worker.pass_rms == inline.pass_rms
            inline.update(*args)
            carried = PreviewCorrection(p.horizon, p.com_height)
            carried.state, carried.jerks = inline.correction.state.copy(), inline.correction.jerks.copy()
            carried.advance(wpg.sample_duration)
            expected = carried.at(0.05)
        assert np.abs(expected[0]).max() > 1e-4  # the filter did correct something
    finally:
        worker.close()


def test_a_plan_crosses_to_the_worker_unchanged(talos):
    """PlanPreview pickles as a few arrays (the worker gets one per sample); what comes out is the
    plan, field by field, mid-swing too; a plan whose samples lack a foot pickles as it is."""
    controller = standing_controller(talos)
    wpg = controller.wpg
    for _ in range(12):
        wpg.set_velocity(0.3, 0.1, 0.2)
        wpg.update()
    plan = wpg.preview()
    assert any(sample.single_support for sample in plan.samples)
    plan.samples[3].feet["left"] = SolePlan(np.array([0.1, 0.2, 0.03]), 0.4, np.array([0.5, 0.0, -0.1]), 0.2)
    copy = pickle.loads(pickle.dumps(plan))
    assert (copy.t0, copy.sample_duration, len(copy.samples)) == (plan.t0, plan.sample_duration, len(plan.samples))
    for got, sent in zip(copy.samples, plan.samples):
        assert (got.t, got.single_support, set(got.feet)) == (sent.t, sent.single_support, set(sent.feet))
        np.testing.assert_array_equal([got.com, got.zmp], [sent.com, sent.zmp])
        for side, sole in sent.feet.items():
            assert (got.feet[side].yaw, got.feet[side].yaw_rate) == (sole.yaw, sole.yaw_rate)
            np.testing.assert_array_equal([got.feet[side].position, got.feet[side].velocity],
                                          [sole.position, sole.velocity])
    del plan.samples[0].feet["right"]
    assert set(pickle.loads(pickle.dumps(plan)).samples[0].feet) == {"left"}


def test_a_stopped_worker_is_reported(talos):
    controller = standing_controller(talos)
    wpg, p = controller.wpg, controller.params
    worker = DynamicFilterWorker(talos, p.horizon, p.com_height, "full", passes=1)
    wpg.update()
    args = (wpg.preview(), controller.ik.q, controller.com_z, controller.sole_height, controller.upper_body)
    worker.update(*args)
    worker._process.kill()
    worker._process.join()
    wpg.update()
    with pytest.raises(RuntimeError, match="the dynamic filter worker stopped"):
        worker.update(*args)
    worker.close()
    assert worker._process is None


def test_filter_settings_are_checked(talos):
    with pytest.raises(ValueError, match="dynfilter 'both' is not one of off, legs, full"):
        DynamicFilter(talos, 16, 0.88, "both")
    with pytest.raises(ValueError, match=r"dynfilter passes = 0 must be an integer in \[1, 10\]"):
        DynamicFilter(talos, 16, 0.88, "full", passes=0)


def test_preview_ik_reaches_the_planned_feet_com_and_waist(talos):
    from robot_ctrl.dynfilter.preview_ik import PreviewIK

    ik = PreviewIK(talos)
    ik.set_configuration(talos.q_half_sitting)
    data = talos.pin.createData()
    pin.framesForwardKinematics(talos.pin, data, talos.q_half_sitting)
    feet = [data.oMf[talos.frame_ids[f"{s}_foot"]].copy() for s in ("left", "right")]
    feet[1].translation += [0.15, 0.0, 0.03]  # right foot stepping forward and lifted
    com = pin.centerOfMass(talos.pin, data, talos.q_half_sitting) + [0.05, 0.04, -0.02]
    waist = pin.utils.rpyToMatrix(0.0, 0.0, 0.1)
    posture = talos.q_half_sitting[talos.q_index].copy()
    for _ in range(6):
        q = ik.step(feet, com, waist, posture)
    pin.framesForwardKinematics(talos.pin, data, q)
    for frame, target in zip((talos.frame_ids["left_foot"], talos.frame_ids["right_foot"]), feet):
        # The posture weight μ biases the tasks by O(μ²): micrometres.
        assert np.linalg.norm(pin.log6(data.oMf[frame].actInv(target)).vector) < 1e-5
    np.testing.assert_allclose(pin.centerOfMass(talos.pin, data, q), com, atol=1e-5)
    assert np.linalg.norm(pin.log3(waist @ data.oMf[talos.frame_ids["waist"]].rotation.T)) < 1e-5
    upper = [i for i, n in enumerate(talos.joint_names) if n.startswith("arm_")]
    # The posture acts in the tasks' null space: the arms stay near their reference.
    assert np.abs(q[talos.q_index][upper] - posture[upper]).max() < 0.05


def test_the_guard_refuses_a_diverging_update_and_returns_smoothly_to_the_plan(talos):
    """A plan whose CoM the legs cannot reach (0.4 m ahead of the feet) gives the preview a
    multibody ZMP metres off: the update is refused, counted, and the offset led back towards zero
    from where it was, within the bound."""
    from dataclasses import replace

    from robot_ctrl.dynfilter.dynamic_filter import MAX_OFFSET, filter_request
    from robot_ctrl.modes import FilterMode

    controller = standing_controller(talos)
    wpg, p = controller.wpg, controller.params
    dynfilter = DynamicFilter(talos, p.horizon, p.com_height, "full", passes=2)
    for _ in range(6):  # a sound plan first: some offset to return from
        wpg.set_velocity(0.25, 0.0, 0.0)
        wpg.update()
        dynfilter.update(wpg.preview(), controller.ik.q, controller.com_z, controller.sole_height, controller.upper_body)
    assert dynfilter.fallbacks == 0
    wpg.update()
    request = filter_request(FilterMode.FULL, wpg.preview(), controller.ik.q, controller.com_z, controller.sole_height,
                             controller.upper_body)
    plan = request.plan
    far = replace(request, plan=replace(plan, samples=tuple(replace(s, com=s.com + [0.4, 0.0]) for s in plan.samples)))
    before = dynfilter.correction.offsets(plan.sample_duration)[1]  # sample 1 is the next sample's start
    dynfilter.refine(far)
    assert dynfilter.fallbacks == 1 and dynfilter.pass_rms[0] > 0.06
    offsets = dynfilter.correction.offsets(plan.sample_duration)
    np.testing.assert_allclose(offsets[0], before, atol=1e-12)  # carried on, no jump
    assert np.abs(offsets).max() <= MAX_OFFSET and np.abs(offsets[-1]).max() < np.abs(offsets[0]).max() + 1e-6


def test_the_preview_walks_its_unplanned_swing_foot_ahead(talos):
    """At 0.5 m/s the horizon holds a swing whose landing the MPC does not plan yet: the preview
    repeats the last step instead of putting the foot back where it lifted off."""
    controller = standing_controller(talos)
    wpg = controller.wpg
    for _ in range(30):
        wpg.set_velocity(0.5, 0.0, 0.0)
        wpg.update()
    preview = wpg.preview().samples
    com_x = preview[-1].com[0]
    rear = min(f.position[0] for f in preview[-1].feet.values())
    assert com_x - rear < 0.35  # the legs keep up with the CoM (it was 0.52 m with the foot left behind)
