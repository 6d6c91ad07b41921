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
    ESTIMATED = "estimated"  # IMU + leg kinematics + foot contacts (``control/estimation/base_estimator.py``)


class HardwareKind(_Mode):
    """The backends a scenario runs on (``robot_ctrl.backends.open_hardware``)."""

    MUJOCO = "mujoco"
    MIT_CAN_EMULATED = "mit-can-emulated"
    DYNAMIXEL_EMULATED = "dynamixel-emulated"
    MIT_CAN = "mit-can"  # real drives on the buses named in the bus config
    DYNAMIXEL = "dynamixel"

    @property
    def real(self) -> bool:
        """Real servos: no simulation behind them, no body sensors, the loop keeps the time."""
        return self in (HardwareKind.MIT_CAN, HardwareKind.DYNAMIXEL)


class SpeedClass(_Mode):
    """How fast the walk-and-reach sequence is played: the synthesis's clock runs ``scale`` times
    the learned one, so every action lasts 1/scale of its learned duration and the pelvis moves
    ``scale`` times as fast over the same lengths (the gait's steps shorten with it, their lengths
    kept). The scalings are the thesis's (3.3.2: 0.8, 0.92 and 1.2, its slow, middle and fast
    trials of Table 3.1); ``nominal`` plays the learned timing."""

    SLOW = "slow"
    MIDDLE = "middle"
    NOMINAL = "nominal"
    FAST = "fast"

    @property
    def scale(self) -> float:
        return {"slow": 0.8, "middle": 0.92, "nominal": 1.0, "fast": 1.2}[self.value]


class DrawerMethod(_Mode):
    """How the drawer task is done: our method (synthesis → WPG → dynamic filter → stack of tasks),
    or the naive baseline of thesis 3.8.4 (every joint learned and played on the servos)."""

    OURS = "ours"
    NAIVE = "naive"


class CameraView(_Mode):
    """Where a simulation video's camera films from (``sim/mujoco_video.py``)."""

    FOLLOW = "follow"  # behind and to the right of the robots, following them
    SIDE = "side"  # the robot's left side, a little ahead of it, where its hands reach
    TOP = "top"  # from above
    HAND = "hand"  # close on the robot's left hand


_OPTION = {CameraView: "camera", DrawerMethod: "method", FilterMode: "dynfilter", ArmMotion: "arms", BaseState: "base-state", HardwareKind: "hw", SpeedClass: "speed"}  # the option each is chosen by
