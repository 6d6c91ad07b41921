"""MitCanEmulator: MIT-style CAN motors emulated on python-can buses, backed by a simulated robot.

Each emulated motor listens on its bus for its CAN id and answers every frame with a 6-byte
reply, as the real drives do. Commands are decoded with the same protocol code a real motor would
have to match, converted to the joint side with the bus config and, once every motor has received
its command for the tick, applied together to the ``plant`` (any HardwareAdapter, normally the
MuJoCo backend: hardware in the loop), which advances one control period. Lock-step: each motor
answers its command after that step, with the state after it (a real drive answers at once with
the state of that instant while its physics keeps running). A disabled motor (after 0xFD, before 0xFC) is limp: kp = kd = τ = 0.

Every decoded command is kept in ``received`` (joint side, with the plant time) so tests can check
what actually crossed the bus. Fault injection: with ``drop_replies`` set, the motors still act on
commands but stop answering (a broken reply path); motors whose index is in ``silent`` never answer
(unpowered, or a wrong CAN id); each other reply is lost with probability ``drop_probability``
(a noisy bus; seeded). ``body_state()`` gives the plant's last full state, standing in for
the robot's IMU and force sensors, which are not on the motor buses.
"""

from __future__ import annotations

import threading

import can
import numpy as np

from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.bus_config import BusConfig
from robot_ctrl.hw.mit_protocol import DISABLE, ENABLE, HOST_ID, SET_ZERO, MitRanges, pack_reply, unpack_command
from robot_ctrl.hw.types import JointCommand, JointState


class MitCanEmulator:
    def __init__(self, config: BusConfig, plant: HardwareAdapter):
        if config.backend != "mit_can":
            raise ValueError(f"{config.path.name} is a {config.backend!r} config, not mit_can")
        self.config = config
        self.plant = plant
        self.nj = len(config.motors)
        self.ranges = [MitRanges.from_dict(config.models[m.model]) for m in config.motors]
        self._index = {(m.bus, m.id): i for i, m in enumerate(config.motors)}
        self.enabled = np.zeros(self.nj, dtype=bool)
        self.encoder_zero = np.zeros(self.nj)  # set by the set-zero frame [rad, motor side]
        self.received: list[tuple[float, JointCommand]] = []
        self.drop_replies = False
        self.silent: set[int] = set()
        self.drop_probability = 0.0
        self._rng = np.random.default_rng(0)
        self._pending: list[tuple[float, float, float, float, float] | None] = [None] * self.nj
        self._lock = threading.Lock()
        self._state: JointState | None = None
        self._buses: dict[str, can.BusABC] = {}
        self._threads: list[threading.Thread] = []
        self._running = threading.Event()

    def start(self) -> None:
        """Bring the plant up (configure, activate) and start listening on every bus."""
        self.plant.configure()
        self.plant.activate()
        self._state = self.plant.read()
        self._running.set()
        for name, options in self.config.buses.items():
            bus = can.Bus(**options)
            self._buses[name] = bus
            thread = threading.Thread(target=self._serve, args=(name, bus), name=f"mit-emulator-{name}", daemon=True)
            thread.start()
            self._threads.append(thread)

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

    def clock(self) -> float:
        """The plant's time [s]: the clock a safety layer uses in lock-step emulation, where the
        robot does not move while the controller computes."""
        with self._lock:
            return self._state.t

    # Bus side -----------------------------------------------------------------------------------
    def _serve(self, name: str, bus: can.BusABC) -> None:
        while self._running.is_set():
            msg = bus.recv(timeout=0.05)
            if msg is None or msg.arbitration_id == HOST_ID:
                continue
            i = self._index.get((name, msg.arbitration_id))
            if i is None:
                continue
            data = bytes(msg.data)
            with self._lock:
                if data == ENABLE:
                    self.enabled[i] = True
                elif data == DISABLE:
                    self.enabled[i] = False
                elif data == SET_ZERO:
                    self.encoder_zero[i] += self._motor_position(i)
                elif len(data) == 8:
                    self._pending[i] = unpack_command(data, self.ranges[i])
                    if all(c is not None for c in self._pending):
                        self._step()  # answers every motor's command with the state after the step
                    continue
                self._reply(i)

    def _motor_position(self, i: int) -> float:
        m = self.config.motors[i]
        return m.direction * m.gear_ratio * self._state.q[i] + m.zero_offset - self.encoder_zero[i]

    def _step(self) -> None:
        p, v, kp, kd, t = (np.array(column) for column in zip(*self._pending))
        self._pending = [None] * self.nj
        d, g = self.config.direction, self.config.gear
        on = self.enabled.astype(float)
        cmd = JointCommand(q=d * (p + self.encoder_zero - self.config.zero) / g, dq=d * v / g, kp=on * kp * g**2,
                           kd=on * kd * g**2, tau_ff=on * d * g * t)
        self.received.append((self._state.t, cmd))
        self.plant.write(cmd)
        self._state = self.plant.read()
        for i in range(self.nj):
            self._reply(i)

    def _reply(self, i: int) -> None:
        if self.drop_replies or i in self.silent or (self.drop_probability and self._rng.random() < self.drop_probability):
            return
        m, s = self.config.motors[i], self._state
        v = m.direction * m.gear_ratio * s.dq[i]
        tau = m.direction * s.tau[i] / m.gear_ratio
        data = pack_reply(m.id, self._motor_position(i), v, tau, self.ranges[i])
        self._buses[m.bus].send(can.Message(arbitration_id=HOST_ID, data=data, is_extended_id=False))
