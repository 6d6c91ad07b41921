"""Body sensors of a real robot: the IMU and the foot force/torque sensors, from the lab's driver.

A servo bus carries the joints only. A walking robot also needs its IMU and its feet's
force/torque sensors, whose drivers differ from lab to lab, so robot_ctrl takes them as a plug-in:
the bus config names a function, ``body_sensors: my_lab.sensors:open``, which
:func:`open_body_sensors` imports and calls once as ``open(robot, config)``. It returns a callable
that the backend calls once per tick, after reading the joints, and that returns a
:class:`~robot_ctrl.hw.types.JointState` (its joint fields are ignored) with:

- ``t``: when the reading was taken, in seconds since ``open`` on a monotonic clock (the run's
  time: the state's, which its time limits and logs count in);
- ``base_quat_xyzw``: the IMU's attitude estimate (x, y, z, w), of the base link in the world;
- ``base_angvel``: the gyro [rad/s], its mean since the last call (the IMU's delta angle over that
  time, divided by it, as IMUs that integrate their gyro internally report it), and ``base_linacc``
  the accelerometer [m/s², gravity included], both in the base frame;
- ``foot_wrench``: ``{"left": (6,), "right": (6,)}``, force [N] then moment [N·m] at each sole
  frame's origin, in the sole frame, the floor's reaction on the foot;
- ``base_pos`` and ``base_linvel``: None (no sensor measures them: the floating-base estimator
  does, ``control/estimation/base_estimator.py``).
"""

from __future__ import annotations

import importlib
from typing import Callable

from robot_ctrl.buses.bus_config import BusConfig
from robot_ctrl.hw.adapter import HardwareFault
from robot_ctrl.hw.types import JointState
from robot_ctrl.robot.config import ConfigError


def open_body_sensors(config: BusConfig, robot) -> Callable[[], JointState]:
    """The reading function of the driver ``config.body_sensors`` names."""
    module_name, function = config.body_sensors.split(":")
    where = f"{config.path.name}: body_sensors = {config.body_sensors!r}"
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(f"{where}: cannot import {module_name} ({exc})") from exc
    opener = getattr(module, function, None)
    if not callable(opener):
        raise ConfigError(f"{where}: {module_name} has no function {function}")
    try:
        read = opener(robot, config)
    except Exception as exc:  # the lab's driver: whatever it raises, one line and exit status 3
        raise HardwareFault(f"{where}: the driver did not open ({type(exc).__name__}: {exc})") from exc
    if not callable(read):
        raise ConfigError(f"{where}: {function}(robot, config) must return a function that reads the sensors")
    return read
