"""DynamixelPort: one serial port of a Dynamixel bus config and the servos on it.

It owns the port handler and the Sync Write / Sync Read groups of its servos (Goal Position, the
position gains, the present-state block, Hardware Error Status and Bus Watchdog) and does one
transaction at a time; ``DynamixelBackend`` runs its ports' transactions side by side, so a robot
split over several ports spends the longest port's time per tick, not their sum. With ``fast``
(every servo's model says ``fast_sync_read: true``) the present state comes from a Fast Sync Read:
one status packet that the servos fill one after the other, instead of one status packet per
servo, each with its own header and turnaround.

Replies the host did not take: Protocol 2.0 status packets carry the servo's id and a CRC, no
sequence number or time. The SDK clears the port's input before each instruction and takes, per
servo asked, the first status packet with its id within the packet timeout, passing over any other
on its way, silently. So a port keeps what the SDK passes over (``last_skipped``: ids of packets a
Sync Read passed over, a servo's second answer, or the genuine one behind a spoof) and, before a
tick's first instruction, what came with nothing asked (``take_queued``: a reply later than its
wait, or a second answer after the last one taken). ``DynamixelBackend`` counts and acts on both.

A pseudo-terminal (``/dev/pts/N``) is a servo emulator in software, not a wire: its replies wait on
the emulating program's scheduling (in the same interpreter, on its lock), so the SDK's packet
timeout (16 ms latency timer × 2 + 2 ms + the bytes' time) gets ``EMULATED_REPLY_MARGIN`` more
there. A serial adapter's timeout is the SDK's own.
"""

from __future__ import annotations

import os

import dynamixel_sdk as sdk
import numpy as np
from dynamixel_sdk.protocol2_packet_handler import PKT_ERROR, PKT_ID, PKT_PARAMETER0, Protocol2PacketHandler

from robot_ctrl.buses import dynamixel_protocol as dxl
from robot_ctrl.buses.bus_config import MotorMap


EMULATED_REPLY_MARGIN = 200.0  # [ms] added to the SDK's packet timeout on a pseudo-terminal


class _EmulatedPortHandler(sdk.PortHandler):
    """The SDK's port handler with ``EMULATED_REPLY_MARGIN`` more to wait for a reply."""

    def setPacketTimeout(self, packet_length):
        super().setPacketTimeout(packet_length)
        self.packet_timeout += EMULATED_REPLY_MARGIN


class _SkipKeepingPacketHandler(Protocol2PacketHandler):
    """The SDK's Protocol 2.0 packet handler, keeping in ``skipped`` the ids of the status packets a
    Sync Read's wait for one servo passed over (the SDK's ``readRx`` drops them unseen)."""

    def __init__(self):
        super().__init__()
        self.skipped: list[int] = []

    def readRx(self, port, dxl_id, length):
        while True:
            rxpacket, result = self.rxPacket(port, False)
            if result != sdk.COMM_SUCCESS or rxpacket[PKT_ID] == dxl_id:
                break
            self.skipped.append(rxpacket[PKT_ID])
        if result != sdk.COMM_SUCCESS:
            return [], result, 0
        return rxpacket[PKT_PARAMETER0 + 1: PKT_PARAMETER0 + 1 + length], result, rxpacket[PKT_ERROR]


def is_pseudo_terminal(device: str) -> bool:
    """Whether ``device`` is the slave end of a pseudo-terminal (a software emulator's port)."""
    return os.path.realpath(device).startswith("/dev/pts/")


class DynamixelPort:
    def __init__(self, name: str, options: dict, motors: list[tuple[int, MotorMap]], fast: bool = False):
        """``motors``: (index in the robot's joint order, mapping) of each servo on this port;
        ``fast``: read the present state with Fast Sync Read."""
        self.name, self.device, self.baudrate = name, options["device"], int(options["baudrate"])
        self.fast = fast
        self.index = [i for i, _ in motors]
        self.motors = [m for _, m in motors]
        self.ids = [m.id for m in self.motors]
        self.port = None
        self.last_skipped: list[int] = []  # ids of the status packets the last read_present passed over

    def open(self) -> None:
        port = (_EmulatedPortHandler if is_pseudo_terminal(self.device) else sdk.PortHandler)(self.device)
        try:
            opened = port.openPort()
        except Exception as exc:  # pyserial's SerialException: no such device, no permission
            raise OSError(f"cannot open the Dynamixel port {self.device} ({self.name}): {exc}") from exc
        if not opened:
            raise OSError(f"cannot open the Dynamixel port {self.device} ({self.name})")
        self.port = port
        if not self.port.setBaudRate(self.baudrate):
            raise OSError(f"cannot set {self.device} to {self.baudrate} baud")
        self.packet = _SkipKeepingPacketHandler()
        self.goal = sdk.GroupSyncWrite(self.port, self.packet, dxl.GOAL_POSITION, 4)
        self.gains = sdk.GroupSyncWrite(self.port, self.packet, dxl.GAINS, 6)
        self.present = sdk.GroupSyncRead(self.port, self.packet, dxl.PRESENT, dxl.PRESENT_LENGTH)
        self.status = {address: sdk.GroupSyncRead(self.port, self.packet, address, 1)
                       for address in (dxl.HARDWARE_ERROR_STATUS, dxl.BUS_WATCHDOG)}
        for servo in self.ids:
            self.present.addParam(servo)
            for group in self.status.values():
                group.addParam(servo)

    def close(self) -> None:
        if self.port is not None:
            self.port.closePort()
            self.port = None

    # Sync transactions ------------------------------------------------------------------------
    def write_goals(self, raw: np.ndarray) -> None:
        """Goal Position registers of this port's servos (``raw`` in the robot's joint order)."""
        self.goal.clearParam()
        for servo, i in zip(self.ids, self.index):
            self.goal.addParam(servo, dxl.to_bytes(int(raw[i]), 4))
        self._check(self.goal.txPacket(), "goal sync write")

    def write_gains(self, kp_reg: np.ndarray, kd_reg: np.ndarray) -> None:
        """Position P and D gain registers (I = 0), in the robot's joint order."""
        self.gains.clearParam()
        for servo, i in zip(self.ids, self.index):
            self.gains.addParam(servo, dxl.to_bytes(int(kd_reg[i]), 2) + dxl.to_bytes(0, 2)
                                + dxl.to_bytes(int(kp_reg[i]), 2))
        self._check(self.gains.txPacket(), "gain sync write")

    def read_present(self) -> np.ndarray | None:
        """(current, velocity, position, temperature) registers per servo of this port, or None if
        a servo did not answer; ``last_skipped`` then says which status packets it passed over."""
        self.packet.skipped = []
        answered = self.present.fastSyncRead() if self.fast else self.present.txRxPacket()
        self.last_skipped = self.packet.skipped
        if answered != sdk.COMM_SUCCESS:
            return None
        if not all(self.present.isAvailable(s, dxl.PRESENT, dxl.PRESENT_LENGTH) for s in self.ids):
            return None
        return np.array([[dxl.to_signed(self.present.getData(s, dxl.PRESENT, 2), 2),
                          dxl.to_signed(self.present.getData(s, dxl.PRESENT + 2, 4), 4),
                          dxl.to_signed(self.present.getData(s, dxl.PRESENT + 6, 4), 4),
                          self.present.getData(s, dxl.PRESENT + dxl.TEMPERATURE_OFFSET, 1)] for s in self.ids])

    def joint_index(self, servo: int | None) -> int | None:
        """The robot joint index of servo id ``servo`` on this port; None for another id (or None)."""
        return self.index[self.ids.index(servo)] if servo in self.ids else None

    def take_queued(self) -> list[int | None]:
        """The ids of the status packets waiting with nothing asked (None for bytes that make no
        status packet), taken off the port: call it before a tick's first instruction."""
        waiting = self.port.getBytesAvailable()
        if not waiting:
            return []
        buffer, ids = bytearray(self.port.readPort(waiting)), []
        while (pkt := dxl.parse(buffer)) is not None:
            ids.append(pkt[0] if pkt[1] == dxl.INST_STATUS else None)
        return ids or [None]

    def check_fast_sync_read(self) -> None:
        """With ``fast``, raise naming the port if its servos answer a Sync Read but not a Fast Sync
        Read (a model or firmware without it)."""
        if not self.fast or self.present.fastSyncRead() == sdk.COMM_SUCCESS:
            return
        if self.present.txRxPacket() == sdk.COMM_SUCCESS:
            raise OSError(f"the servos on {self.device} ({self.name}) answer a Sync Read but not a Fast Sync Read: "
                          "set fast_sync_read: false for their models")

    def read_status(self, address: int) -> list[int]:
        """One status byte (Hardware Error Status or Bus Watchdog) of each servo."""
        group = self.status[address]
        self._check(group.txRxPacket(), "status sync read")
        return [group.getData(s, address, 1) for s in self.ids]

    # One servo --------------------------------------------------------------------------------
    def write(self, motor: MotorMap, address: int, value: int, size: int) -> None:
        problem = self._write(motor, address, value, size)
        if problem:
            raise OSError(f"{motor.joint} (servo {motor.id}): writing {value} at address {address} failed ({problem})")

    def torque_off(self) -> None:
        """Torque Enable 0 on every servo of this port, each tried whatever another answers; the
        servos that did not take it raise together."""
        failed = []
        for m in self.motors:
            try:
                problem = self._write(m, dxl.TORQUE_ENABLE, 0, 1)
            except Exception as exc:  # a port that fails outright: the next servo is still tried
                problem = f"{type(exc).__name__}: {exc}"
            if problem:
                failed.append(f"{m.joint} (servo {m.id}): {problem}")
        if failed:
            raise OSError("torque off failed for " + ", ".join(failed))

    def read(self, motor: MotorMap, address: int, size: int) -> int:
        read = {1: self.packet.read1ByteTxRx, 2: self.packet.read2ByteTxRx, 4: self.packet.read4ByteTxRx}[size]
        value, result, error = read(self.port, motor.id, address)
        if result != sdk.COMM_SUCCESS or error:
            raise OSError(f"{motor.joint} (servo {motor.id}): reading address {address} failed "
                          f"({self.packet.getTxRxResult(result)}, error {error})")
        return value

    def set(self, motor: MotorMap, address: int, value: int, size: int) -> None:
        """Write a register and read it back; raise naming the joint if the servo refuses it."""
        problem = self._write(motor, address, value, size)
        if not problem:
            back = self.read(motor, address, size)
            problem = None if back == value else f"it reads back {back}"
        if problem:
            raise OSError(f"{motor.joint} (servo {motor.id}) does not take {value} at address {address} ({problem}): "
                          "it needs current-based position mode (5), return delay 0, no profile and its bus "
                          "watchdog (an X-series servo)")

    def _write(self, motor: MotorMap, address: int, value: int, size: int) -> str | None:
        write = {1: self.packet.write1ByteTxRx, 2: self.packet.write2ByteTxRx, 4: self.packet.write4ByteTxRx}[size]
        result, error = write(self.port, motor.id, address, value)
        return None if result == sdk.COMM_SUCCESS and not error else f"{self.packet.getTxRxResult(result)}, error {error}"

    def _check(self, result: int, what: str) -> None:
        if result != sdk.COMM_SUCCESS:
            raise OSError(f"Dynamixel {what} on {self.device} failed: {self.packet.getTxRxResult(result)}")
