"""DynamixelBackend: joints driven by Dynamixel servos (Protocol 2.0, X-series control table)
through ``dynamixel_sdk``.

The servos may be split over several serial ports (the bus config's ``ports``; ``DynamixelPort``),
whose transactions run side by side. Per tick, on each port: a Sync Write of Goal Position, a Sync
Write of the position D/I/P gains when they changed (clipped to the register range, ``GAIN_MAX``),
and one Sync Read (a Fast Sync Read where every servo of the port has a model with
``fast_sync_read: true``, checked at ``configure``) of present current, velocity, position and
temperature; every ``ERROR_CHECK_TICKS`` ticks, a Sync Read of
each servo's Hardware Error Status and Bus Watchdog: a servo shut down by an error (overload,
overheating...) or whose watchdog expired (it then ignores goals) fails the write, naming it.
``configure`` (torque off, so the EEPROM takes writes) puts every servo in current-based position
mode (Operating Mode 5: the position PID outputs a motor current, so the gains act on torque, not on
PWM), with return delay 0 and no motion profile (the goal is taken at once), and writes its
protective limits (``_protection``: Shutdown, Temperature Limit, PWM Limit and the joint's Velocity
Limit), each read back: a servo that refuses (a model without mode 5) fails the configuration,
naming its joint.
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
failed Sync Read keeps the previous values and timestamp (``missing_replies`` counts it); more than
the config's ``max_missed_replies`` in a row fail the read, naming the port (a fault, as a silent
MIT motor).

Fresh answers or none (``DynamixelPort``: what Protocol 2.0 carries and how the SDK matches): a
status packet a Sync Read passed over names a servo that answered twice (a duplicate, or another
node sending with its id: a spoof) and neither answer is taken: the servo keeps its last values
(``duplicate_replies``). Status packets waiting before a tick's first instruction came with nothing
asked (later than their wait, or a second answer after the last one taken): ``late_replies``, bytes
that make no status packet of a servo on the port ``foreign_frames``. A servo found answering unasked
in ``UNASKED_TICKS_TO_FAULT`` ticks in a row fails the write, naming it (one may be a glitch).
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numpy as np

from robot_ctrl.buses import dynamixel_protocol as dxl
from robot_ctrl.buses.bus_config import BusConfig
from robot_ctrl.buses.dynamixel_port import DynamixelPort
from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.types import JointCommand, JointState

#: A servo found answering unasked in this many ticks in a row is a fault (one may be a glitch).
UNASKED_TICKS_TO_FAULT = 2
ERROR_CHECK_TICKS = 40  # [ticks] between reads of the Hardware Error Status and the Bus Watchdog
#: [°C] above the safety layer's fault temperature (80 °C): the layer's damping acts first, the
#: servo's own shutdown is the backstop.
DEFAULT_TEMPERATURE_LIMIT = 85


class DynamixelBackend(HardwareAdapter):
    def __init__(self, config: BusConfig, kd_damping: np.ndarray, body_sensors: Callable[[], JointState] | None = None,
                 watchdog_ms: float = 100.0, clock: Callable[[], float] = time.monotonic,
                 effort: np.ndarray | None = None, velocity: np.ndarray | None = None):
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
        self.units = dxl.RegisterUnits.of(config)
        self.effort = None if effort is None else np.asarray(effort, dtype=float)  # [N·m] joint side
        self.velocity = None if velocity is None else np.asarray(velocity, dtype=float)  # [rad/s] joint side
        self.goal_current: np.ndarray | None = None  # registers written at activation
        fast = [bool(config.models[m.model].get("fast_sync_read", False)) for m in config.motors]
        self.ports = [DynamixelPort(name, options, [(i, m) for i, m in enumerate(config.motors) if m.bus == name],
                                    fast=all(f for f, m in zip(fast, config.motors) if m.bus == name))
                      for name, options in config.buses.items()]
        self.ports = [port for port in self.ports if port.motors]
        self._port_of = {m.bus: port for port in self.ports for m in port.motors}
        self._pool: ThreadPoolExecutor | None = None  # the ports' transactions side by side
        self._p = np.zeros(self.nj)  # motor side
        self._v = np.zeros(self.nj)
        self._t = np.zeros(self.nj)
        self._temperature = np.zeros(self.nj)
        self._gains: tuple | None = None
        self._time = None
        self._t0 = 0.0
        self._body: JointState | None = None
        self._open = False
        self._ticks = 0
        self._missed_reads = 0  # Sync Reads in a row that a servo did not answer
        self._unasked = np.zeros(self.nj, dtype=bool)  # the servo answered unasked since the last tick
        self._unasked_ticks = np.zeros(self.nj, dtype=int)  # ticks in a row in which it did

    @property
    def drive_timeout_joints(self) -> tuple[str, ...]:
        """Every servo: its Bus Watchdog, armed at activation, stops it when goals stop coming."""
        return tuple(m.joint for m in self.config.motors)

    # Lifecycle hooks ------------------------------------------------------------------------------
    def _on_configure(self) -> None:
        self._t0 = self.clock()  # the state's time counts from here
        self._pool = ThreadPoolExecutor(len(self.ports), thread_name_prefix="dynamixel-port")
        for port in self.ports:
            port.open()
            port.check_fast_sync_read()
        self._open = True  # damping can be sent from here on
        self._sync_read()
        if self._time is None:
            raise OSError(f"no answer from the servos on {', '.join(p.device for p in self.ports)}")
        current_limit = []
        for i, m in enumerate(self.config.motors):  # torque is off: the EEPROM can be written
            port = self._port_of[m.bus]
            port.set(m, dxl.RETURN_DELAY_TIME, 0, 1)
            port.set(m, dxl.OPERATING_MODE, dxl.CURRENT_BASED_POSITION, 1)
            for address, value in self._protection(i).items():
                port.set(m, address, value, dxl.PROTECTIVE_LIMITS[address])
            port.set(m, dxl.PROFILE_ACCELERATION, 0, 4)
            port.set(m, dxl.PROFILE_VELOCITY, 0, 4)
            current_limit.append(port.read(m, dxl.CURRENT_LIMIT, 2))
        limit = np.array(current_limit)
        if self.effort is not None:
            wanted = np.ceil(self.effort / self.config.gear / self.units.torque).astype(int)
            limit = np.minimum(wanted, limit)
        self.goal_current = limit

    def _protection(self, i: int) -> dict[int, int]:
        """Servo ``i``'s protective limits (register: value) from its model in the bus config: the
        hardware errors that switch its torque off, its temperature and PWM limits, and its velocity
        limit from the joint's (where the robot's velocity limits were given)."""
        model = self.config.models[self.config.motors[i].model]
        limits = {dxl.SHUTDOWN: int(model.get("shutdown", dxl.SHUTDOWN_DEFAULT)),
                  dxl.TEMPERATURE_LIMIT: int(model.get("temperature_limit_c", DEFAULT_TEMPERATURE_LIMIT)),
                  dxl.PWM_LIMIT: int(model.get("pwm_limit", dxl.PWM_MAX))}
        if self.velocity is not None:
            limits[dxl.VELOCITY_LIMIT] = int(np.ceil(self.velocity[i] * self.config.gear[i] / self.units.velocity[i]))
        return limits

    def _each_port(self, call) -> list:
        """``call(port)`` on every port, side by side; the results in port order. A port that fails
        does not stop the others: every call runs to its end, then the failures raise together."""
        futures = [self._pool.submit(call, port) for port in self.ports]
        results, failed = [], []
        for port, future in zip(self.ports, futures):
            try:
                results.append(future.result())
            except Exception as exc:  # the SDK's and the OS's errors alike: reported, not lost
                failed.append(f"{port.device} ({port.name}): {exc}")
        if failed:
            raise RuntimeError("; ".join(failed))
        return results

    def _on_activate(self) -> None:
        self._check_servos(watchdog=False)
        self._gains = None
        self._on_estop()  # P = 0, D = damping, goal = present position: torque comes on soft, in place
        for m, current in zip(self.config.motors, self.goal_current):
            self._port_of[m.bus].set(m, dxl.GOAL_CURRENT, int(current), 2)  # the servo's torque limit
        for m in self.config.motors:
            port = self._port_of[m.bus]
            port.write(m, dxl.BUS_WATCHDOG, 0, 1)  # clears a tripped watchdog
            port.write(m, dxl.TORQUE_ENABLE, 1, 1)
            port.set(m, dxl.BUS_WATCHDOG, self.watchdog_units, 1)  # read back: a dead host leaves it stopped in place
        self._sync_read()
        self._ticks = 0
        self._unasked[:], self._unasked_ticks[:] = False, 0  # what the lifecycle's own reads left

    def _on_deactivate(self) -> None:
        """Torque off on every servo of every port, whatever fails on another."""
        self._each_port(lambda port: port.torque_off())

    def _on_disable(self) -> None:
        self._on_deactivate()

    def _on_estop(self) -> None:
        if not self._open:
            return
        zero = np.zeros(self.nj)
        q, _, _ = self.config.to_joint(self._p, self._v, self._t)
        self._send(JointCommand(q=q, dq=zero, kp=zero, kd=self.kd_damping, tau_ff=zero))

    def _on_close(self) -> None:
        for port in self.ports:
            port.close()
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        self._open = False

    # Read / write ---------------------------------------------------------------------------------
    def _write(self, cmd: JointCommand) -> None:
        self._send(cmd)
        self._unasked_ticks = np.where(self._unasked, self._unasked_ticks + 1, 0)
        self._unasked[:] = False
        stale = self._unasked_ticks >= UNASKED_TICKS_TO_FAULT
        if stale.any():
            joints = ", ".join(self.config.motors[i].joint for i in np.flatnonzero(stale))
            raise RuntimeError(f"{joints} answered unasked (late, twice or spoofed) in {UNASKED_TICKS_TO_FAULT} ticks in a "
                               "row: the state they report cannot be trusted")
        self._ticks += 1
        if self._ticks % ERROR_CHECK_TICKS == 0:
            self._check_servos()

    def _check_servos(self, watchdog: bool = True) -> None:
        """Raise, naming the joints, if a servo reports a hardware error or (``watchdog``) an
        expired bus watchdog."""
        problems = []
        for address in (dxl.HARDWARE_ERROR_STATUS, dxl.BUS_WATCHDOG):
            if address == dxl.BUS_WATCHDOG and not watchdog:
                continue
            for port, values in zip(self.ports, self._each_port(lambda port: port.read_status(address))):
                for m, value in zip(port.motors, values):
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
        """The command's gains (when they changed) and goals on every port, a port's failure not
        keeping them from the others."""
        p, v, kp, kd, t = self.config.to_motor(cmd.q, cmd.dq, cmd.kp, cmd.kd, cmd.tau_ff)
        kp_reg = np.clip(np.round(kp / self.units.kp), 0, dxl.GAIN_MAX).astype(int)
        kd_reg = np.clip(np.round(kd / self.units.kd), 0, dxl.GAIN_MAX).astype(int)
        gains = (tuple(kp_reg), tuple(kd_reg))
        kp_q = kp_reg * self.units.kp
        # Feedforward folded into the goal (see the module docstring); without stiffness, hold the goal.
        goal = np.where(kp_q > 0, p + (t + kd_reg * self.units.kd * v) / np.where(kp_q > 0, kp_q, 1.0), self._p)
        raw = np.round(goal / self.units.position).astype(np.int64)
        new_gains = gains != self._gains

        def send(port: DynamixelPort) -> list[int | None]:
            queued = port.take_queued()  # before the SDK's next instruction clears them unseen
            if new_gains:
                port.write_gains(kp_reg, kd_reg)
            port.write_goals(raw)
            return queued

        self._gains = None  # unknown until every port has taken them
        queued = self._each_port(send)
        self._gains = gains
        for port, ids in zip(self.ports, queued):
            self.late_replies += len(self._answered_unasked(port, ids))

    def _answered_unasked(self, port: DynamixelPort, ids: list[int | None]) -> list[int]:
        """The joints of ``port`` whose servos sent the status packets ``ids`` unasked, marked for
        the fault count; what names no servo of the port is counted foreign."""
        joints = [port.joint_index(servo) for servo in ids]
        self.foreign_frames += sum(i is None for i in joints)
        joints = [i for i in joints if i is not None]
        self._unasked[joints] = True
        return joints

    def _sync_read(self) -> None:
        """Every port's present state; if a servo did not answer, the previous values and time stay."""
        answers = self._each_port(lambda port: port.read_present())
        if any(a is None for a in answers):
            self.missing_replies += 1
            self._missed_reads += 1
            if self._missed_reads > self.config.max_missed_replies:
                silent = ", ".join(f"{p.device} ({p.name})" for p, a in zip(self.ports, answers) if a is None)
                raise RuntimeError(f"no status from the servos on {silent} for {self._missed_reads} reads in a row")
            return
        self._missed_reads = 0
        for port, registers in zip(self.ports, answers):
            doubted = self._answered_unasked(port, port.last_skipped)
            self.duplicate_replies += len(doubted)
            taken = [k for k, i in enumerate(port.index) if i not in doubted]  # a doubted servo keeps its last values
            i = [port.index[k] for k in taken]
            current, velocity, position, temperature = registers[taken].T
            self._temperature[i] = temperature
            self._t[i] = current * self.units.torque[i]
            self._v[i] = velocity * self.units.velocity[i]
            self._p[i] = position * self.units.position[i]
        self._body = self.body_sensors() if self.body_sensors is not None else None
        self._time = self._body.t if self._body is not None else self.clock() - self._t0
