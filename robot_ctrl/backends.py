"""Choosing a hardware backend by name, as the CLI's ``--hw`` does.

- ``mujoco``: the robot simulated in MuJoCo (``MujocoBackend``) in a process of its own
  (``RobotProcess``: the controller computes while the robot moves), behind a ``SafetyLayer`` with
  the robot's limits and no soft start (``SafetyLimits.for_simulation``), on the simulation's clock.
- ``mit-can-emulated``: ``MitCanBackend`` behind a ``SafetyLayer``, talking over python-can virtual
  buses to a ``MitCanEmulator`` whose motors drive the MuJoCo simulation (hardware in the loop).
- ``dynamixel-emulated``: ``DynamixelBackend`` behind a ``SafetyLayer``, over a pseudo-terminal to a
  ``DynamixelEmulator`` driving the MuJoCo simulation.
- ``mit-can``, ``dynamixel``: real drives on the interfaces the bus config (``--bus-config``, required)
  names, behind a ``SafetyLayer`` on the wall clock with its watchdog thread. The IMU and the foot
  force/torque sensors come from the driver the bus config's ``body_sensors`` names
  (``buses/body_sensors.py``); without one they read the joints only, which the bring-up commands
  (``robot-ctrl hw``) need, and the scenarios refuse to run.

``disturbances`` (pushes, model mismatch, latency, sensor noise: ``sim/disturbances.py``) act on the
simulated robot, on the emulated buses' too. Every kind comes behind a ``SafetyLayer``: what a
controller sends reaches the simulated servos as it would reach real ones, and the layer's
interventions go to the run's report. ``video`` records an MP4 of the simulated robot
(``MujocoWorld``). The emulated setups read the bus mapping from ``configs/hw/<robot>_mit_can.yaml`` or
``<robot>_dynamixel.yaml`` (or ``bus_config``), and use the simulation's clock for the safety layer's
watchdog and staleness checks (lock-step: the simulated robot waits for the controller); the
watchdog thread runs as it would on a real bus.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

from robot_ctrl.buses.body_sensors import open_body_sensors
from robot_ctrl.buses.bus_config import load_bus_config, shipped_bus_configs
from robot_ctrl.hw.safety import SafetyLayer, SafetyLimits
from robot_ctrl.modes import HardwareKind
from robot_ctrl.robot.config import ConfigError
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.sim.disturbances import Disturbances
from robot_ctrl.sim.mujoco_backend import MujocoBackend
from robot_ctrl.sim.mujoco_video import Video
from robot_ctrl.sim.mujoco_world import MujocoWorld
from robot_ctrl.sim.prop import Prop
from robot_ctrl.sim.robot_process import RobotProcess

logger = logging.getLogger("robot_ctrl.backends")


@contextmanager
def open_hardware(kind: HardwareKind | str, robot: RobotModel, bus_config: str | None = None, viewer: bool = False,
                  control_dt: float = 0.005, video: Video | Path | None = None,
                  disturbances: Disturbances = Disturbances(),
                  prop: Prop | None = None, clock: Callable[[], float] = time.monotonic,
                  allow_drives_without_timeout: bool = False) -> Iterator[SafetyLayer]:
    """The adapter for ``kind``; emulators are started before and stopped after the block.
    ``prop``: a prop placed in the robot's simulated world (``sim/prop.py``), whose readings arrive
    in ``JointState.scene`` (e.g. the walk-and-reach task's drawer cabinet, ``sim/drawer_cabinet.py``);
    ``clock``: what real servos' backend and safety layer measure time with;
    ``allow_drives_without_timeout``: real drives with no command timeout of their own (which hold
    their last command if this process dies) may be enabled; on servo buses the joints that would
    hold are logged either way."""
    kind = HardwareKind.parse(kind)
    if disturbances.reply_loss and kind is not HardwareKind.MIT_CAN_EMULATED:
        raise ValueError(f"reply loss acts on the emulated MIT-CAN bus (--hw mit-can-emulated), not on {kind.value}")
    if kind is HardwareKind.MUJOCO:
        robot_process = RobotProcess(functools.partial(MujocoBackend, robot, control_dt, viewer=viewer, video=video,
                                                       disturbances=disturbances, prop=prop), robot.nj, robot.name)
        hw = SafetyLayer(robot_process, SafetyLimits.for_simulation(robot, control_dt), clock=None)
        try:
            yield hw
        finally:
            hw.close()
        return
    limits = SafetyLimits.from_robot(robot, control_dt)
    if kind.real:
        hw = SafetyLayer(_bus_backend(kind, robot, bus_config, clock, allow_drives_without_timeout), limits,
                         clock=clock)
        hw.start_watchdog()
        try:
            yield hw
        finally:
            hw.close()
        return
    plant = MujocoBackend(robot, control_dt, viewer=viewer, video=video, disturbances=disturbances, prop=prop)
    with emulated_drives(kind, robot, plant, bus_config, reply_loss=disturbances.reply_loss) as (emulator, config):
        _say_what_holds(config)
        if kind is HardwareKind.MIT_CAN_EMULATED:
            from robot_ctrl.buses.mit_can_backend import MitCanBackend

            backend = MitCanBackend(config, robot.kd, body_sensors=emulator.body_state)
        else:
            from robot_ctrl.buses.dynamixel_backend import DynamixelBackend

            config = dataclasses.replace(config, buses={name: dict(port, device=emulator.port_names[name])
                                                        for name, port in config.buses.items()})
            backend = DynamixelBackend(config, robot.kd, body_sensors=emulator.body_state, effort=robot.effort,
                                       velocity=robot.velocity_limit)
        hw = SafetyLayer(backend, limits, clock=emulator.clock)
        hw.start_watchdog()  # a bus has no lock-step: a stalled controller must be caught from outside
        try:
            yield hw
        finally:
            hw.close()


@contextmanager
def emulated_drives(kind: HardwareKind | str, robot: RobotModel, plant, bus_config: str | None = None,
                    reply_loss: float = 0.0, free_running: float | None = None):
    """The emulated drives of the bus config (default ``configs/hw/<robot>_mit_can`` or
    ``_dynamixel``) driving ``plant``, started before the block and stopped after it; yields the
    emulator and its bus config. ``kind``: an MIT-CAN or Dynamixel kind, emulated or real (what the
    drives stand in for); ``free_running``: for a controller in another process, the plant's period
    on the wall clock (not lock-step), with Dynamixel ports at the devices the config names."""
    kind = HardwareKind.parse(kind)
    if kind in (HardwareKind.MIT_CAN, HardwareKind.MIT_CAN_EMULATED):
        from robot_ctrl.buses.mit_can_emulator import MitCanEmulator

        config = _bus_config(kind, bus_config or f"{robot.name}_mit_can", robot)
        emulator = MitCanEmulator(config, plant, period=free_running)
        emulator.drop_probability = reply_loss
    elif kind in (HardwareKind.DYNAMIXEL, HardwareKind.DYNAMIXEL_EMULATED):
        from robot_ctrl.buses.dynamixel_emulator import DynamixelEmulator

        config = _bus_config(kind, bus_config or f"{robot.name}_dynamixel", robot)
        emulator = DynamixelEmulator(config, plant, link_devices=free_running is not None, period=free_running)
    else:
        raise ValueError(f"--hw {kind.value} has no servo bus to emulate (mit-can or dynamixel)")
    try:
        emulator.start()
        yield emulator, config
    finally:
        emulator.close()


def _bus_backend(kind: HardwareKind, robot: RobotModel, bus_config: str | None, clock: Callable[[], float],
                 allow_drives_without_timeout: bool):
    """The backend of real drives, on the interfaces the bus config names, with the body sensors it
    names (if any); drives with no command timeout of their own only when allowed."""
    if bus_config is None:
        raise ConfigError(f"--hw {kind.value} needs --bus-config: the YAML naming your buses, CAN ids, directions "
                          f"and zero offsets (start from {shipped_bus_configs()})")
    config = _bus_config(kind, bus_config, robot)
    if kind is HardwareKind.DYNAMIXEL:
        missing = {name: port["device"] for name, port in config.buses.items() if not Path(port["device"]).exists()}
        if missing:
            raise ConfigError(f"--bus-config {bus_config}: no serial device " + ", ".join(
                f"{device} (port {name})" for name, device in missing.items()) + ": is the adapter plugged in "
                "(ls /dev/serial/by-id)?")
    holding = _say_what_holds(config)
    if holding and not allow_drives_without_timeout:
        raise ConfigError(f"--hw {kind.value}: {len(holding)} drives have no command timeout of their own "
                          f"({', '.join(holding[:3])}{', ...' if len(holding) > 3 else ''}): if this process dies "
                          "they hold their last command. Pass --allow-drives-without-timeout to run them anyway")
    sensors = open_body_sensors(config, robot) if config.body_sensors else None
    if kind is HardwareKind.MIT_CAN:
        from robot_ctrl.buses.mit_can_backend import MitCanBackend

        return MitCanBackend(config, robot.kd, body_sensors=sensors, clock=clock)
    from robot_ctrl.buses.dynamixel_backend import DynamixelBackend

    return DynamixelBackend(config, robot.kd, body_sensors=sensors, clock=clock, effort=robot.effort,
                            velocity=robot.velocity_limit)


def _bus_config(kind: HardwareKind, name: str, robot: RobotModel):
    """The bus config ``name``, refused in one line if it is not for the backend ``kind`` drives."""
    config = load_bus_config(name, robot.joint_names)
    wanted = "mit_can" if kind in (HardwareKind.MIT_CAN, HardwareKind.MIT_CAN_EMULATED) else "dynamixel"
    if config.backend != wanted:
        raise ConfigError(f"--bus-config {name}: a {config.backend} bus config, and --hw {kind.value} needs a "
                          f"{wanted} one (start from {shipped_bus_configs()})")
    return config


def _say_what_holds(config) -> tuple[str, ...]:
    """Log which joints of the bus config would hold their last command if this process died, and
    return them."""
    holding = config.holding_joints
    if holding:
        logger.warning("if this process dies, %d joints hold their last command (no drive timeout): %s",
                       len(holding), ", ".join(holding))
    else:
        logger.warning("if this process dies, every drive stops by itself (its command timeout)")
    return holding


@contextmanager
def open_group_hardware(kind: HardwareKind | str, robot: RobotModel, base_poses: list[tuple[float, float, float]],
                        viewer: bool = False, control_dt: float = 0.005, video: Video | Path | None = None,
                        disturbances: Disturbances = Disturbances()) -> Iterator[tuple[MujocoWorld, list[SafetyLayer]]]:
    """Several copies of ``robot`` in one MuJoCo world, at ``base_poses`` (world x, y, yaw), each
    behind its own ``SafetyLayer`` and under the same ``disturbances`` (each robot pushed in its own
    start frame); the world steps once every robot has written its command. Only
    ``mujoco``: the emulated buses each drive a world of their own."""
    if disturbances.reply_loss:
        raise ValueError("reply loss acts on the emulated MIT-CAN bus (--hw mit-can-emulated); a group walks in MuJoCo")
    if HardwareKind.parse(kind) is not HardwareKind.MUJOCO:
        raise ValueError(f"hw {kind!r}: a group walks in one shared MuJoCo world, which only the 'mujoco' "
                         "backend drives (each emulated bus drives a simulated robot of its own)")
    prefixes = tuple(f"{robot.name}_{i}" for i in range(len(base_poses)))
    world = MujocoWorld(robot.group_mjcf_path(prefixes), control_dt, viewer, video, disturbances.friction_scale)
    limits = SafetyLimits.for_simulation(robot, control_dt)
    hws = [SafetyLayer(MujocoBackend(robot, world=world, prefix=p, base_xy_yaw=pose, disturbances=disturbances),
                       limits, clock=None)
           for p, pose in zip(prefixes, base_poses)]
    try:
        yield world, hws
    finally:
        for hw in hws:
            hw.close()
        world.close()
