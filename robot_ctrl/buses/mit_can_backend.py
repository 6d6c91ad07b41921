"""MitCanBackend: joints driven by MIT-style CAN servos (``mit_protocol``) over python-can.

Lifecycle: ``configure`` opens one python-can bus per bus in the YAML and sets the drive-side
timeout where the drive has one (Damiao: register TIMEOUT written and read back, so a dead host
process leaves the motor disabled after the bus config's ``drive_timeout_s``; a drive that does
not confirm it fails the configuration; a config with drives that have no such timeout is refused
unless it states why they may be enabled, ``without_drive_timeout``); ``activate`` sends the
enter-motor-mode frame to every motor and takes their replies as the first state; ``write`` sends
one command frame per motor (joint side converted to motor side, see ``bus_config``); ``read``
collects the replies that command caused (each motor answers every frame it receives) and
returns the joint state; ``deactivate`` sends exit-motor-mode; ``estop`` sends damping commands
(kp = 0, kd = ``kd_damping``, τ = 0) to every motor. ``zero_motor(joint)`` sends the set-zero frame
(only on request: it redefines the encoder's zero).

A motor bus carries joint data only. The base pose, IMU and foot force/torque readings of the
JointState come from ``body_sensors`` (a callable returning a JointState whose body fields are
used), which on a real robot is the IMU/force-sensor driver and in the emulator the simulation.

Replies (the bus config's ``reply_timeout_s`` and ``max_missed_replies``): each tick waits at most
``reply_timeout_s`` for one reply per motor. A motor that misses one keeps its last values
(``missed`` counts its misses in a row, ``missing_replies`` all of them); one that misses more than
``max_missed_replies`` in a row raises, and so does ``activate`` if a motor stays silent through
as many enable frames (after disabling them all again). Frames still queued when a tick's commands
go out came after their own tick's wait: they are dropped (``late_replies``), not read as this
tick's. A reply is a drive's when it comes on its bus, from the host's id (standard frame), naming
that drive's id; the MIT formats carry no sequence number or timestamp, and a drive answers each
frame once, so a second answer to one request within a tick's wait (a duplicate, or another node
sending with the host's id: a spoof) makes both doubtful: neither is taken, the motor keeps its last
values as on a missed reply (``duplicate_replies``), and once every motor has answered the frames
already queued are still read, to find such a second answer. A frame from the host's id naming no
drive of its bus is foreign. The state's time advances when any motor answered; when none did it
stays, and the safety layer sees a stale state.

Threads: the safety layer's watchdog sends damping from a thread of its own, while a write may be in
flight. Frames go out at once from either; replies are taken by one thread at a time (``_receiving``):
two threads waiting on one socket would take each other's replies, and one could be left blocked
for good on a frame the other took (python-can's receive selects, then reads a blocking socket).

Late replies: the formats carry no time either, so a reply delayed by a control period or more (a
buffering adapter, a congested bus) would come in a later tick's wait and look like that tick's.
Every ``stale_check_every`` ticks the host first listens with nothing asked, as long as the longest
tick's wait for its replies took since the last check (at most ``reply_timeout_s``; on a healthy
bus the replies' round trip, as a wait ends once every motor answered): a reply then answers an
older request. On a loop that keeps its period, a late reply that a tick's wait would take as
fresh comes within that long after the tick starts, so the check hears it; one that comes later
is cut off by the wait's gap and found queued at the next tick. Both are late (``late_replies``), and a motor
found late in ``STALE_CHECKS_TO_FAULT`` intervals between checks in a row raises (one may be a
glitch). What no host can catch on these formats: a drive that answers each request with the state
of the request before (its lateness comes with the next frame, not with time).

Reply formats (``mit_protocol``, per motor model): 6-byte mini-cheetah replies carry no
temperature or fault; CubeMars and Damiao 8-byte replies do. The state's ``temperature`` is
reported when every motor's format carries one. A fault code, or a Damiao drive that says it is
disabled while it should be enabled (its CAN timeout expired, say), raises naming the joint.

A bus on an interface that hands a sender its own frames back (python-can's ``udp_multicast``, the
bus between processes that ``robot-ctrl hw emulate`` serves: ``ECHOING_INTERFACES``) has each frame
this backend sent recognized when it comes back and set aside: it is neither a reply nor a foreign
frame, and a register frame's echo never confirms its own write.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from typing import Callable

import can
import numpy as np

from robot_ctrl.buses.bus_config import BusConfig
from robot_ctrl.buses.mit_protocol import (
    DISABLE,
    ENABLE,
    HOST_ID,
    PARAM_CAN_ID,
    PARAM_READ,
    PARAM_WRITE,
    SET_ZERO,
    TIMEOUT_REGISTER,
    TIMEOUT_UNIT,
    MitRanges,
    pack_command,
    param_frame,
    reply_motor_id,
    unpack_param,
    unpack_reply,
)
from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.robot.config import ConfigError

#: [s] Replies follow each other back to back once they come (0.13 ms per frame at 1 Mbit/s): after
#: this long without one, the rest of the bus's motors missed theirs.
REPLY_GAP = 0.002
#: A motor found answering late at this many stale checks in a row is a fault (one may be a glitch).
STALE_CHECKS_TO_FAULT = 2
#: [s] how long ``configure`` waits for the drives to answer a register read or write
PARAM_WAIT = 0.1
#: python-can interfaces on which a bus hears its own frames (udp_multicast: every socket on the group
#: hears every datagram, and receive_own_messages cannot be turned off there)
ECHOING_INTERFACES = ("udp_multicast",)


class MitCanBackend(HardwareAdapter):
    def __init__(self, config: BusConfig, kd_damping: np.ndarray, body_sensors: Callable[[], JointState] | None = None,
                 clock: Callable[[], float] = time.monotonic):
        if config.backend != "mit_can":
            raise ValueError(f"{config.path.name} is a {config.backend!r} config, not mit_can")
        super().__init__(len(config.motors))
        self.config = config
        self.kd_damping = np.asarray(kd_damping, dtype=float)
        self.body_sensors = body_sensors
        self.reply_timeout = config.reply_timeout
        self.clock = clock
        self.ranges = [MitRanges.from_dict(config.models[m.model]) for m in config.motors]
        self.formats = [config.reply_format(m) for m in config.motors]
        self._bus_format = {m.bus: f for m, f in zip(config.motors, self.formats)}  # one format per bus
        self._index = {(m.bus, m.id): i for i, m in enumerate(config.motors)}
        waiver = config.without_drive_timeout
        unnamed = [j for j in config.holding_joints if waiver is None or j not in waiver.joints]
        if unnamed:
            raise ConfigError(f"{config.path.name}: {len(unnamed)} drives have no command timeout of their own "
                              f"({unnamed[0]}{', ...' if len(unnamed) > 1 else ''}): a host that dies leaves them on "
                              "their last stiff command. Use drives with one (reply: damiao, drive_timeout_s), or "
                              "name each such joint under without_drive_timeout: {why: ..., joints: [...]}")
        self._buses: dict[str, can.BusABC] = {}
        #: per echoing bus, the (CAN id, data) of the frames sent whose echo has not come back yet
        self._echoes: dict[str, deque[tuple[int, bytes]]] = {}
        self._p = np.zeros(self.nj)  # motor side
        self._v = np.zeros(self.nj)
        self._t = np.zeros(self.nj)
        self._temperature = np.full(self.nj, np.nan)  # [°C] where the format reports it
        self._faults: dict[int, str] = {}
        self._ticks = 0  # commands sent, for the stale checks
        self._late = np.zeros(self.nj, dtype=bool)  # a reply of the motor came late since the last check
        self._late_checks = np.zeros(self.nj, dtype=int)  # check intervals in a row in which the motor was late
        self._longest_wait = REPLY_GAP  # [s] the longest a tick waited for its replies since the last check
        self._time = None
        self._t0 = 0.0
        self._body: JointState | None = None
        self._receiving = threading.Lock()  # one thread takes replies at a time (module docstring)

    # Lifecycle hooks ------------------------------------------------------------------------------
    def _on_configure(self) -> None:
        self._t0 = self.clock()  # the state's time counts from here
        for name, options in self.config.buses.items():
            self._buses[name] = can.Bus(**options)
            if options.get("interface") in ECHOING_INTERFACES:
                self._echoes[name] = deque(maxlen=1024)
        self._set_drive_timeouts()

    @property
    def drive_timeout_joints(self) -> tuple[str, ...]:
        """Joints whose drive disables itself when the host stops sending (Damiao: ``drive_timeout_s``)."""
        return tuple(m.joint for m in self.config.motors if m.joint not in self.config.holding_joints)

    @property
    def without_drive_timeout(self) -> str | None:
        waiver = self.config.without_drive_timeout
        return None if waiver is None else waiver.why

    def _set_drive_timeouts(self) -> None:
        """Write the Damiao drives' TIMEOUT register and read it back; fail naming the drives that
        did not confirm it."""
        motors = [i for i, f in enumerate(self.formats) if f == "damiao"]
        if not motors:
            return
        counts = round(self.config.drive_timeout / TIMEOUT_UNIT)
        for op in (PARAM_WRITE, PARAM_READ):
            for i in motors:
                m = self.config.motors[i]
                self._send(m.bus, PARAM_CAN_ID, param_frame(m.id, op, TIMEOUT_REGISTER, counts))
            confirmed = self._collect_params(motors, op, counts)
        unconfirmed = np.zeros(self.nj, dtype=bool)
        unconfirmed[[i for i in motors if i not in confirmed]] = True
        if unconfirmed.any():
            raise RuntimeError(f"{self._joints(unconfirmed)} did not confirm their CAN timeout "
                               f"({self.config.drive_timeout} s): check their power, wiring and CAN ids")

    def _collect_params(self, motors: list[int], op: int, value: int) -> set[int]:
        """The motors among ``motors`` that answered register operation ``op`` with ``value``."""
        confirmed: set[int] = set()
        deadline = time.monotonic() + PARAM_WAIT
        for name, bus in self._buses.items():
            expected = {i for i in motors if self.config.motors[i].bus == name}
            while expected - confirmed and (remaining := deadline - time.monotonic()) > 0:
                msg = bus.recv(timeout=remaining)
                if msg is None or self._echo(name, msg) or msg.arbitration_id != HOST_ID:
                    continue  # a drive answers on the host's id
                answer = unpack_param(bytes(msg.data))
                if answer is None:
                    continue
                i = self._index.get((name, answer[0]))
                if i in expected and answer[1:] == (op, TIMEOUT_REGISTER, value):
                    confirmed.add(i)
        return confirmed

    def _on_activate(self) -> None:
        self._take_late()  # register answers still queued from configure: no sign of a late drive
        self._late[:] = False
        self._faults.clear()
        silent = np.ones(self.nj, dtype=bool)
        for _ in range(self.config.max_missed_replies + 1):  # a lost frame is asked again
            self._broadcast(ENABLE, silent)
            silent &= ~self._collect(silent, expect_enabled=True, gap=None)
            if not silent.any():
                break
        if silent.any():
            self._on_deactivate()
            raise RuntimeError(f"no reply from {self._joints(silent)} on enable: check their power, wiring and "
                               "CAN ids (all motors disabled again)")
        if self._faults:
            faults = dict(self._faults)
            self._on_deactivate()
            self._faults = faults
            self._raise_faults()

    def _on_deactivate(self) -> None:
        """Disable every motor on every bus, whatever fails on another; the failures raise together."""
        failed = self._broadcast(DISABLE)
        self._collect(gap=None)
        self._faults.clear()
        self._raise_failed(failed)

    def _on_disable(self) -> None:
        self._on_deactivate()

    def _on_estop(self) -> None:
        """Damping to every motor on every bus, a bus-off one too (its frames may yet go out), whatever
        fails on another; the failures raise together."""
        if not self._buses:
            return
        self._take_late()
        q, _, _ = self.config.to_joint(self._p, self._v, self._t)
        zero = np.zeros(self.nj)
        failed = self._send_each(self._command_frames(JointCommand(q=q, dq=zero, kp=zero, kd=self.kd_damping,
                                                                   tau_ff=zero)))
        self._collect(expect_enabled=True)
        self._faults.clear()
        self._raise_failed(failed)

    def _on_close(self) -> None:
        for bus in self._buses.values():
            bus.shutdown()
        self._buses.clear()
        self._echoes.clear()

    def zero_motor(self, joint: str) -> None:
        """Make the motor of ``joint`` take its current position as zero (writes its encoder offset)."""
        motor = next((m for m in self.config.motors if m.joint == joint), None)
        if motor is None:
            raise KeyError(f"{joint!r} is not in {self.config.path.name}")
        self._raise_failed(self._send_each([(self.config.motors.index(motor), SET_ZERO)]))
        self._collect()

    # Read / write ---------------------------------------------------------------------------------
    def _write(self, cmd: JointCommand) -> None:
        self._send_commands(cmd)

    def _read(self) -> JointState:
        q, dq, tau = self.config.to_joint(self._p, self._v, self._t)
        fields = self._body.body_fields() if self._body is not None else {}
        temperature = self._temperature.copy() if np.isfinite(self._temperature).all() else None
        return JointState(t=self._time if self._time is not None else 0.0, q=q, dq=dq, tau=tau,
                          temperature=temperature, **fields)

    def _send_commands(self, cmd: JointCommand) -> None:
        """Send ``cmd`` and take the replies; a bus-off, a failed send, a drive fault or a motor past
        ``max_missed_replies`` raises."""
        self._take_late()
        every = self.config.stale_check_every
        if every and self._ticks % every == every - 1:
            self._check_stale()
        self._ticks += 1
        off = [name for name, bus in self._buses.items() if bus.state is can.BusState.ERROR]
        if off:
            raise RuntimeError(f"CAN bus {', '.join(off)} is bus-off (error state): check wiring and termination; "
                               "with restart-ms set the interface restarts itself")
        failed = self._send_each(self._command_frames(cmd))
        sent = self.clock()
        replied = self._collect(expect_enabled=True)
        self._longest_wait = max(self._longest_wait, self.clock() - sent)
        self._raise_failed(failed)
        self._raise_faults()
        self.missed = np.where(replied, 0, self.missed + 1)
        lost = self.missed > self.config.max_missed_replies
        if lost.any():
            raise RuntimeError(f"{self._joints(lost)} missed more than {self.config.max_missed_replies} replies in a row"
                               + (f" ({self.duplicate_replies} second answers to one request so far: another node "
                                  "answers with a drive's id?)" if self.duplicate_replies else ""))

    def _check_stale(self) -> None:
        """Listen as long as the longest tick's wait since the last check, with nothing asked (a reply
        now answers an older tick's request); fault the motors late in this interval and the one before."""
        self._take_late(min(self._longest_wait, self.reply_timeout))
        self._longest_wait = 0.0
        self._late_checks = np.where(self._late, self._late_checks + 1, 0)
        self._late[:] = False
        stale = self._late_checks >= STALE_CHECKS_TO_FAULT
        if stale.any():
            raise RuntimeError(f"{self._joints(stale)} answered late in {STALE_CHECKS_TO_FAULT} stale checks in a row "
                               "(replies with nothing asked, or after their tick's wait): the state they report is old")

    def _take_late(self, listen: float = 0.0) -> None:
        """Drop the frames that come within ``listen`` (what is queued for 0), counting the replies
        among them as late: this tick's replies are not asked for yet."""
        with self._receiving:
            deadline = self.clock() + listen
            for name, bus in self._buses.items():
                while (msg := bus.recv(timeout=max(deadline - self.clock(), 0.0))) is not None:
                    i = None if self._echo(name, msg) else self._reply_index(name, msg)
                    if i is not None:
                        self.late_replies += 1
                        self._late[i] = True

    def _reply_index(self, name: str, msg: can.Message) -> int | None:
        """The index of the motor whose reply ``msg`` (not an echo) is, on bus ``name``; None for an
        error frame or a foreign frame (each counted)."""
        if msg.is_error_frame:
            self.error_frames += 1
            return None
        if msg.arbitration_id != HOST_ID or msg.is_extended_id:  # not a drive's reply to us
            self.foreign_frames += 1
            return None
        i = self._index.get((name, reply_motor_id(bytes(msg.data), self._bus_format.get(name, "mit6"))))
        if i is None:
            self.foreign_frames += 1  # the host's id, but no motor of this bus
        return i

    def _raise_faults(self) -> None:
        faults, self._faults = self._faults, {}
        if faults:
            raise RuntimeError("drive fault: " + ", ".join(f"{self.config.motors[i].joint}: {f}" for i, f in faults.items()))

    def _joints(self, mask: np.ndarray) -> str:
        return ", ".join(self.config.motors[i].joint for i in np.flatnonzero(mask))

    def _command_frames(self, cmd: JointCommand) -> list[tuple[int, bytes]]:
        p, v, kp, kd, t = self.config.to_motor(cmd.q, cmd.dq, cmd.kp, cmd.kd, cmd.tau_ff)
        return [(i, pack_command(p[i], v[i], kp[i], kd[i], t[i], self.ranges[i])) for i in range(self.nj)]

    def _broadcast(self, frame: bytes, motors: np.ndarray | None = None) -> dict[str, str]:
        """``frame`` to every motor (or those ``motors`` marks); the buses whose send failed."""
        return self._send_each([(i, frame) for i in range(self.nj) if motors is None or motors[i]])

    def _send_each(self, frames: list[tuple[int, bytes]]) -> dict[str, str]:
        """Send each (motor index, frame) on the motor's bus. A bus whose send fails gets no more of
        these frames; every other bus gets all of its own. Returns bus → why it failed."""
        failed: dict[str, str] = {}
        for i, data in frames:
            m = self.config.motors[i]
            if m.bus in failed:
                continue
            try:
                self._send(m.bus, m.id, data)
            except (can.CanError, OSError) as exc:
                failed[m.bus] = f"{type(exc).__name__}: {exc}"
        return failed

    def _send(self, bus: str, can_id: int, data: bytes) -> None:
        self._buses[bus].send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))
        if bus in self._echoes:
            self._echoes[bus].append((can_id, bytes(data)))

    def _echo(self, bus: str, msg: can.Message) -> bool:
        """Whether ``msg`` is a frame this backend sent on ``bus``, come back (then set aside)."""
        sent = self._echoes.get(bus)
        if not sent:
            return False
        frame = (msg.arbitration_id, bytes(msg.data))
        try:
            k = sent.index(frame)
        except ValueError:
            return False
        for _ in range(k + 1):  # echoes come back in the order sent; any before it were lost
            sent.popleft()
        return True

    def _raise_failed(self, failed: dict[str, str]) -> None:
        if failed:
            raise RuntimeError("; ".join(f"CAN bus {name} ({self._joints(self._on_bus(name))}): {why}"
                                         for name, why in failed.items()))

    def _on_bus(self, name: str) -> np.ndarray:
        return np.array([m.bus == name for m in self.config.motors])

    def _collect(self, asked: np.ndarray | None = None, expect_enabled: bool = False,
                 gap: float | None = REPLY_GAP) -> np.ndarray:
        """Receive one reply per motor ``asked`` (default all; or time out); if any came, advance
        the state's time. Faults the replies report (and, with ``expect_enabled``, drives that say
        they are disabled) are kept in ``_faults``. A bus's wait ends ``gap`` after its last reply
        (a tick's replies come back to back); lifecycle calls (``gap=None``) wait the whole reply
        timeout for every motor. Returns which motors replied."""
        with self._receiving:
            return self._take_replies(asked, expect_enabled, gap)

    def _take_replies(self, asked: np.ndarray | None, expect_enabled: bool, gap: float | None) -> np.ndarray:
        asked = np.ones(self.nj, dtype=bool) if asked is None else asked
        replied = np.zeros(self.nj, dtype=bool)
        doubted = np.zeros(self.nj, dtype=bool)  # answered twice in this wait
        before = self._p.copy(), self._v.copy(), self._t.copy(), self._temperature.copy()
        deadline = self.clock() + self.reply_timeout
        failed: dict[str, str] = {}
        for name, bus in self._buses.items():
            expected = sum(1 for i, m in enumerate(self.config.motors) if m.bus == name and asked[i])
            got, bus_deadline = 0, deadline
            while True:
                # once every motor answered, only what is already queued (a second answer to one request)
                remaining = bus_deadline - self.clock() if got < expected else 0.0
                try:
                    msg = bus.recv(timeout=max(remaining, 0.0))  # past the deadline: what is already queued
                except (can.CanError, OSError) as exc:  # this bus only: the others' replies are still taken
                    failed[name] = f"{type(exc).__name__}: {exc}"
                    break
                if msg is None:
                    break
                if self._echo(name, msg):
                    continue
                bus_deadline = deadline if gap is None else min(deadline, self.clock() + gap)
                i = self._reply_index(name, msg)
                if i is None:
                    continue
                if replied[i] or doubted[i]:  # a second answer to one request: which one is the drive's?
                    self.duplicate_replies += 1
                    doubted[i] = True
                    continue
                reply = unpack_reply(bytes(msg.data), self.ranges[i], self.formats[i])
                self._p[i], self._v[i], self._t[i] = reply.position, reply.velocity, reply.torque
                if reply.temperature is not None:
                    self._temperature[i] = reply.temperature
                if reply.fault is not None:
                    self._faults[i] = reply.fault
                elif expect_enabled and reply.enabled is False:
                    self._faults[i] = "disabled itself"
                replied[i] = True
                got += 1
        if doubted.any():  # neither answer is taken: the motor keeps its last values, as on a missed reply
            for mine, kept in zip((self._p, self._v, self._t, self._temperature), before):
                mine[doubted] = kept[doubted]
            self._faults = {i: f for i, f in self._faults.items() if not doubted[i]}
            replied &= ~doubted
        if replied.any():
            self._body = self.body_sensors() if self.body_sensors is not None else None
            self._time = self._body.t if self._body is not None else self.clock() - self._t0
        self.missing_replies += int((asked & ~replied).sum())
        self._raise_failed(failed)
        return replied
