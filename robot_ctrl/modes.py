"""The modes a user chooses between, validated in one place: ``Mode.parse(value)`` accepts a member
or its value and refuses anything else with one line naming the option and the allowed values."""

from __future__ import annotations

from enum import Enum


class _Mode(str, Enum):
    @classmethod
    def parse(cls, value):
        try:
            return cls(value)
        except ValueError:
            raise ValueError(f"{_OPTION[cls]} {value!r} is not one of {', '.join(m.value for m in cls)}") from None

    def __str__(self) -> str:
        return self.value


class FilterMode(_Mode):
    """What the dynamic filter's whole-body preview includes (``off``: no correction)."""

    OFF = "off"
    LEGS = "legs"  # the upper body frozen at its current reference over the horizon
    FULL = "full"  # the planned upper-body motion included


class ArmMotion(_Mode):
    """Upper-body reference of a walk: half-sitting arms, or the elbows swinging (``ArmSwing``)."""

    NONE = "none"
    SWING = "swing"


class BaseState(_Mode):
    """Where the controller's base pose and velocity come from."""

    SIMULATED = "simulated"  # the simulator's ground truth
    ESTIMATED = "estimated"  # IMU + leg kinematics + foot contacts (``control/base_estimator.py``)


class HardwareKind(_Mode):
    """The backends a scenario runs on (``robot_ctrl.hw.hardware.open_hardware``)."""

    MUJOCO = "mujoco"
    MIT_CAN_EMULATED = "mit-can-emulated"
    DYNAMIXEL_EMULATED = "dynamixel-emulated"
    MIT_CAN = "mit-can"  # real drives on the buses named in the bus config
    DYNAMIXEL = "dynamixel"

    @property
    def real(self) -> bool:
        """Real servos: no simulation behind them, no body sensors, the loop keeps the time."""
        return self in (HardwareKind.MIT_CAN, HardwareKind.DYNAMIXEL)


_OPTION = {FilterMode: "dynfilter", ArmMotion: "arms", BaseState: "base-state", HardwareKind: "hw"}  # the option each is chosen by
