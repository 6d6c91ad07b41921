"""MitCanEmulator: MIT-style CAN motors emulated on python-can buses, backed by a simulated robot.

Each emulated motor listens on its bus for its CAN id and answers every frame with a reply in its
model's format (``mit6``, ``cubemars`` or ``damiao``, see ``mit_protocol``), as the real drives do. Commands are decoded with the same protocol code a real motor would
have to match, converted to the joint side with the bus config and, once every motor has received
its command for the tick, applied together to the ``plant`` (any HardwareAdapter, normally the
MuJoCo backend: hardware in the loop), which advances one control period. Lock-step: each motor
answers its command after that step, with the state after it. With ``period`` (free-running, as
real drives are: ``robot-ctrl hw emulate``, where the controller is another process on the wall
clock), the plant advances every ``period`` of wall-clock time with the commands the drives hold,
from the first command on, whether or not a controller still sends (until then the robot stands
still, as on a hanger), and each motor answers a command at once with the state of that instant. A disabled motor (after 0xFD, before 0xFC) is limp: kp = kd = τ = 0.

Every decoded command is kept in ``received`` (joint side, with the plant time; lock-step only) so
tests can check what actually crossed the bus. Fault injection: with ``drop_replies`` set, the motors still act on
commands but stop answering (a broken reply path); motors whose index is in ``silent`` never answer
(unpowered, or a wrong CAN id); each other reply is lost with probability ``drop_probability``
(a noisy bus; seeded); ``faults`` maps a motor's index to the fault code (CubeMars) or status
(Damiao) its replies report. Damiao drives keep their registers (``registers``, read and written
over the bus) and disable themselves when no command came for their TIMEOUT register's time (wall
clock, checked on silence too), reporting status 13 until enabled again, as a drive whose host
died. ``body_state()`` gives the plant's last full state, standing in for the robot's IMU and force
sensors, which are not on the motor buses; ``drive_status()`` what each drive is doing now (for
``robot-ctrl hw emulate --status``, whose drives serve another process).
"""

from __future__ import annotations

import select
import threading
import time

import can
import numpy as np

from robot_ctrl.buses.bus_config import BusConfig
from robot_ctrl.buses.drive_status import drive_entry
from robot_ctrl.buses.mit_protocol import (
    DISABLE,
    ENABLE,
    HOST_ID,
    PARAM_CAN_ID,
    PARAM_WRITE,
    SET_ZERO,
    TIMEOUT_REGISTER,
    TIMEOUT_UNIT,
    MitRanges,
    pack_reply,
    param_frame,
    unpack_command,
    unpack_param,
)
from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.types import JointCommand, JointState

LOST = 13  # Damiao status: communication lost (its CAN timeout expired)
AMBIENT = 30.0  # [°C] the temperature an emulated drive reports when the plant has none
SILENCE_CHECK = 0.01  # [s] how often a silent bus's drives look at their timeouts


class MitCanEmulator:
    def __init__(self, config: BusConfig, plant: HardwareAdapter, period: float | None = None):
        if config.backend != "mit_can":
            raise ValueError(f"{config.path.name} is a {config.backend!r} config, not mit_can")
        self.config = config
        self.plant = plant
        self.nj = len(config.motors)
        self.ranges = [MitRanges.from_dict(config.models[m.model]) for m in config.motors]
        self.formats = [config.reply_format(m) for m in config.motors]
        self.faults: dict[int, int] = {}
        self.registers: list[dict[int, int]] = [{} for _ in config.motors]
        self._last_command = np.full(self.nj, np.nan)  # [s] wall clock of each motor's last frame
        self._index = {(m.bus, m.id): i for i, m in enumerate(config.motors)}
        self.enabled = np.zeros(self.nj, dtype=bool)
        self.kp = np.zeros(self.nj)  # the gains of each motor's last command, motor side, as it acts on them
        self.kd = np.zeros(self.nj)
        self.encoder_zero = np.zeros(self.nj)  # set by the set-zero frame [rad, motor side]
        self.received: list[tuple[float, JointCommand]] = []
        self.drop_replies = False
        self.silent: set[int] = set()
        self.drop_probability = 0.0
        self._rng = np.random.default_rng(0)
        self.period = period
        self._pending: list[tuple[float, float, float, float, float] | None] = [None] * self.nj
        self._held: list[tuple[float, float, float, float, float] | None] = [None] * self.nj  # free-running
        self._lock = threading.Lock()
        self._state: JointState | None = None
        self._buses: dict[str, can.BusABC] = {}
        self._threads: list[threading.Thread] = []
        self._running = threading.Event()

    def start(self) -> None:
        """Bring the plant up (configure, activate) and start listening on every bus: a thread per
        bus in lock-step, one thread for every bus and the plant when free-running (fewer hand-overs
        of the interpreter lock: each answer goes out sooner)."""
        self.plant.configure()
        self.plant.activate()
        self._state = self.plant.read()
        self._running.set()
        for name, options in self.config.buses.items():
            self._buses[name] = can.Bus(**options)
        if self.period is None:
            self._threads = [threading.Thread(target=self._serve, args=(name, bus), name=f"mit-emulator-{name}",
                                              daemon=True) for name, bus in self._buses.items()]
        else:
            self._threads = [threading.Thread(target=self._run_free, name="mit-emulator", daemon=True)]
        for thread in self._threads:
            thread.start()

    def close(self) -> None:
        self._running.clear()
        for thread in self._threads:
            thread.join()
        for bus in self._buses.values():
            bus.shutdown()
        self._threads.clear()
        self._buses.clear()
        self.plant.close()

    def body_state(self) -> JointState:
        with self._lock:
            return self._state

    def drive_status(self) -> dict[str, dict]:
        """Per joint: enabled, the stiffness and damping it acts with (joint side: 0 when disabled) and
        the wall-clock time since its last frame (None before the first)."""
        now, g2 = time.monotonic(), self.config.gear**2
        with self._lock:
            return {m.joint: drive_entry(bool(self.enabled[i]), self.enabled[i] * self.kp[i] * g2[i],
                                         self.enabled[i] * self.kd[i] * g2[i], now - self._last_command[i])
                    for i, m in enumerate(self.config.motors)}

    def clock(self) -> float:
        """The plant's time [s]: the clock a safety layer uses in lock-step emulation, where the
        robot does not move while the controller computes."""
        with self._lock:
            return self._state.t

    # Bus side -----------------------------------------------------------------------------------
    def _serve(self, name: str, bus: can.BusABC) -> None:
        """Lock-step: answer the frames of bus ``name``; when stopped, the frames already sent are
        still taken (a motor acts on every frame it receives, the disable sent just before a close
        included)."""
        on_bus = [i for i, m in enumerate(self.config.motors) if m.bus == name]
        while True:
            msg = bus.recv(timeout=SILENCE_CHECK if self._running.is_set() else 0.0)
            with self._lock:  # a drive's timeout acts on silence too, not only when the next frame comes
                for i in on_bus:
                    self._expire(i)
            if msg is not None:
                self._take(name, bus, msg)
            elif not self._running.is_set():
                return

    def _run_free(self) -> None:
        """Free-running: answer every bus's frames as they come, and advance the plant every
        ``period`` of wall-clock time (a period it falls behind by is skipped, not caught up) with
        the commands the drives hold, from the first command on (until then the robot stands as on a
        hanger); a drive that has had none is limp."""
        by_fd = {bus.fileno(): (name, bus) for name, bus in self._buses.items()}
        deadline = time.monotonic()
        while self._running.is_set():
            ready, _, _ = select.select(list(by_fd), [], [], min(max(deadline - time.monotonic(), 0.0), SILENCE_CHECK))
            for fd in ready:
                name, bus = by_fd[fd]
                while (msg := bus.recv(timeout=0.0)) is not None:
                    self._take(name, bus, msg)
            with self._lock:
                for i in range(self.nj):
                    self._expire(i)
                if time.monotonic() >= deadline:
                    deadline = max(deadline + self.period, time.monotonic())
                    if all(c is None for c in self._held):
                        continue  # the robot waits on its hanger for the first command
                    self._apply([c if c is not None else (self._motor_position(i), 0.0, 0.0, 0.0, 0.0)
                                 for i, c in enumerate(self._held)])
        for name, bus in self._buses.items():  # the frames sent just before a close are still taken
            while (msg := bus.recv(timeout=0.0)) is not None:
                self._take(name, bus, msg)

    def _take(self, name: str, bus: can.BusABC, msg: can.Message) -> None:
        """Act on one frame of bus ``name`` and answer it as the drive would."""
        if msg.arbitration_id == HOST_ID:
            return
        if msg.arbitration_id == PARAM_CAN_ID:
            self._register(name, bus, bytes(msg.data))
            return
        i = self._index.get((name, msg.arbitration_id))
        if i is None:
            return
        data = bytes(msg.data)
        with self._lock:
            self._last_command[i] = time.monotonic()
            if data == ENABLE:
                self.enabled[i] = True
                if self.faults.get(i) == LOST:
                    del self.faults[i]  # enabling again clears a lost communication
            elif data == DISABLE:
                self.enabled[i] = False
            elif data == SET_ZERO:
                self.encoder_zero[i] += self._motor_position(i)
            elif len(data) == 8:
                command = unpack_command(data, self.ranges[i])
                self.kp[i], self.kd[i] = command[2:4]
                if self.period is not None:
                    self._held[i] = command  # acts from the plant's next period; answered now
                else:
                    self._pending[i] = command
                    if all(c is not None for c in self._pending):
                        self._step()  # answers every motor's command with the state after the step
                    return
            self._reply(i)

    def _register(self, name: str, bus: can.BusABC, data: bytes) -> None:
        """A Damiao register read or write: answered with the register's value."""
        frame = unpack_param(data)
        i = None if frame is None else self._index.get((name, frame[0]))
        if i is None or self.formats[i] != "damiao" or i in self.silent:
            return
        motor_id, op, register, value = frame
        with self._lock:
            if op == PARAM_WRITE:
                self.registers[i][register] = value
            answer = param_frame(motor_id, op, register, self.registers[i].get(register, 0))
        bus.send(can.Message(arbitration_id=HOST_ID, data=answer, is_extended_id=False))

    def _expire(self, i: int) -> None:
        """A Damiao drive whose TIMEOUT passed since its last frame disables itself (status 13)."""
        timeout = self.registers[i].get(TIMEOUT_REGISTER, 0) * TIMEOUT_UNIT
        silent = time.monotonic() - self._last_command[i]  # NaN before the first frame: not expired
        if self.enabled[i] and self.formats[i] == "damiao" and timeout > 0 and silent > timeout:
            self.enabled[i] = False
            self.faults[i] = LOST

    def _motor_position(self, i: int) -> float:
        m = self.config.motors[i]
        return m.direction * m.gear_ratio * self._state.q[i] + m.zero_offset - self.encoder_zero[i]

    def _step(self) -> None:
        """Lock-step: the tick's commands to the plant, then every motor's answer."""
        self._apply(self._pending)
        self._pending = [None] * self.nj
        for i in range(self.nj):
            self._reply(i)

    def _apply(self, commands: list[tuple[float, float, float, float, float]]) -> None:
        """Advance the plant one control period with each motor's (p, v, kp, kd, τ), motor side; a
        disabled motor is limp."""
        p, v, kp, kd, t = (np.array(column) for column in zip(*commands))
        d, g = self.config.direction, self.config.gear
        on = self.enabled.astype(float)
        cmd = JointCommand(q=d * (p + self.encoder_zero - self.config.zero) / g, dq=d * v / g, kp=on * kp * g**2,
                           kd=on * kd * g**2, tau_ff=on * d * g * t)
        if self.period is None:  # a free-running emulator serves for hours: it keeps none
            self.received.append((self._state.t, cmd))
        self.plant.write(cmd)
        self._state = self.plant.read()

    def _reply(self, i: int) -> None:
        if self.drop_replies or i in self.silent or (self.drop_probability and self._rng.random() < self.drop_probability):
            return
        m, s = self.config.motors[i], self._state
        v = m.direction * m.gear_ratio * s.dq[i]
        tau = m.direction * s.tau[i] / m.gear_ratio
        code = self.faults.get(i)
        if code is None and self.formats[i] == "damiao" and not self.enabled[i]:
            code = 0  # a disabled Damiao drive says so
        temperature = s.temperature[i] if s.temperature is not None else AMBIENT
        data = pack_reply(m.id, self._motor_position(i), v, tau, self.ranges[i], self.formats[i], temperature, code)
        self._buses[m.bus].send(can.Message(arbitration_id=HOST_ID, data=data, is_extended_id=False))
