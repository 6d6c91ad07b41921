"""BaseEstimator: the base's pose and velocity from the IMU, the encoders and the foot sensors,
checked against kinematics computed here and against the simulator over a walk."""

import dataclasses
import json

import numpy as np
import pinocchio as pin
import pytest

from robot_ctrl.cli import main
from robot_ctrl.control.estimation.base_estimator import BaseEstimator
from robot_ctrl.geometry import GRAVITY, SIDES
from robot_ctrl.hw.types import JointState

LEGS = {"left": slice(0, 6), "right": slice(6, 12)}  # the legs' joints in Talos's joint order


def standing_robot(talos, yaw, roll):
    """A turned, slightly rolled half-sitting configuration with both soles' mean on z = 0."""
    q = talos.q_half_sitting.copy()
    q[:3] = [0.4, -0.3, 0.0]
    q[3:7] = pin.Quaternion(pin.utils.rpyToMatrix(roll, 0.0, yaw)).coeffs()  # x, y, z, w
    data = talos.pin.createData()
    pin.framesForwardKinematics(talos.pin, data, q)
    q[2] = -np.mean([data.oMf[talos.frame_ids[f"{s}_foot"]].translation[2] for s in SIDES])
    return q


def feet_still_velocity(talos, q, base_twist):
    """Generalized velocity with the base moving by ``base_twist`` (linear, angular; base frame)
    and each leg's joints moving so that its sole stays still: ``J_leg dq_leg = −J_base v_base``."""
    data = talos.pin.createData()
    pin.computeJointJacobians(talos.pin, data, q)
    pin.updateFramePlacements(talos.pin, data)
    v = np.zeros(talos.pin.nv)
    v[:6] = base_twist
    for side in SIDES:
        J = pin.getFrameJacobian(talos.pin, data, talos.frame_ids[f"{side}_foot"], pin.LOCAL)
        legs = talos.v_index[LEGS[side]]
        v[legs] = np.linalg.solve(J[:, legs], -J[:, :6] @ v[:6])
    return v


def sensed_state(talos, t, q, v, base_known: bool) -> JointState:
    """What the robot's sensors give at (q, v): encoders, the IMU's attitude and gyro, feet each
    carrying half the weight; the base's position and velocity only when ``base_known``."""
    rot = pin.Quaternion(q[6], *q[3:6]).matrix()
    half = np.array([0.0, 0.0, talos.mass * GRAVITY / 2, 0.0, 0.0, 0.0])
    return JointState(t=t, q=q[talos.q_index], dq=v[talos.v_index], tau=np.zeros(talos.nj),
                      base_pos=q[:3].copy() if base_known else np.full(3, np.nan),
                      base_quat_xyzw=q[3:7].copy(), base_angvel=v[3:6].copy(),
                      base_linvel=rot @ v[:3] if base_known else np.full(3, np.nan),
                      foot_wrench={s: half for s in SIDES})


def test_leg_odometry_gives_the_base_velocity_and_position_of_a_moving_base(talos):
    """The base of a turned, rolled robot translates and spins with both soles still: the
    estimate's velocity is the base's, and one tick later its position is where the base went."""
    q = standing_robot(talos, yaw=0.7, roll=0.05)
    v = feet_still_velocity(talos, q, np.array([0.2, -0.1, 0.05, 0.1, -0.2, 0.3]))
    rot = pin.Quaternion(q[6], *q[3:6]).matrix()
    yaw = np.arctan2(rot[1, 0], rot[0, 0])
    estimator = BaseEstimator(talos, (q[0], q[1], yaw))
    first = estimator.update(sensed_state(talos, 0.0, q, v, base_known=False))
    np.testing.assert_allclose(first.base_pos, q[:3], atol=1e-9)
    np.testing.assert_allclose(first.base_linvel, rot @ v[:3], atol=1e-9)
    dt = 0.005
    q1 = pin.integrate(talos.pin, q, v * dt)
    second = estimator.update(sensed_state(talos, dt, q1, v, base_known=False))
    np.testing.assert_allclose(second.base_pos, q1[:3], atol=2e-5)  # the soles moved O(dt²)
    np.testing.assert_allclose(second.base_quat_xyzw, q1[3:7], atol=1e-12)
    assert estimator.contacts == ("left", "right")


def test_the_estimate_never_reads_the_measured_base(talos):
    q = standing_robot(talos, yaw=-0.3, roll=0.0)
    v = feet_still_velocity(talos, q, np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.2]))
    runs = []
    for known in (True, False):
        estimator = BaseEstimator(talos, (q[0], q[1], -0.3))
        runs.append([estimator.update(sensed_state(talos, k * 0.005, pin.integrate(talos.pin, q, v * k * 0.005), v,
                                                    known)) for k in range(5)])
    for with_truth, without in zip(*runs):
        np.testing.assert_array_equal(with_truth.base_pos, without.base_pos)
        np.testing.assert_array_equal(with_truth.base_linvel, without.base_linvel)


def test_a_lifted_foot_is_not_an_anchor(talos):
    """A foot carrying less than the release share stops anchoring; the other foot alone carries the estimate."""
    q = standing_robot(talos, yaw=0.0, roll=0.0)
    v = np.zeros(talos.pin.nv)
    estimator = BaseEstimator(talos, (q[0], q[1], 0.0))
    state = sensed_state(talos, 0.0, q, v, base_known=False)
    estimator.update(state)
    lifted = dict(state.foot_wrench, right=np.zeros(6))
    estimate = estimator.update(dataclasses.replace(state, t=0.005, foot_wrench=lifted))
    assert estimator.contacts == ("left",)
    np.testing.assert_allclose(estimate.base_pos, q[:3], atol=1e-9)


def test_walk_with_the_estimated_base_and_noisy_sensors(tmp_path):
    """#19's bar: 3 m with the floating-base estimator instead of the simulator's base state (here
    with noisy encoders, IMU attitude and foot sensors): no fall, final error ≤ 5 cm."""
    assert main(["walk", "--distance", "3", "--base-state", "estimated", "--sensor-noise", "--quiet",
                 "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fell"] is False and report["base_state"] == "estimated"
    assert report["final_position_error_m"] <= 0.05
    error = report["base_estimate_error"]
    assert error["position_error_max_m"] < 0.03 and error["velocity_error_rms_mps"] < 0.03
    assert report["zmp_in_support_ratio"] >= 0.98


@pytest.mark.parametrize("option,message", [(["--base-state", "guess"], "--base-state")])
def test_bad_base_state_is_refused(option, message, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["walk", "--distance", "1", *option])
    assert exit_info.value.code == 2 and message in capsys.readouterr().err
