"""AttitudeFilter: the IMU's attitude fused with its gyro, checked on a turn known in closed form,
clean and with the attitude noise of ``--sensor-noise``."""

import numpy as np
import pinocchio as pin

from robot_ctrl.control.estimation.attitude_filter import AttitudeFilter
from robot_ctrl.geometry import yaw_of
from robot_ctrl.hw.types import JointState
from robot_ctrl.sim.disturbances import NOISE

DT, N = 0.005, 1000  # 5 s at 200 Hz
OMEGA = np.array([0.3, -0.2, 0.5])  # [rad/s] a constant body-frame turn
START = pin.rpy.rpyToMatrix(0.02, -0.01, 0.7)
SIGMA = NOISE["base_orientation"]


def quat_xyzw(rotation):
    x, y, z, w = pin.Quaternion(rotation).coeffs()
    return np.array([x, y, z, w])


def readings(noise: bool, seed: int = 0):
    """The base turning at OMEGA from START, read with or without noise; the true attitude beside."""
    rng = np.random.default_rng(seed)
    for k in range(N):
        attitude = START @ pin.exp3(OMEGA * k * DT)
        measured = attitude @ pin.exp3(rng.normal(0.0, SIGMA, 3)) if noise else attitude
        yield JointState(t=k * DT, q=np.zeros(2), dq=np.zeros(2), tau=np.zeros(2), base_pos=np.array([1.0, 2.0, 0.9]),
                         base_quat_xyzw=quat_xyzw(measured), base_angvel=OMEGA.copy()), attitude


def errors(noise: bool):
    imu = AttitudeFilter()
    attitude_error, start_error = [], []
    for reading, attitude in readings(noise):
        out = imu.update(reading)
        attitude_error.append(pin.log3(attitude.T @ pin.Quaternion(*out.base_quat_xyzw[[3, 0, 1, 2]]).matrix()))
        start_error.append(pin.log3(START.T @ imu.start_attitude))
    return np.array(attitude_error), np.array(start_error), imu


def test_without_noise_the_estimate_stays_on_the_reading():
    attitude, start, imu = errors(noise=False)
    assert np.abs(attitude).max() < 1e-9 and np.abs(start).max() < 1e-9
    np.testing.assert_allclose(imu.start_pose, [1.0, 2.0, yaw_of(START)], atol=1e-9)


def test_the_filter_averages_the_attitude_noise_and_refines_the_start():
    """At the gain floor (τ = 1 s) a white noise σ leaves σ √(a/(2 − a)) = 0.05 σ; the start
    attitude, carried back by the gyro, ends within a fifth of σ while the first reading alone is
    off by about σ per axis."""
    attitude, start, _ = errors(noise=True)
    assert 0.03 * SIGMA < attitude[N // 2:].std() < 0.08 * SIGMA
    assert np.linalg.norm(start[0]) > 0.5 * SIGMA
    assert np.linalg.norm(start[-1]) < 0.2 * SIGMA  # three axes of 0.05 σ each


def test_a_gap_in_the_readings_restarts_the_filter_on_the_reading():
    imu = AttitudeFilter()
    states = [r for r, _ in readings(noise=True)]
    for state in states[:100]:
        imu.update(state)
    late = states[200]  # 0.5 s after the last reading
    np.testing.assert_array_equal(imu.update(late).base_quat_xyzw, late.base_quat_xyzw)
    np.testing.assert_array_equal(imu.start_pose[:2], [1.0, 2.0])


def test_the_first_readings_are_averaged():
    """Standing still, the gain ``max(1/n, dt/τ)`` makes the n-th estimate the mean of the first n
    readings while 1/n is the larger: 20 noisy readings give their mean, to second order in the
    noise, not a value still near the first reading (what the floor ``dt/τ`` alone would give)."""
    rng = np.random.default_rng(3)
    imu = AttitudeFilter()
    deviations = []
    for k in range(20):
        noise = rng.normal(0.0, SIGMA, 3)
        deviations.append(noise)
        reading = JointState(t=k * DT, q=np.zeros(2), dq=np.zeros(2), tau=np.zeros(2), base_pos=np.zeros(3),
                             base_quat_xyzw=quat_xyzw(START @ pin.exp3(noise)), base_angvel=np.zeros(3))
        out = imu.update(reading)
    estimate = pin.log3(START.T @ pin.Quaternion(*out.base_quat_xyzw[[3, 0, 1, 2]]).matrix())
    mean = np.mean(deviations, axis=0)
    assert np.linalg.norm(estimate - mean) < 3e-4  # the mean of the readings
    assert np.linalg.norm(mean - deviations[0]) > 3 * 3e-4  # and far from the first reading alone
