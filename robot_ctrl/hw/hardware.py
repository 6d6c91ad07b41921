"""Choosing a hardware backend by name, as the CLI's ``--hw`` does.

- ``mujoco``: the robot simulated in MuJoCo (``MujocoBackend``) in a process of its own
  (``RobotProcess``: the controller computes while the robot moves), no safety layer (the
  simulation reports saturation and falls itself).
- ``mit-can-emulated``: ``MitCanBackend`` behind a ``SafetyLayer``, talking over python-can virtual
  buses to a ``MitCanEmulator`` whose motors drive the MuJoCo simulation (hardware in the loop).
- ``dynamixel-emulated``: ``DynamixelBackend`` behind a ``SafetyLayer``, over a pseudo-terminal to a
  ``DynamixelEmulator`` driving the MuJoCo simulation.

The emulated setups read the bus mapping from ``configs/hw/<robot>_mit_can.yaml`` or
``<robot>_dynamixel.yaml`` (or ``bus_config``), and use the simulation's clock for the safety layer's
watchdog and staleness checks (lock-step: the simulated robot waits for the controller).
"""

from __future__ import annotations

import dataclasses
import functools
from contextlib import contextmanager
from typing import Iterator

from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.bus_config import load_bus_config
from robot_ctrl.hw.mujoco_backend import MujocoBackend
from robot_ctrl.hw.robot_process import RobotProcess
from robot_ctrl.hw.safety import SafetyLayer, SafetyLimits
from robot_ctrl.robot.model import RobotModel

KINDS = ("mujoco", "mit-can-emulated", "dynamixel-emulated")


@contextmanager
def open_hardware(kind: str, robot: RobotModel, bus_config: str | None = None, viewer: bool = False,
                  control_dt: float = 0.005) -> Iterator[HardwareAdapter]:
    """The adapter for ``kind``; emulators are started before and stopped after the block."""
    if kind not in KINDS:
        raise ValueError(f"hw {kind!r} is not one of {', '.join(KINDS)}")
    if kind == "mujoco":
        hw = RobotProcess(functools.partial(MujocoBackend, robot, control_dt, viewer=viewer), robot.nj, robot.name)
        try:
            yield hw
        finally:
            hw.close()
        return
    plant = MujocoBackend(robot, control_dt, viewer=viewer)
    limits = SafetyLimits.from_robot(robot, control_dt)
    if kind == "mit-can-emulated":
        from robot_ctrl.hw.mit_can_backend import MitCanBackend
        from robot_ctrl.hw.mit_can_emulator import MitCanEmulator

        config = load_bus_config(bus_config or f"{robot.name}_mit_can", robot.joint_names)
        emulator = MitCanEmulator(config, plant)
        emulator.start()
        backend = MitCanBackend(config, robot.kd, body_sensors=emulator.body_state)
    else:
        from robot_ctrl.hw.dynamixel_backend import DynamixelBackend
        from robot_ctrl.hw.dynamixel_emulator import DynamixelEmulator

        config = load_bus_config(bus_config or f"{robot.name}_dynamixel", robot.joint_names)
        emulator = DynamixelEmulator(config, plant)
        emulator.start()
        config = dataclasses.replace(config, buses={"port": dict(config.buses["port"], device=emulator.port_name)})
        backend = DynamixelBackend(config, robot.kd, body_sensors=emulator.body_state)
    try:
        yield SafetyLayer(backend, limits, clock=emulator.clock)
    finally:
        emulator.close()
