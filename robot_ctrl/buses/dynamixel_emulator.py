"""DynamixelEmulator: Dynamixel servos (Protocol 2.0) emulated behind a pseudo-terminal, backed by a
simulated robot.

The emulator opens a pty pair per port of the bus config and serves the servo side of the wire on
its master end; a backend (or any Dynamixel tool) opens ``port_names[port]``, the slave end, as it
would open ``/dev/ttyUSB0``. With ``link_devices``, the emulator also links each port's ``device``
in the bus config to its slave end (as socat's ``link=`` does), so another process opens the
device the config names, as it would a serial adapter; the links go with ``close``. It answers Ping, Read, Write, Sync Read, Fast Sync Read and Sync
Write for the servos of the bus config with status packets (CRC and byte stuffing as on the wire,
``dynamixel_protocol``); servos listed in ``without_fast_sync_read`` are a model or firmware
without Fast Sync Read (they add no part, so the packet never completes). ``instructions`` counts
the packets taken per instruction. Registers kept per servo:
Torque Enable, position D/I/P gains, Bus Watchdog, Goal Position, Operating Mode, Return Delay
Time, Current Limit, Goal Current and the profile; present current, velocity, position and
temperature are computed from the plant. EEPROM registers (Operating Mode, Return Delay Time,
Current Limit) refuse writes while torque is on (access error), as on a servo; servos listed in
``without_current_mode`` are a model without current-based position mode (a write of 5 is a data
range error).

Once every servo (on every port) has a new Goal Position from a Sync Write, the goals go to the
``plant`` (a HardwareAdapter, normally the MuJoCo backend: hardware in the loop), which advances
one control period; a Sync Read that comes while some servos' goals of the tick are still missing
waits for them (lock-step across ports, at most ``PENDING_WAIT``). With ``period`` (free-running,
as real servos are: ``robot-ctrl hw emulate``), the plant instead advances every ``period`` of
wall-clock time with the goals the servos hold, from the first Sync Write of goals on (until then
the robot stands still, as on a hanger), and a Sync Read answers at once with the state of that instant. Either way servo i follows ``kp_i (goal_i − q_i) − kd_i dq_i`` with kp = P × kp_unit and kd = D ×
kd_unit (joint side through the gear ratio); in current-based position mode that torque is bounded
by Goal Current at the measured state (``bound_servo_torque``); the PWM output of the other modes is
not modelled. Torque disabled: limp. A Bus Watchdog that expires
(no packet for its time, wall clock) stops the servo where it is, torque on (the goal becomes the
present position, as the X-series e-manual says: "the DYNAMIXEL will stop"); the Goal Position is
read-only (a write is refused with a range error) and the register reads −1 until the host writes 0.
``temperature`` (°C, per servo) is what Present
Temperature reports; tests raise it to exercise the safety layer. ``hardware_error`` (per servo)
is its Hardware Error Status: a servo with one set is limp and refuses torque, as after an
overload shutdown. Gains beyond the register range (``GAIN_MAX``) are ignored, as a servo ignores
an out-of-range write. Every applied command is kept in
``received`` (joint side, with the plant time; lock-step only). ``drive_status()`` says what each servo is doing now
(for ``robot-ctrl hw emulate --status``).

The emulated servos answer from threads of the host's own interpreter, while the host's port
threads busy-poll for the reply (the SDK's ``rxPacket``): at Python's default 5 ms switch interval
each of the few hand-overs of the interpreter lock an answer needs waits out a slice, replies took
up to 34 ms and missed the SDK's packet timeout (16 ms latency timer × 2 + 2 ms). While the
emulator serves, the switch interval is ``SWITCH_INTERVAL`` (answers within a few milliseconds);
``close`` restores it. A real servo answers in microseconds, whatever the host's interpreter does.
"""

from __future__ import annotations

import os
import select
import sys
import threading
import time
import tty
from collections import Counter
from pathlib import Path

import numpy as np

from robot_ctrl.buses import dynamixel_protocol as dxl
from robot_ctrl.buses.bus_config import BusConfig
from robot_ctrl.buses.drive_status import drive_entry
from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.servo_torque import bound_servo_torque
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.robot.config import ConfigError

CURRENT_LIMIT = 32767  # the emulated model's Current Limit register (its largest value)
PENDING_WAIT = 0.5  # [s] the longest a Sync Read waits for the rest of a tick's goals
WATCHDOG_CHECK = 0.01  # [s] how often a silent port's servos look at their Bus Watchdog
SWITCH_INTERVAL = 1e-4  # [s] the interpreter's thread switch interval while the emulator serves
#: address: size
EEPROM = {dxl.RETURN_DELAY_TIME: 1, dxl.OPERATING_MODE: 1, dxl.CURRENT_LIMIT: 2, **dxl.PROTECTIVE_LIMITS}
#: The protective limits' X-series defaults (address: value); stored and read back. Of them the
#: emulator acts on the temperature limit (with Shutdown's overheating bit: torque off), not on the
#: velocity and PWM limits (it models no motion profile and no PWM).
PROTECTION_DEFAULTS = {dxl.TEMPERATURE_LIMIT: 80, dxl.PWM_LIMIT: dxl.PWM_MAX, dxl.VELOCITY_LIMIT: 1023,
                       dxl.SHUTDOWN: dxl.SHUTDOWN_DEFAULT}


class DynamixelEmulator:
    def __init__(self, config: BusConfig, plant: HardwareAdapter, temperature: float = 35.0,
                 link_devices: bool = False, period: float | None = None):
        if config.backend != "dynamixel":
            raise ValueError(f"{config.path.name} is a {config.backend!r} config, not dynamixel")
        self.config = config
        self.plant = plant
        n = len(config.motors)
        self.nj = n
        self._slots = {port: {m.id: i for i, m in enumerate(config.motors) if m.bus == port} for port in config.buses}
        self.units = dxl.RegisterUnits.of(config)
        self.torque_enable = np.zeros(n, dtype=int)
        self.gains = np.zeros((n, 3), dtype=int)  # D, I, P registers
        self.watchdog = np.zeros(n, dtype=int)  # register value; −1 when it expired
        self.goal = np.zeros(n, dtype=np.int64)
        self.temperature = np.full(n, float(temperature))
        self.hardware_error = np.zeros(n, dtype=int)  # Hardware Error Status, set by tests
        self.operating_mode = np.full(n, 3)  # X-series default: position control (PWM output)
        self.return_delay = np.full(n, 250)  # [2 µs]
        self.current_limit = np.full(n, CURRENT_LIMIT)
        self.protection = {address: np.full(n, value) for address, value in PROTECTION_DEFAULTS.items()}
        self.goal_current = np.full(n, CURRENT_LIMIT)
        self.profile = np.zeros((n, 2), dtype=np.int64)  # acceleration, velocity
        self.without_current_mode: set[int] = set()
        self.without_fast_sync_read: set[int] = set()
        self.instructions: Counter[int] = Counter()  # packets taken, per instruction
        self.received: list[tuple[float, JointCommand]] = []
        self._lock = threading.Lock()
        self._state: JointState | None = None
        self._last_packet = time.monotonic()
        self._last_command = np.full(n, np.nan)  # [s] wall clock of each servo's last write or goal
        self._fresh_goal = np.zeros(n, dtype=bool)  # a goal of this tick has come
        self._stepped = threading.Condition(self._lock)
        self._switch_interval: float | None = None  # the interpreter's own, while serving
        self._running = threading.Event()
        self._threads: list[threading.Thread] = []
        self._fds: list[int] = []
        self.port_names: dict[str, str] = {}
        self.link_devices = link_devices
        self.period = period
        self._links: list[Path] = []

    def start(self) -> None:
        """Bring the plant up (configure, activate), open a pty per port and serve them."""
        self.plant.configure()
        self.plant.activate()
        self._state = self.plant.read()
        self.goal[:] = np.round(self._motor_position() / self.units.position)
        self._running.set()
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch_interval, SWITCH_INTERVAL))
        for name in self.config.buses:
            master, slave = os.openpty()
            tty.setraw(slave)
            self.port_names[name] = os.ttyname(slave)
            self._fds += [master, slave]
            if self.link_devices:
                self._link(Path(self.config.buses[name]["device"]), self.port_names[name])
            thread = threading.Thread(target=self._serve, args=(name, master), name=f"dynamixel-emulator-{name}",
                                      daemon=True)
            thread.start()
            self._threads.append(thread)
        if self.period is not None:
            thread = threading.Thread(target=self._run_plant, name="dynamixel-emulator-plant", daemon=True)
            thread.start()
            self._threads.append(thread)

    def close(self) -> None:
        self._running.clear()
        for thread in self._threads:
            thread.join()
        for fd in self._fds:
            os.close(fd)
        for link in self._links:
            link.unlink(missing_ok=True)
        self._threads.clear()
        self._fds.clear()
        self._links.clear()
        if self._switch_interval is not None:
            sys.setswitchinterval(self._switch_interval)
            self._switch_interval = None
        self.plant.close()

    def body_state(self) -> JointState:
        with self._lock:
            return self._state

    def drive_status(self) -> dict[str, dict]:
        """Per joint: torque on, the stiffness and damping it acts with (joint side: 0 with torque off),
        the wall-clock time since its last write or goal, and whether its Bus Watchdog stopped it."""
        now, g2 = time.monotonic(), self.config.gear**2
        with self._lock:
            on = (self.torque_enable != 0) & (self.hardware_error == 0)
            kp, kd = on * self.gains[:, 2] * self.units.kp * g2, on * self.gains[:, 0] * self.units.kd * g2
            return {m.joint: drive_entry(bool(on[i]), kp[i], kd[i], now - self._last_command[i],
                                         stopped=bool(self.watchdog[i] < 0))
                    for i, m in enumerate(self.config.motors)}

    def _link(self, device: Path, slave: str) -> None:
        """Link ``device`` to the pty ``slave``; a link left by an emulator that is gone (its pty
        closed) is replaced, anything else there is refused."""
        if device.is_symlink() and not device.exists():
            device.unlink()
        if device.exists() or device.is_symlink():
            raise ConfigError(f"{self.config.path.name}: {device} is already there (another emulator, or a real "
                              "device): give this port a device path of its own")
        device.symlink_to(slave)
        self._links.append(device)

    def clock(self) -> float:
        """The plant's time [s] (the safety layer's clock in lock-step emulation)."""
        with self._lock:
            return self._state.t

    # Wire side ------------------------------------------------------------------------------------
    def _serve(self, port: str, master: int) -> None:
        buffer = bytearray()
        while self._running.is_set():
            ready, _, _ = select.select([master], [], [], WATCHDOG_CHECK)
            self._check_watchdog()
            if not ready:
                continue
            buffer += os.read(master, 4096)
            while (pkt := dxl.parse(buffer)) is not None:
                self._last_packet = time.monotonic()
                with self._lock:
                    reply = self._handle(port, *pkt)
                if reply:
                    os.write(master, reply)

    def _check_watchdog(self) -> None:
        silent_ms = (time.monotonic() - self._last_packet) * 1e3
        with self._lock:
            expired = (self.watchdog > 0) & (silent_ms > 20.0 * self.watchdog)
            self.watchdog[expired] = -1
            self.goal[expired] = np.round(self._motor_position()[expired] / self.units.position[expired])

    def _handle(self, port: str, servo: int, instruction: int, params: bytes) -> bytes:
        """Answer one packet on ``port`` (called with the lock held)."""
        slot = self._slots[port]
        self.instructions[instruction] += 1
        if instruction == dxl.INST_SYNC_WRITE:
            address, length = int.from_bytes(params[0:2], "little"), int.from_bytes(params[2:4], "little")
            for k in range(4, len(params), 1 + length):
                i = slot.get(params[k])
                if i is not None:
                    self._store(i, address, params[k + 1 : k + 1 + length])
                    self._last_command[i] = time.monotonic()
                    self._fresh_goal[i] |= address == dxl.GOAL_POSITION
            if self._fresh_goal.all() and self.period is None:
                self._fresh_goal[:] = False
                self._step()
                self._stepped.notify_all()
            return b""
        if instruction in (dxl.INST_SYNC_READ, dxl.INST_FAST_SYNC_READ):
            if self._fresh_goal.any() and self.period is None:  # another port's goals of this tick are coming
                self._stepped.wait_for(lambda: not self._fresh_goal.any(), timeout=PENDING_WAIT)
            address, length = int.from_bytes(params[0:2], "little"), int.from_bytes(params[2:4], "little")
            asked = [t for t in params[4:] if t in slot]
            if instruction == dxl.INST_SYNC_READ:
                return b"".join(dxl.status(t, self._load(slot[t], address, length)) for t in asked)
            if any(slot[t] in self.without_fast_sync_read for t in asked) or len(asked) < len(params) - 4:
                return b""  # a servo that does not add its part breaks the one packet
            return dxl.fast_sync_status([(t, self._load(slot[t], address, length), 0) for t in asked])
        if servo not in slot:
            return b""
        i = slot[servo]
        if instruction == dxl.INST_PING:
            return dxl.status(servo, bytes([0x06, 0x04, 0x2D]))  # model 1030 (XM430-W350), firmware 45
        if instruction == dxl.INST_WRITE:
            self._last_command[i] = time.monotonic()
            return dxl.status(servo, error=self._store(i, int.from_bytes(params[0:2], "little"), params[2:]))
        if instruction == dxl.INST_READ:
            address, length = int.from_bytes(params[0:2], "little"), int.from_bytes(params[2:4], "little")
            return dxl.status(servo, self._load(i, address, length))
        return dxl.status(servo, error=0x02)  # instruction error

    def _store(self, i: int, address: int, data: bytes) -> int:
        """Write a register; the status error (0 when taken)."""
        value = int.from_bytes(data, "little")
        if address in EEPROM:
            if self.torque_enable[i]:
                return dxl.ACCESS_ERROR
            if address == dxl.OPERATING_MODE:
                if value == dxl.CURRENT_BASED_POSITION and i in self.without_current_mode:
                    return dxl.DATA_RANGE_ERROR
                self.operating_mode[i] = value
            elif address == dxl.RETURN_DELAY_TIME:
                self.return_delay[i] = value
            elif address in self.protection:
                self.protection[address][i] = value
            else:
                self.current_limit[i] = value
            return 0
        if address == dxl.GOAL_CURRENT and len(data) == 2:
            if value > self.current_limit[i]:
                return dxl.DATA_RANGE_ERROR
            self.goal_current[i] = value
        elif address in (dxl.PROFILE_ACCELERATION, dxl.PROFILE_VELOCITY) and len(data) == 4:
            self.profile[i, address == dxl.PROFILE_VELOCITY] = value
        elif address == dxl.TORQUE_ENABLE:
            self.torque_enable[i] = data[0] if not self.hardware_error[i] else 0  # shut down until a reboot
        elif address == dxl.GAINS and len(data) == 6:
            gains = [int.from_bytes(data[k : k + 2], "little") for k in (0, 2, 4)]
            if max(gains) <= dxl.GAIN_MAX:  # out of range: ignored, as a servo does
                self.gains[i] = gains
        elif address == dxl.BUS_WATCHDOG:
            self.watchdog[i] = dxl.to_signed(data[0], 1)
        elif address == dxl.GOAL_POSITION and len(data) == 4:
            if self.watchdog[i] < 0:  # stopped by its bus watchdog: the goal is read-only
                return dxl.DATA_RANGE_ERROR
            self.goal[i] = dxl.to_signed(int.from_bytes(data, "little"), 4)
        return 0

    def _load(self, i: int, address: int, length: int) -> bytes:
        """Servo i's control table from ``address``, ``length`` bytes; only the registers that range
        covers are computed (a tick's Sync Read asks for the present state of every servo)."""
        table = bytearray(256)

        def put(register: int, size: int, value) -> None:
            if register < address + length and address < register + size:
                table[register : register + size] = dxl.to_bytes(int(value()), size)

        put(dxl.RETURN_DELAY_TIME, 1, lambda: self.return_delay[i])
        put(dxl.OPERATING_MODE, 1, lambda: self.operating_mode[i])
        put(dxl.CURRENT_LIMIT, 2, lambda: self.current_limit[i])
        put(dxl.GOAL_CURRENT, 2, lambda: self.goal_current[i])
        put(dxl.PROFILE_ACCELERATION, 4, lambda: self.profile[i, 0])
        put(dxl.PROFILE_VELOCITY, 4, lambda: self.profile[i, 1])
        for register, values in self.protection.items():
            put(register, EEPROM[register], lambda: values[i])
        put(dxl.TORQUE_ENABLE, 1, lambda: self.torque_enable[i])
        put(dxl.HARDWARE_ERROR_STATUS, 1, lambda: self.hardware_error[i])
        for k in range(3):
            put(dxl.GAINS + 2 * k, 2, lambda: self.gains[i, k])
        put(dxl.BUS_WATCHDOG, 1, lambda: self.watchdog[i] & 0xFF)
        put(dxl.GOAL_POSITION, 4, lambda: self.goal[i])
        m, s = self.config.motors[i], self._state
        put(dxl.PRESENT, 2, lambda: round(m.direction * s.tau[i] / m.gear_ratio / self.units.torque[i]))
        put(dxl.PRESENT + 2, 4, lambda: round(m.direction * m.gear_ratio * s.dq[i] / self.units.velocity[i]))
        put(dxl.PRESENT + 6, 4, lambda: round((m.direction * m.gear_ratio * s.q[i] + m.zero_offset)
                                              / self.units.position[i]))
        put(dxl.PRESENT + dxl.TEMPERATURE_OFFSET, 1, lambda: min(max(round(float(self.temperature[i])), 0), 255))
        return bytes(table[address : address + length])

    def _motor_position(self) -> np.ndarray:
        c = self.config
        return c.direction * c.gear * self._state.q + c.zero

    def _run_plant(self) -> None:
        """Free-running: the plant advances every ``period`` of wall-clock time (a period it falls
        behind by is skipped) with the goals and gains the servos hold, from the first Sync Write of
        goals on (until then the robot stands still, as on a hanger)."""
        deadline = time.monotonic()
        while self._running.is_set():
            deadline = max(deadline + self.period, time.monotonic())
            time.sleep(max(deadline - time.monotonic(), 0.0))
            with self._lock:
                if self._fresh_goal.any():  # the robot waits on its hanger for the first goal
                    self._step()

    def _step(self) -> None:
        c = self.config
        hot = self.temperature >= self.protection[dxl.TEMPERATURE_LIMIT]
        self.hardware_error[hot] |= dxl.OVERHEATING
        shut_down = (self.hardware_error & self.protection[dxl.SHUTDOWN]) != 0
        self.torque_enable[shut_down] = 0  # a hardware error that Shutdown names switches the torque off
        on = self.torque_enable.astype(float)
        goal = self.goal * self.units.position
        q_des, zero = c.direction * (goal - c.zero) / c.gear, np.zeros(self.nj)
        kp = on * self.gains[:, 2] * self.units.kp * c.gear**2
        kd = on * self.gains[:, 0] * self.units.kd * c.gear**2
        current_mode = self.operating_mode == dxl.CURRENT_BASED_POSITION
        limit = np.where(current_mode, self.goal_current * self.units.torque * c.gear, np.inf)  # joint side [N·m]
        s = self._state
        q_des, kp, kd, _, _ = bound_servo_torque(q_des, zero, kp, kd, zero, s.q, s.dq, limit, -np.inf, np.inf)
        cmd = JointCommand(q=q_des, dq=zero, kp=kp, kd=kd, tau_ff=zero)
        if self.period is None:  # a free-running emulator serves for hours: it keeps none
            self.received.append((self._state.t, cmd))
        self.plant.write(cmd)
        self._state = self.plant.read()
