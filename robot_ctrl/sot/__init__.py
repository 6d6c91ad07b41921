"""Stack-of-tasks inverse kinematics: tasks, joint limits and the strict-priority QP solver."""

from robot_ctrl.sot.com_task import ComTask
from robot_ctrl.sot.frame_task import FrameTask
from robot_ctrl.sot.joint_limits import JointLimits
from robot_ctrl.sot.posture_task import PostureTask
from robot_ctrl.sot.solver import HierarchicalQP, InfeasibleError
from robot_ctrl.sot.task import Task
from robot_ctrl.sot.whole_body_ik import WholeBodyIK

__all__ = ["ComTask", "FrameTask", "HierarchicalQP", "InfeasibleError", "JointLimits", "PostureTask", "Task",
           "WholeBodyIK"]
