"""Stack-of-tasks inverse kinematics: tasks, joint limits and the strict-priority QP solver.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "com_task": ["ComTask"],
    "frame_task": ["FrameTask"],
    "joint_limits": ["JointLimits"],
    "posture_task": ["PostureTask"],
    "solver": ["HierarchicalQP", "InfeasibleError"],
    "task": ["Task"],
    "whole_body_ik": ["WholeBodyIK"],
})
