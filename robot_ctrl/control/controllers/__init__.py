"""Controllers: one ``step(JointState) -> JointCommand`` per tick, and their parts.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "walking_controller": ["WalkingController", "WalkingOptions", "PlanSample"],
    "balance_controller": ["BalanceController", "BalanceParams"],
    "joint_playback": ["JointPlayback"],
    "stabilizer": ["DcmStabilizer", "StabilizerGains"],
    "static_feedforward": ["static_torques"],
    "arm_swing": ["ArmSwing"],
    "push_recovery": ["plan_velocity_change"],
})
