"""Hardware adapters: the lifecycle/read/write interface and its backends."""

from robot_ctrl.hw.adapter import HardwareAdapter, LifecycleError
from robot_ctrl.hw.types import CommandError, JointCommand, JointState, LifecycleState

__all__ = ["CommandError", "HardwareAdapter", "JointCommand", "JointState", "LifecycleError", "LifecycleState"]
