"""Joint-to-motor mapping of a servo bus, read from YAML (``configs/hw/*.yaml``).

A file names the backend, its buses (or serial port), motor models with their ranges, and one
entry per joint of the robot::

    backend: mit_can                      # or dynamixel
    buses:                                # mit_can: python-can bus per name
      can0: {interface: socketcan, channel: can0, bitrate: 1000000}
    port: {device: /dev/ttyUSB0, baudrate: 4000000}   # dynamixel: one port, or several:
    ports: {left: {device: /dev/ttyUSB0, baudrate: 4000000}, right: {...}}   # joints name theirs in bus
    models:
      leg: {position: [-12.5, 12.5], velocity: [-20, 20], kp: [0, 10000], kd: [0, 300], torque: [-320, 320]}
    joints:
      leg_left_1_joint: {bus: can0, id: 1, model: leg, direction: 1, zero_offset: 0.0, gear_ratio: 1.0}
    reply_timeout_s: 0.001                # mit_can: the longest wait for a tick's replies
    max_missed_replies: 3                 # a motor's last values are held this many ticks, then a fault
    stale_check_every: 20                 # mit_can: every this many ticks the host first listens with nothing
                                          # asked (replies then are late), 0: never (drives that send unasked)
    drive_timeout_s: 0.1                  # mit_can: drives with a CAN timeout (Damiao) disable themselves
                                          # after this long without a command
    body_sensors: my_lab.sensors:open     # the IMU and foot F/T driver, module:function (buses/body_sensors.py)
    # dynamixel models may set their protective limits: shutdown (hardware-error bits that switch the
    # torque off, default 0x34), temperature_limit_c (default 85), pwm_limit (default 885); the
    # velocity limit is the joint's
    without_drive_timeout:                # mit_can: drives with no command timeout of their own (mit6,
      why: "in a few words"               # cubemars) are enabled only with each of their joints named
      joints: [leg_left_1_joint, ...]     # here, and on real buses only with --allow-drives-without-timeout

A mit_can model may name its reply format, ``reply: mit6`` (default), ``cubemars`` or ``damiao``
(``mit_protocol``); the motors of one bus share one format, and Damiao ids are 1..15.

Conventions (motor side = what crosses the bus, joint side = the robot config's joint order)::

    q = direction (p − zero_offset) / gear_ratio          p: motor position [rad]
    dq = direction v / gear_ratio,  τ = direction gear_ratio τ_m
    kp_m = kp / gear_ratio²,  kd_m = kd / gear_ratio²

Every field is checked when the file is loaded; errors name the joint and the field.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from robot_ctrl import ROOT
from robot_ctrl.buses.mit_protocol import REPLY_FORMATS
from robot_ctrl.robot.config import ConfigError

HW_CONFIGS = ROOT / "configs" / "hw"


def shipped_bus_configs() -> str:
    """The bus configs shipped in ``configs/hw/`` to start a robot's from, for messages that suggest
    one (not the ``*_emulated`` ones, for drives that ``robot-ctrl hw emulate`` serves)."""
    return " or ".join(f"configs/hw/{p.name}" for p in sorted(HW_CONFIGS.glob("*.yaml"))
                       if not p.stem.endswith("_emulated"))
BACKENDS = ("mit_can", "dynamixel")


@dataclass(frozen=True)
class MotorMap:
    joint: str
    bus: str
    id: int
    model: str
    direction: int  # +1 or −1
    zero_offset: float  # [rad] motor position at joint zero
    gear_ratio: float  # motor turns per joint turn (> 0)


@dataclass(frozen=True)
class DriveTimeoutWaiver:
    """Drives with no command timeout of their own that the config lets be enabled: why, and the
    joints they drive (each named, so that a drive added later is not waived unseen)."""

    why: str
    joints: tuple[str, ...]


@dataclass(frozen=True)
class BusConfig:
    backend: str
    buses: dict[str, dict[str, Any]]  # bus name -> python-can options (mit_can) / port name -> port (dynamixel)
    models: dict[str, dict[str, Any]]
    motors: tuple[MotorMap, ...]  # in the robot's joint order
    path: Path
    reply_timeout: float = 0.001  # [s] the longest wait for a tick's replies (mit_can)
    max_missed_replies: int = 3  # replies a motor may miss in a row (its last values held) before a fault
    stale_check_every: int = 20  # ticks between listens with nothing asked, for late replies (mit_can; 0: never)
    drive_timeout: float = 0.1  # [s] set on drives that have a CAN timeout (mit_can, Damiao)
    body_sensors: str | None = None  # "module:function" opening the IMU and foot F/T driver (buses/body_sensors.py)
    #: Why motors without a drive-side command timeout may be enabled (None: they may not). Such a
    #: drive holds its last command, stiff, when the host dies.
    without_drive_timeout: DriveTimeoutWaiver | None = None

    def reply_format(self, motor: MotorMap) -> str:
        """The reply format of ``motor``'s model (mit_can)."""
        return self.models[motor.model].get("reply", "mit6")

    @property
    def holding_joints(self) -> tuple[str, ...]:
        """Joints whose drive has no command timeout of its own and holds its last command if the host
        dies: MIT-CAN drives but Damiao's (a Dynamixel servo's Bus Watchdog stops it)."""
        if self.backend != "mit_can":
            return ()
        return tuple(m.joint for m in self.motors if self.reply_format(m) != "damiao")

    # Joint side <-> motor side, vectorized over the joints.
    @property
    def direction(self) -> np.ndarray:
        return np.array([m.direction for m in self.motors], dtype=float)

    @property
    def gear(self) -> np.ndarray:
        return np.array([m.gear_ratio for m in self.motors])

    @property
    def zero(self) -> np.ndarray:
        return np.array([m.zero_offset for m in self.motors])

    def to_motor(self, q, dq, kp, kd, tau):
        d, g = self.direction, self.gear
        return d * g * q + self.zero, d * g * dq, kp / g**2, kd / g**2, d * tau / g

    def to_joint(self, p, v, tau_m):
        d, g = self.direction, self.gear
        return d * (p - self.zero) / g, d * v / g, d * g * tau_m


def _require(cond: bool, message: str, path: Path) -> None:
    if not cond:
        raise ConfigError(f"{path.name}: {message}")


GEAR_RATIO = (0.1, 1000.0)  # motor turns per joint turn: direct drive to the strongest harmonic drives, with margin


def _integer(x) -> bool:
    """An integer as YAML gives it (a bool is not one)."""
    return isinstance(x, int) and not isinstance(x, bool)


def _finite(x) -> bool:
    """A finite number as YAML gives it (a bool is not one)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


def load_bus_config(name_or_path: str | Path, joint_names: tuple[str, ...]) -> BusConfig:
    """Load ``configs/hw/<name>.yaml`` (or a path) for a robot with these joints (in order)."""
    path = Path(name_or_path)
    if not path.suffix:
        path = HW_CONFIGS / f"{name_or_path}.yaml"
    if not path.is_file():
        have = sorted(p.stem for p in HW_CONFIGS.glob("*.yaml"))
        raise ConfigError(f"bus config {str(name_or_path)!r} not found; configs/hw has: {have}")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"cannot read bus config {path}: {' '.join(str(exc).split())}") from exc
    _require(isinstance(data, dict), "the file must be a YAML mapping", path)
    backend = data.get("backend")
    _require(backend in BACKENDS, f"backend must be one of {BACKENDS}, got {backend!r}", path)
    models = data.get("models") or {}
    _require(isinstance(models, dict) and models, "models must map model names to their ranges", path)
    if backend == "mit_can":
        buses = data.get("buses") or {}
        _require(isinstance(buses, dict) and buses, "buses must map bus names to python-can options", path)
        for bus, options in buses.items():
            _require(isinstance(options, dict) and "interface" in options and "channel" in options,
                     f"buses.{bus} needs interface and channel", path)
        for model, ranges in models.items():
            for key in ("position", "velocity", "kp", "kd", "torque"):
                r = ranges.get(key) if isinstance(ranges, dict) else None
                _require(isinstance(r, list) and len(r) == 2 and all(_finite(x) for x in r) and r[0] < r[1],
                         f"models.{model}.{key} must be [low, high], finite numbers with low < high", path)
            _require(ranges.get("reply", "mit6") in REPLY_FORMATS,
                     f"models.{model}.reply must be one of {', '.join(REPLY_FORMATS)}", path)
    else:
        ports = data.get("ports") or {"port": data.get("port") or {}}
        _require(isinstance(ports, dict) and ports and not ("ports" in data and "port" in data),
                 "give either port (one serial port) or ports (name -> port)", path)
        for name, port in ports.items():
            _require(isinstance(port, dict) and "device" in port and "baudrate" in port,
                     f"{'port' if 'ports' not in data else f'ports.{name}'} needs device and baudrate", path)
        buses = dict(ports)
        for model, spec in models.items():
            for key in ("units_per_rev", "velocity_unit", "current_unit", "torque_constant", "kp_unit", "kd_unit"):
                value = spec.get(key) if isinstance(spec, dict) else None
                _require(_finite(value) and value > 0, f"models.{model}.{key} must be a finite number > 0", path)
            _require(isinstance(spec.get("fast_sync_read", False), bool),
                     f"models.{model}.fast_sync_read must be true or false", path)
            for key, (lo, hi) in (("shutdown", (0, 255)), ("temperature_limit_c", (0, 100)), ("pwm_limit", (0, 885))):
                value = spec.get(key, lo)
                _require(_integer(value) and lo <= value <= hi,
                         f"models.{model}.{key} = {value!r} must be an integer in [{lo}, {hi}]", path)
    timeout = data.get("reply_timeout_s", BusConfig.reply_timeout)
    _require(_finite(timeout) and 1e-4 <= timeout <= 1.0,
             f"reply_timeout_s = {timeout!r} is outside the allowed range [0.0001, 1] s", path)
    missed = data.get("max_missed_replies", BusConfig.max_missed_replies)
    _require(_integer(missed) and 0 <= missed <= 1000,
             f"max_missed_replies = {missed!r} is outside the allowed range [0, 1000]", path)
    stale_check = data.get("stale_check_every", BusConfig.stale_check_every)
    _require(_integer(stale_check) and 0 <= stale_check <= 10000,
             f"stale_check_every = {stale_check!r} is outside the allowed range [0, 10000] ticks", path)
    drive_timeout = data.get("drive_timeout_s", BusConfig.drive_timeout)
    _require(_finite(drive_timeout) and 0.001 <= drive_timeout <= 10.0,
             f"drive_timeout_s = {drive_timeout!r} is outside the allowed range [0.001, 10] s", path)
    sensors = data.get("body_sensors")
    _require(sensors is None or (isinstance(sensors, str) and re.fullmatch(r"[A-Za-z_][\w.]*:[A-Za-z_]\w*", sensors)),
             f"body_sensors = {sensors!r} must be module:function (a Python module on the path and its function)",
             path)
    acknowledged = data.get("without_drive_timeout")
    _require(acknowledged is None or (isinstance(acknowledged, dict) and set(acknowledged) == {"why", "joints"}
                                      and isinstance(acknowledged["why"], str) and len(acknowledged["why"].split()) >= 3
                                      and isinstance(acknowledged["joints"], list)
                                      and all(isinstance(j, str) for j in acknowledged["joints"])),
             "without_drive_timeout must give why (in a few words) drives without a command timeout may be enabled, "
             "and joints: the list of those drives' joints", path)
    if acknowledged is not None:
        unknown = [j for j in acknowledged["joints"] if j not in joint_names]
        _require(not unknown, f"without_drive_timeout.joints are not in the robot: {unknown}", path)
        acknowledged = DriveTimeoutWaiver(acknowledged["why"], tuple(acknowledged["joints"]))
    joints = data.get("joints") or {}
    _require(isinstance(joints, dict), "joints must map joint names to motors", path)
    missing = [j for j in joint_names if j not in joints]
    extra = [j for j in joints if j not in joint_names]
    _require(not missing, f"joints missing from the mapping: {missing}", path)
    _require(not extra, f"joints not in the robot: {extra}", path)
    motors = []
    seen = set()
    for joint in joint_names:
        entry = joints[joint]
        _require(isinstance(entry, dict), f"joints.{joint} must be a mapping", path)
        bus = entry.get("bus", "port")
        _require(bus in buses, f"joints.{joint}.bus {bus!r} is not one of {sorted(buses)}", path)
        motor_id = entry.get("id")
        limit = 127 if backend == "mit_can" else 252
        _require(isinstance(motor_id, int) and not isinstance(motor_id, bool) and 1 <= motor_id <= limit,
                 f"joints.{joint}.id must be an integer in [1, {limit}]", path)
        _require((bus, motor_id) not in seen, f"joints.{joint}: id {motor_id} is used twice on bus {bus}", path)
        seen.add((bus, motor_id))
        model = entry.get("model")
        _require(model in models, f"joints.{joint}.model {model!r} is not one of {sorted(models)}", path)
        direction = entry.get("direction", 1)
        _require(not isinstance(direction, bool) and direction in (1, -1), f"joints.{joint}.direction must be 1 or -1",
                 path)
        zero = entry.get("zero_offset", 0.0)
        _require(_finite(zero), f"joints.{joint}.zero_offset must be a finite number [rad]", path)
        gear = entry.get("gear_ratio", 1.0)
        _require(_finite(gear) and GEAR_RATIO[0] <= gear <= GEAR_RATIO[1],
                 f"joints.{joint}.gear_ratio must be a number in [{GEAR_RATIO[0]:g}, {GEAR_RATIO[1]:g}]", path)
        motors.append(MotorMap(joint, bus, motor_id, model, int(direction), float(zero), float(gear)))
    config = BusConfig(backend, buses, models, tuple(motors), path, float(timeout), missed, stale_check,
                       float(drive_timeout), sensors, acknowledged)
    if backend == "mit_can":
        formats: dict[str, tuple[str, str]] = {}
        for m in motors:
            fmt = config.reply_format(m)
            first = formats.setdefault(m.bus, (fmt, m.joint))
            _require(first[0] == fmt, f"joints.{m.joint}: bus {m.bus} mixes reply formats ({first[1]} is {first[0]}, "
                     f"{m.joint} is {fmt}); give each drive family a bus of its own", path)
            _require(fmt != "damiao" or m.id <= 15, f"joints.{m.joint}.id must be in [1, 15] for a Damiao drive", path)
    return config
