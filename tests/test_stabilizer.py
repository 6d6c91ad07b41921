"""The DCM stabilizer's desired ZMP stays in the support polygon however far the DCM runs away."""

import numpy as np
import pinocchio as pin
import pytest

from robot_ctrl.control.controllers.stabilizer import DcmStabilizer
from robot_ctrl.control.estimation.state_estimator import Estimate
from robot_ctrl.geometry.support_polygon import SupportPolygon

FEET = SupportPolygon.of_soles([(np.array([0.0, 0.09]), 0.0), (np.array([0.0, -0.09]), 0.0)], 0.21, 0.13)


def estimate(com_xy, com_velocity_xy, zmp):
    return Estimate(com=np.array([*com_xy, 0.9]), com_velocity=np.array([*com_velocity_xy, 0.0]),
                    soles={s: pin.SE3.Identity() for s in ("left", "right")}, in_contact={"left": True, "right": True},
                    zmp=np.asarray(zmp, float), support=FEET, hands={}, base_xy_yaw=np.zeros(3),
                    configuration=np.zeros(39))


def test_the_desired_zmp_is_clamped_onto_the_support_polygon():
    stabilizer = DcmStabilizer(com_height=0.88)
    # Pushed hard forward-left: the measured DCM is about 0.6 m ahead, far outside both feet.
    est = estimate([0.05, 0.04], [1.5, 0.6], [0.02, 0.0])
    stabilizer.correction(est, np.zeros(2), np.zeros(2), np.zeros(2), 0.005)
    p = stabilizer.desired_zmp
    assert FEET.contains(p, tol=1e-9) and abs(FEET.distance_inside(p)) < 1e-9  # on the boundary
    # ... at its closest point to where the unclamped law points (ahead and to the left of the feet).
    assert abs(p[0] - 0.105) < 1e-12 and 0.0 < p[1] <= 0.155
    # Inside the feet the law is not touched: a small DCM error gives a desired ZMP strictly inside.
    stabilizer.correction(estimate([0.0, 0.0], [0.02, 0.0], [0.0, 0.0]), np.zeros(2), np.zeros(2), np.zeros(2), 0.005)
    assert FEET.distance_inside(stabilizer.desired_zmp) > 0.05


def test_one_tick_of_the_feedback_law():
    """Δċ = k_zmp (p_meas − p_d) + k_com (c_ref − c_meas) − k_leak Δc, with p_d = p_ref + k_dcm (ξ_meas − ξ_ref),
    k_dcm = 1 + ω_dcm / ω, ξ = c + ċ / ω, integrated over one tick, each gain a different number so that a
    wrong sign or factor shows."""
    from robot_ctrl.control.controllers.stabilizer import StabilizerGains

    gains = StabilizerGains(dcm_rate=2.0, k_zmp=3.0, k_com=5.0, k_leak=7.0, max_offset=0.04)
    stabilizer = DcmStabilizer(com_height=0.8, gains=gains)
    omega = np.sqrt(9.81 / 0.8)
    stabilizer.offset = np.array([0.01, -0.002])
    com, velocity, zmp = np.array([0.004, 0.003]), np.array([0.03, -0.02]), np.array([0.01, 0.005])
    com_ref, velocity_ref, zmp_ref = np.array([0.0, 0.001]), np.array([0.02, 0.0]), np.array([0.002, 0.0])
    p_d = zmp_ref + (1 + 2.0 / omega) * ((com + velocity / omega) - (com_ref + velocity_ref / omega))
    rate = 3.0 * (zmp - p_d) + 5.0 * (com_ref - com) - 7.0 * np.array([0.01, -0.002])
    offset = stabilizer.correction(estimate(com, velocity, zmp), com_ref, velocity_ref, zmp_ref, 0.01)
    np.testing.assert_allclose(stabilizer.desired_zmp, p_d, rtol=1e-12)  # inside the feet: not clamped
    np.testing.assert_allclose(offset, np.array([0.01, -0.002]) + 0.01 * rate, rtol=1e-12)
    # The offset is bounded by max_offset on each axis.
    stabilizer.offset = np.array([0.0399, -0.0399])
    offset = stabilizer.correction(estimate(com - 1.0, velocity, zmp), com_ref, velocity_ref, zmp_ref, 0.01)
    assert offset[0] == 0.04


def test_the_clamp_is_the_closest_point_of_the_nearest_edge():
    stabilizer = DcmStabilizer(com_height=0.88)
    # The DCM straight ahead of the feet, mid-way between them: the desired ZMP on the front edge.
    stabilizer.correction(estimate([0.0, 0.0], [1.0, 0.0], [0.0, 0.0]), np.zeros(2), np.zeros(2), np.zeros(2), 0.005)
    np.testing.assert_allclose(stabilizer.desired_zmp, [0.105, 0.0], atol=1e-12)
    # Off to the right of the right foot's outer edge.
    stabilizer.correction(estimate([0.02, -0.2], [0.0, -0.3], [0.0, 0.0]), np.zeros(2), np.zeros(2), np.zeros(2), 0.005)
    p = stabilizer.desired_zmp
    assert abs(p[1] + 0.155) < 1e-12 and -0.105 < p[0] < 0.105


def test_the_lateral_dcm_rate_acts_across_the_heading():
    """K_dcm per axis of the walking frame: the forward rate along the heading, the lateral one across
    it, ``p_d = R diag(k_forward, k_lateral) Rᵀ (ξ_meas − ξ_ref)`` with R the heading's rotation (the
    default heading 0: the world's axes)."""
    from robot_ctrl.control.controllers.stabilizer import StabilizerGains

    omega = np.sqrt(9.81 / 0.8)
    k = np.diag([1 + 2.0 / omega, 1 + 6.0 / omega])
    error = np.array([0.01, 0.004])  # the measured DCM's departure (world frame), by the CoM alone
    for heading in (None, np.pi / 2, np.radians(30.0), -2.5):
        stabilizer = DcmStabilizer(com_height=0.8, gains=StabilizerGains(dcm_rate=2.0, lateral_dcm_rate=6.0))
        frame = {} if heading is None else {"heading": heading}
        stabilizer.correction(estimate(error, [0.0, 0.0], [0.0, 0.0]), np.zeros(2), np.zeros(2), np.zeros(2), 0.005,
                              **frame)
        c, s = np.cos(heading or 0.0), np.sin(heading or 0.0)
        R = np.array([[c, -s], [s, c]])
        np.testing.assert_allclose(stabilizer.desired_zmp, R @ k @ R.T @ error, rtol=1e-12, atol=1e-15)
    # Without a lateral rate both axes take the forward one, whatever the heading.
    stabilizer = DcmStabilizer(com_height=0.8, gains=StabilizerGains(dcm_rate=2.0))
    stabilizer.correction(estimate(error, [0.0, 0.0], [0.0, 0.0]), np.zeros(2), np.zeros(2), np.zeros(2), 0.005,
                          heading=1.0)
    np.testing.assert_allclose(stabilizer.desired_zmp, (1 + 2.0 / omega) * error, rtol=1e-12)


def test_a_robot_configs_gains_are_checked_field_by_field():
    """``StabilizerGains.of_robot``: the defaults under a config's fields; a field that is no gain, or
    a value outside (0, 100] (rates, 1/s) or (0, 0.2] (max_offset, m), is refused by name."""
    from robot_ctrl.control.controllers.stabilizer import StabilizerGains

    assert StabilizerGains.of_robot({}) == StabilizerGains()
    gains = StabilizerGains.of_robot({"lateral_dcm_rate": 6, "max_offset": 0.2, "k_zmp": 100})
    assert gains == StabilizerGains(lateral_dcm_rate=6.0, max_offset=0.2, k_zmp=100.0)
    assert isinstance(gains.lateral_dcm_rate, float)
    for fields, message in (({"dcm_gain": 3.0}, "stabilizer.dcm_gain is not a stabilizer gain (allowed: dcm_rate, "
                                                "lateral_dcm_rate, k_zmp, k_com, k_leak, max_offset)"),
                            ({"lateral_dcm_rate": 0.0},
                             "stabilizer.lateral_dcm_rate = 0.0 must be a number in (0, 100.0]"),
                            ({"k_com": 100.5}, "stabilizer.k_com = 100.5 must be a number in (0, 100.0]"),
                            ({"k_leak": True}, "stabilizer.k_leak = True must be a number in (0, 100.0]"),
                            ({"dcm_rate": "2"}, "stabilizer.dcm_rate = '2' must be a number in (0, 100.0]"),
                            ({"max_offset": 0.21}, "stabilizer.max_offset = 0.21 must be a number in (0, 0.2]"),
                            ({"max_offset": -0.01}, "stabilizer.max_offset = -0.01 must be a number in (0, 0.2]")):
        with pytest.raises(ValueError) as raised:
            StabilizerGains.of_robot(fields)
        assert str(raised.value) == f"robot config {message}"
