"""State estimation: CoM, DCM, ZMP and support polygon from a measured state; the floating
base from the IMU, encoders and foot sensors; the IMU's attitude fused with its gyro.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "state_estimator": ["Estimate", "StateEstimator"],
    "base_estimator": ["BaseEstimator"],
    "attitude_filter": ["AttitudeFilter"],
})
