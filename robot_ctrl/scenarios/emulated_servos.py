"""``robot-ctrl hw emulate``: emulated drives in a process of their own, serving their buses to
whatever process opens them, as real drives would.

The drives drive a simulated robot (``MujocoBackend`` in this process): MIT-CAN drives on the
python-can interfaces the bus config names (one that reaches other processes, e.g.
``udp_multicast``), Dynamixel servos behind pseudo-terminals linked at the devices the bus config
names. A controller in another process (``robot-ctrl hw stand --hw mit-can --bus-config F``)
drives them through the real backend, on the wall clock, exactly as it would drive real ones; if it
dies, the drives do what their firmware does on silence (a Damiao drive disables itself after its
CAN timeout; a Dynamixel's Bus Watchdog stops it where it is). The simulated robot runs on the wall
clock (free-running), whether or not a controller sends, and each drive answers at once.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Callable

from robot_ctrl.backends import emulated_drives
from robot_ctrl.buses.bus_config import load_bus_config
from robot_ctrl.buses.drive_status import StatusFile
from robot_ctrl.kernels import load_kernels
from robot_ctrl.modes import HardwareKind
from robot_ctrl.robot.config import ConfigError
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.sim.mujoco_backend import MujocoBackend


def serve_emulated_drives(kind: HardwareKind, robot: RobotModel, bus_config: str, status: Path | None,
                          log: Callable[[str], None], stop: threading.Event | None = None,
                          control_dt: float = 0.005) -> None:
    """Serve until ``stop`` is set (or a KeyboardInterrupt: Ctrl-C, SIGTERM); ``status``: the JSON
    file rewritten with every drive's status (``buses/drive_status.py``); ``control_dt``: the simulated
    robot's period [s]."""
    stop = stop or threading.Event()
    config = load_bus_config(bus_config, robot.joint_names)
    in_process = [name for name, options in config.buses.items() if options.get("interface") == "virtual"]
    if in_process:
        raise ConfigError(f"--bus-config {bus_config}: bus {in_process[0]} is python-can's virtual interface, which "
                          "reaches this process only: hw emulate serves other processes (use udp_multicast, as "
                          "configs/hw/talos_mit_can_emulated.yaml does)")
    load_kernels()  # the simulated robot's first step would compile or load them while the drives time out
    plant = MujocoBackend(robot, control_dt)
    with emulated_drives(kind, robot, plant, bus_config, free_running=control_dt) as (emulator, config):
        status_file = StatusFile(status, emulator.drive_status) if status is not None else None
        if status_file is not None:
            status_file.start()
        try:
            where = ", ".join(f"{name} ({_address(options)})" for name, options in config.buses.items())
            log(f"hw emulate: {len(config.motors)} {config.backend} drives of {robot.name} serving {where}"
                f"{f'; status in {status}' if status else ''} (Ctrl-C to stop)")
            while not stop.wait(0.1):
                pass
        finally:
            if status_file is not None:
                status_file.close()


def _address(options: dict) -> str:
    if "device" in options:
        return options["device"]
    return f"{options.get('interface')} {options.get('channel')}" + (f":{options['port']}" if "port" in options else "")
