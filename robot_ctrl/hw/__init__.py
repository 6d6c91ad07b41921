"""Hardware adapters: the lifecycle/read/write interface and its backends."""

from robot_ctrl.hw.adapter import HardwareAdapter, HardwareFault, LifecycleError
from robot_ctrl.hw.types import CommandError, JointCommand, JointState, LifecycleState

__all__ = ["CommandError", "HardwareAdapter", "HardwareFault", "JointCommand", "JointState", "LifecycleError", "LifecycleState"]
