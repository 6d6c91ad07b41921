"""Dynamixel Protocol 2.0 framing: CRC-16, byte stuffing, instruction and status packets.

The backend talks through ``dynamixel_sdk``; this module is the servo side of the same wire
format, used by the emulator (and by tests to check what the SDK put on the wire)::

    FF FF FD 00 | ID | LEN_L LEN_H | INSTRUCTION | PARAMETERS … | CRC_L CRC_H

``LEN`` counts the bytes after it (instruction, parameters, CRC). Inside the instruction and
parameters every ``FF FF FD`` is sent as ``FF FF FD FD`` (stuffing). The CRC-16 (polynomial 0x8005,
initial value 0, not reflected) covers everything before it, after stuffing. Status packets use
the instruction 0x55 followed by an error byte; the answer to a Fast Sync Read (0x8A) is one status
packet, not stuffed, that every servo asked adds its part to (``fast_sync_status``). X-series control table addresses used here:
Torque Enable 64, Position D/I/P Gain 80/82/84, Bus Watchdog 98, Goal Position 116,
Present Current 126, Present Velocity 128, Present Position 132, Present Temperature 146.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

HEADER = bytes([0xFF, 0xFF, 0xFD, 0x00])
INST_PING, INST_READ, INST_WRITE, INST_STATUS = 0x01, 0x02, 0x03, 0x55
INST_SYNC_READ, INST_SYNC_WRITE, INST_FAST_SYNC_READ = 0x82, 0x83, 0x8A
BROADCAST = 0xFE

RETURN_DELAY_TIME = 9  # EEPROM, 2 µs units (default 250: 500 µs per servo and read)
TEMPERATURE_LIMIT = 31  # EEPROM, 1 byte [°C]: above it the servo reports overheating
PWM_LIMIT = 36  # EEPROM, 2 bytes (PWM_MAX: 100 %)
PWM_MAX = 885
VELOCITY_LIMIT = 44  # EEPROM, 4 bytes, velocity units
SHUTDOWN = 63  # EEPROM, 1 byte: the hardware errors that switch the torque off (bits of HARDWARE_ERRORS)
PROTECTIVE_LIMITS = {SHUTDOWN: 1, TEMPERATURE_LIMIT: 1, PWM_LIMIT: 2, VELOCITY_LIMIT: 4}  # address: size
SHUTDOWN_DEFAULT = 0x34  # the X-series default: overload, electrical shock and overheating switch the torque off
OVERHEATING = 1 << 2  # the Hardware Error Status bit
OPERATING_MODE = 11  # EEPROM
CURRENT_BASED_POSITION = 5  # Operating Mode: the position PID outputs a current, limited by Goal Current
CURRENT_LIMIT = 38  # EEPROM, 2 bytes
TORQUE_ENABLE = 64
HARDWARE_ERROR_STATUS = 70
GAINS = 80  # D gain (2 bytes), I gain (2), P gain (2)
GAIN_MAX = 16383  # the position gains' register range; a servo ignores a write beyond it
BUS_WATCHDOG = 98
GOAL_CURRENT = 102  # 2 bytes, ≤ Current Limit
PROFILE_ACCELERATION = 108  # 4 bytes; 0: no profile, the goal is taken at once
PROFILE_VELOCITY = 112  # 4 bytes
GOAL_POSITION = 116
PRESENT = 126  # current (2), velocity (4), position (4), … temperature at 146
PRESENT_LENGTH = 21
TEMPERATURE_OFFSET = 146 - PRESENT


#: Hardware Error Status bits (X-series): any of them shuts the servo's torque off until a reboot.
#: Status packet errors (Protocol 2.0).
DATA_RANGE_ERROR, ACCESS_ERROR = 0x04, 0x07
HARDWARE_ERRORS = {0: "input voltage", 2: "overheating", 3: "motor encoder", 4: "electrical shock", 5: "overload"}


def hardware_errors(status: int) -> str:
    """The names of the bits set in a Hardware Error Status byte."""
    return ", ".join(name for bit, name in HARDWARE_ERRORS.items() if status >> bit & 1) or f"0x{status:02x}"


def _crc_table() -> list[int]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    crc = 0
    for byte in data:
        crc = ((crc << 8) ^ _TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Insert 0xFD after every FF FF FD in the instruction and parameters (the pattern cannot
    overlap itself, so one left-to-right replace is the byte-by-byte rule)."""
    return bytes(body).replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")


def unstuff(body: bytes) -> bytes:
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if len(out) >= 3 and out[-3:] == b"\xff\xff\xfd" and i + 1 < len(body) and body[i + 1] == 0xFD:
            i += 1  # drop the stuffing byte
        i += 1
    return bytes(out)


def packet(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    body = stuff(bytes([instruction]) + params)
    length = len(body) + 2
    head = HEADER + bytes([servo_id, length & 0xFF, length >> 8]) + body
    crc = crc16(head)
    return head + bytes([crc & 0xFF, crc >> 8])


def status(servo_id: int, params: bytes = b"", error: int = 0) -> bytes:
    return packet(servo_id, INST_STATUS, bytes([error]) + params)


def fast_sync_status(answers: list[tuple[int, bytes, int]]) -> bytes:
    """The one status packet that answers a Fast Sync Read: ID ``BROADCAST``, then for each servo
    ``(id, data, error)`` in the order asked, ``ERROR | ID | DATA | CRC``, where each servo's CRC is
    the running CRC of the packet so far and the last one is the packet's own CRC (the servos append
    their parts one after the other). Not byte-stuffed: ``dynamixel_sdk`` reads this packet without
    removing stuffing, at fixed offsets of ``len(data) + 4`` bytes per servo, after checking its CRC."""
    length = 1 + sum(4 + len(data) for _, data, _ in answers)  # instruction, the parts, their CRCs
    head = HEADER + bytes([BROADCAST, length & 0xFF, length >> 8, INST_STATUS])
    params = b""
    for k, (servo, data, error) in enumerate(answers):
        params += bytes([error, servo]) + data
        if k < len(answers) - 1:
            crc = crc16(head + params)
            params += bytes([crc & 0xFF, crc >> 8])
    crc = crc16(head + params)
    return head + params + bytes([crc & 0xFF, crc >> 8])


def parse(buffer: bytearray) -> tuple[int, int, bytes] | None:
    """Take the first complete packet off ``buffer``: ``(id, instruction, params)``; None if none is
    complete yet. Bytes before a header and packets with a bad CRC are dropped."""
    while True:
        start = buffer.find(HEADER)
        if start < 0:
            del buffer[: max(len(buffer) - 3, 0)]
            return None
        del buffer[:start]
        if len(buffer) < 7:
            return None
        length = buffer[5] | (buffer[6] << 8)
        end = 7 + length
        if len(buffer) < end:
            return None
        raw = bytes(buffer[:end])
        del buffer[:end]
        if crc16(raw[:-2]) != (raw[-2] | (raw[-1] << 8)):
            continue
        body = unstuff(raw[7:-2])
        return raw[4], body[0], body[1:]


def to_signed(value: int, size: int) -> int:
    bits = 8 * size
    return value - (1 << bits) if value >= 1 << (bits - 1) else value


def to_bytes(value: int, size: int) -> bytes:
    return int(value & ((1 << (8 * size)) - 1)).to_bytes(size, "little")


@dataclass(frozen=True)
class RegisterUnits:
    """SI value of one register unit for each servo of a bus config, from its models."""

    position: np.ndarray  # [rad] per Goal/Present Position unit
    velocity: np.ndarray  # [rad/s] per Present Velocity unit
    torque: np.ndarray  # [N·m] per Present Current unit (current unit × torque constant)
    kp: np.ndarray  # [N·m/rad] per Position P Gain unit
    kd: np.ndarray  # [N·m·s/rad] per Position D Gain unit

    @classmethod
    def of(cls, config) -> "RegisterUnits":
        models = [config.models[m.model] for m in config.motors]
        return cls(np.array([2 * math.pi / m["units_per_rev"] for m in models]),
                   np.array([m["velocity_unit"] for m in models]),
                   np.array([m["current_unit"] * m["torque_constant"] for m in models]),
                   np.array([m["kp_unit"] for m in models]), np.array([m["kd_unit"] for m in models]))
