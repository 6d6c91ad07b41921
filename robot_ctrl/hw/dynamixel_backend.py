"""DynamixelBackend: joints driven by Dynamixel servos (Protocol 2.0, X-series control table)
through ``dynamixel_sdk``.

Per tick: a Sync Write of Goal Position to every servo, a Sync Write of the position D/I/P gains
when they changed (clipped to the register range, ``GAIN_MAX``), and one Sync Read of present
current, velocity, position and temperature; every ``ERROR_CHECK_TICKS`` ticks, a Sync Read of
each servo's Hardware Error Status and Bus Watchdog: a servo shut down by an error (overload,
overheating...) or whose watchdog expired (it then ignores goals) fails the write, naming it.
``configure`` (torque off, so the EEPROM takes writes) puts every servo in current-based position
mode (Operating Mode 5: the position PID outputs a motor current, so the gains act on torque, not on
PWM), with return delay 0 and no motion profile (the goal is taken at once), each read back: a
servo that refuses (a model without mode 5) fails the configuration, naming its joint.
``activate`` refuses a servo in hardware error, writes its Goal Current (the servo's torque limit:
its joint's ``effort`` through the gear and torque constant, at most its Current Limit), P = 0,
D = ``kd_damping`` and goal = present position, then clears each servo's Bus Watchdog, enables
torque (so torque comes on soft and where the servo is) and arms the watchdog (``watchdog_ms``,
read back); ``deactivate`` disables torque; ``estop`` writes P = 0 and D = ``kd_damping`` (damping
mode).

A Dynamixel takes a position goal and gains, not a velocity or torque feedforward. The servo law
``kp (q_d − q) + kd (dq_d − dq) + τ_ff`` is kept exactly by folding the feedforward into the goal:
``goal = q_d + (τ_ff + kd dq_d) / kp`` (with kp as quantized by the gain register), the usual way to
drive a position-only servo with gravity compensation. Register units per model come from the
bus YAML (``units_per_rev``, ``velocity_unit`` [rad/s], ``current_unit`` [A], ``torque_constant``
[N·m/A], ``kp_unit`` [N·m/rad], ``kd_unit`` [N·m·s/rad]); on a real servo kp_unit and kd_unit must be
calibrated, the control table's gains are not in SI units.

Body sensors (base pose, IMU, foot forces) come from ``body_sensors`` as for the CAN backend. A
failed Sync Read keeps the previous values and timestamp (``missing_replies`` counts it): the
safety layer then sees a stale state.
"""

from __future__ import annotations

import time
from typing import Callable

import dynamixel_sdk as sdk
import numpy as np

from robot_ctrl.hw import dynamixel_protocol as dxl
from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.bus_config import BusConfig
from robot_ctrl.hw.types import JointCommand, JointState

ERROR_CHECK_TICKS = 40  # [ticks] between reads of the Hardware Error Status and the Bus Watchdog


class DynamixelBackend(HardwareAdapter):
    def __init__(self, config: BusConfig, kd_damping: np.ndarray, body_sensors: Callable[[], JointState] | None = None,
                 watchdog_ms: float = 100.0, clock: Callable[[], float] = time.monotonic,
                 effort: np.ndarray | None = None):
        if config.backend != "dynamixel":
            raise ValueError(f"{config.path.name} is a {config.backend!r} config, not dynamixel")
        if not 20.0 <= watchdog_ms <= 127 * 20.0:
            raise ValueError(f"watchdog_ms = {watchdog_ms} is outside the allowed range [20, 2540] ms")
        super().__init__(len(config.motors))
        self.config = config
        self.kd_damping = np.asarray(kd_damping, dtype=float)
        self.body_sensors = body_sensors
        self.watchdog_units = int(round(watchdog_ms / 20.0))
        self.clock = clock
        self.ids = [m.id for m in config.motors]
        self.units = dxl.RegisterUnits.of(config)
        self.effort = None if effort is None else np.asarray(effort, dtype=float)  # [N·m] joint side
        self.goal_current: np.ndarray | None = None  # registers written at activation
        self._p = np.zeros(self.nj)  # motor side
        self._v = np.zeros(self.nj)
        self._t = np.zeros(self.nj)
        self._temperature = np.zeros(self.nj)
        self._gains: tuple | None = None
        self._time = None
        self._body: JointState | None = None
        self._port = None
        self._ticks = 0

    @property
    def drive_timeout_joints(self) -> tuple[str, ...]:
        """Every servo: its Bus Watchdog, armed at activation, stops it when goals stop coming."""
        return tuple(m.joint for m in self.config.motors)

    # Lifecycle hooks ------------------------------------------------------------------------------
    def _on_configure(self) -> None:
        port = self.config.buses["port"]
        self._port = sdk.PortHandler(port["device"])
        if not self._port.openPort():
            raise OSError(f"cannot open the Dynamixel port {port['device']}")
        if not self._port.setBaudRate(int(port["baudrate"])):
            raise OSError(f"cannot set {port['device']} to {port['baudrate']} baud")
        self._packet = sdk.PacketHandler(2.0)
        self._goal = sdk.GroupSyncWrite(self._port, self._packet, dxl.GOAL_POSITION, 4)
        self._gain_write = sdk.GroupSyncWrite(self._port, self._packet, dxl.GAINS, 6)
        self._present = sdk.GroupSyncRead(self._port, self._packet, dxl.PRESENT, dxl.PRESENT_LENGTH)
        self._status = {address: sdk.GroupSyncRead(self._port, self._packet, address, 1)
                        for address in (dxl.HARDWARE_ERROR_STATUS, dxl.BUS_WATCHDOG)}
        for servo in self.ids:
            self._present.addParam(servo)
            for group in self._status.values():
                group.addParam(servo)
        self._sync_read()
        if self._time is None:
            raise OSError(f"no answer from the servos {self.ids} on {port['device']}")
        current_limit = []
        for m in self.config.motors:  # torque is off: the EEPROM can be written
            self._set(m, dxl.RETURN_DELAY_TIME, 0, 1)
            self._set(m, dxl.OPERATING_MODE, dxl.CURRENT_BASED_POSITION, 1)
            self._set(m, dxl.PROFILE_ACCELERATION, 0, 4)
            self._set(m, dxl.PROFILE_VELOCITY, 0, 4)
            current_limit.append(self._read_register(m, dxl.CURRENT_LIMIT, 2))
        limit = np.array(current_limit)
        if self.effort is not None:
            wanted = np.ceil(self.effort / self.config.gear / self.units.torque).astype(int)
            limit = np.minimum(wanted, limit)
        self.goal_current = limit

    def _set(self, motor, address: int, value: int, size: int) -> None:
        """Write a register and read it back; raise naming the joint if the servo refuses it."""
        write = {1: self._packet.write1ByteTxRx, 2: self._packet.write2ByteTxRx, 4: self._packet.write4ByteTxRx}[size]
        result, error = write(self._port, motor.id, address, value)
        if result != sdk.COMM_SUCCESS or error or self._read_register(motor, address, size) != value:
            raise OSError(f"{motor.joint} (servo {motor.id}) does not take {value} at address {address} "
                          f"({self._packet.getTxRxResult(result)}, error {error}): it needs current-based position "
                          "mode (5), return delay 0, no profile and its bus watchdog (an X-series servo)")

    def _read_register(self, motor, address: int, size: int) -> int:
        read = {1: self._packet.read1ByteTxRx, 2: self._packet.read2ByteTxRx, 4: self._packet.read4ByteTxRx}[size]
        value, result, error = read(self._port, motor.id, address)
        if result != sdk.COMM_SUCCESS or error:
            raise OSError(f"{motor.joint} (servo {motor.id}): reading address {address} failed "
                          f"({self._packet.getTxRxResult(result)}, error {error})")
        return value

    def _on_activate(self) -> None:
        self._check_servos(watchdog=False)
        self._gains = None
        self._on_estop()  # P = 0, D = damping, goal = present position: torque comes on soft, in place
        for m, current in zip(self.config.motors, self.goal_current):
            self._set(m, dxl.GOAL_CURRENT, int(current), 2)  # the servo's torque limit: its joint's effort
        for m in self.config.motors:
            self._write_byte(m.id, dxl.BUS_WATCHDOG, 0)  # clears a tripped watchdog
            self._write_byte(m.id, dxl.TORQUE_ENABLE, 1)
            self._set(m, dxl.BUS_WATCHDOG, self.watchdog_units, 1)  # read back: a dead host leaves it limp
        self._sync_read()
        self._ticks = 0

    def _on_deactivate(self) -> None:
        for servo in self.ids:
            self._write_byte(servo, dxl.TORQUE_ENABLE, 0)

    def _on_estop(self) -> None:
        if self._port is None:
            return
        zero = np.zeros(self.nj)
        q, _, _ = self.config.to_joint(self._p, self._v, self._t)
        self._send(JointCommand(q=q, dq=zero, kp=zero, kd=self.kd_damping, tau_ff=zero))

    def _on_close(self) -> None:
        if self._port is not None:
            self._port.closePort()
            self._port = None

    def _write_byte(self, servo: int, address: int, value: int) -> None:
        result, error = self._packet.write1ByteTxRx(self._port, servo, address, value)
        if result != sdk.COMM_SUCCESS or error:
            raise OSError(f"servo {servo}: writing {value} at address {address} failed "
                          f"({self._packet.getTxRxResult(result)}, error {error})")

    # Read / write ---------------------------------------------------------------------------------
    def _write(self, cmd: JointCommand) -> None:
        self._send(cmd)
        self._ticks += 1
        if self._ticks % ERROR_CHECK_TICKS == 0:
            self._check_servos()

    def _check_servos(self, watchdog: bool = True) -> None:
        """Raise, naming the joints, if a servo reports a hardware error or (``watchdog``) an
        expired bus watchdog."""
        problems = []
        for address, group in self._status.items():
            if address == dxl.BUS_WATCHDOG and not watchdog:
                continue
            self._check(group.txRxPacket(), "status sync read")
            for m, servo in zip(self.config.motors, self.ids):
                value = group.getData(servo, address, 1)
                if address == dxl.HARDWARE_ERROR_STATUS and value:
                    problems.append(f"{m.joint}: hardware error ({dxl.hardware_errors(value)}), torque off until "
                                    "the servo is rebooted")
                elif address == dxl.BUS_WATCHDOG and dxl.to_signed(value, 1) < 0:
                    problems.append(f"{m.joint}: bus watchdog expired (goals ignored): no write for "
                                    f"{self.watchdog_units * 20} ms")
        if problems:
            raise RuntimeError("; ".join(problems))

    def _read(self) -> JointState:
        self._sync_read()
        q, dq, tau = self.config.to_joint(self._p, self._v, self._t)
        fields = self._body.body_fields() if self._body is not None else {}
        return JointState(t=self._time, q=q, dq=dq, tau=tau, temperature=self._temperature.copy(), **fields)

    def _send(self, cmd: JointCommand) -> None:
        p, v, kp, kd, t = self.config.to_motor(cmd.q, cmd.dq, cmd.kp, cmd.kd, cmd.tau_ff)
        kp_reg = np.clip(np.round(kp / self.units.kp), 0, dxl.GAIN_MAX).astype(int)
        kd_reg = np.clip(np.round(kd / self.units.kd), 0, dxl.GAIN_MAX).astype(int)
        gains = (tuple(kp_reg), tuple(kd_reg))
        if gains != self._gains:
            self._gain_write.clearParam()
            for servo, d_gain, p_gain in zip(self.ids, kd_reg, kp_reg):
                self._gain_write.addParam(servo, dxl.to_bytes(d_gain, 2) + dxl.to_bytes(0, 2) + dxl.to_bytes(p_gain, 2))
            self._check(self._gain_write.txPacket(), "gain sync write")
            self._gains = gains
        kp_q = kp_reg * self.units.kp
        # Feedforward folded into the goal (see the module docstring); without stiffness, hold the goal.
        goal = np.where(kp_q > 0, p + (t + kd_reg * self.units.kd * v) / np.where(kp_q > 0, kp_q, 1.0), self._p)
        raw = np.round(goal / self.units.position).astype(np.int64)
        self._goal.clearParam()
        for servo, value in zip(self.ids, raw):
            self._goal.addParam(servo, dxl.to_bytes(int(value), 4))
        self._check(self._goal.txPacket(), "goal sync write")

    def _check(self, result: int, what: str) -> None:
        if result != sdk.COMM_SUCCESS:
            raise OSError(f"Dynamixel {what} failed: {self._packet.getTxRxResult(result)}")

    def _sync_read(self) -> None:
        if self._present.txRxPacket() != sdk.COMM_SUCCESS:
            self.missing_replies += 1
            return
        for i, servo in enumerate(self.ids):
            if not self._present.isAvailable(servo, dxl.PRESENT, dxl.PRESENT_LENGTH):
                self.missing_replies += 1
                return
        for i, servo in enumerate(self.ids):
            current = dxl.to_signed(self._present.getData(servo, dxl.PRESENT, 2), 2)
            velocity = dxl.to_signed(self._present.getData(servo, dxl.PRESENT + 2, 4), 4)
            position = dxl.to_signed(self._present.getData(servo, dxl.PRESENT + 6, 4), 4)
            self._temperature[i] = self._present.getData(servo, dxl.PRESENT + dxl.TEMPERATURE_OFFSET, 1)
            self._t[i] = current * self.units.torque[i]
            self._v[i] = velocity * self.units.velocity[i]
            self._p[i] = position * self.units.position[i]
        self._body = self.body_sensors() if self.body_sensors is not None else None
        self._time = self._body.t if self._body is not None else self.clock()
