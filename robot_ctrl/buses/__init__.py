"""Real servo buses behind the hardware interface, each with its wire protocol, its backend and an
emulator that serves the servo side of the same wire from a simulated robot: MIT-style CAN drives
(``mit_*``) and Dynamixel servos (``dynamixel_*``); the YAML bus config that maps joints to motors,
and the lab's IMU and foot-sensor driver plug-in (``body_sensors``).
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "bus_config": ["BusConfig", "MotorMap", "load_bus_config"],
    "body_sensors": ["open_body_sensors"],
    "mit_can_backend": ["MitCanBackend"],
    "mit_can_emulator": ["MitCanEmulator"],
    "mit_protocol": ["MitRanges"],
    "dynamixel_backend": ["DynamixelBackend"],
    "dynamixel_emulator": ["DynamixelEmulator"],
    "dynamixel_port": ["DynamixelPort"],
})
