"""The DCM stabilizer's desired ZMP stays in the support polygon however far the DCM runs away."""

import numpy as np
import pinocchio as pin

from robot_ctrl.control.estimator import Estimate
from robot_ctrl.control.stabilizer import DcmStabilizer
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
