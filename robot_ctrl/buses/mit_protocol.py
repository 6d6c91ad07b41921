"""The MIT-style CAN servo protocol (mini-cheetah actuators and the many drives that copied it).

Command frame, 8 bytes, to the motor's CAN id: position 16 bit, velocity 12, kp 12, kd 12,
feedforward torque 12, big-endian bit-packed::

    [p15..8] [p7..0] [v11..4] [v3..0 kp11..8] [kp7..0] [kd11..4] [kd3..0 t11..8] [t7..0]

Replies (sent to the host, id 0) come in three formats, named per motor model in the bus config
(``reply``):

- ``mit6``, the mini-cheetah firmware: 6 bytes, motor id, position 16 bit, velocity 12, torque 12::

      [id] [p15..8] [p7..0] [v11..4] [v3..0 t11..8] [t7..0]

- ``cubemars``, CubeMars AK series in MIT mode (AK Series Module Driver User Manual V1.0.15.X):
  the same 6 bytes, then the temperature (°C + 40) and a fault code (0 none, ``CUBEMARS_FAULTS``);
- ``damiao``, Damiao DM-J series in MIT mode: 8 bytes, the first holding the motor id in its low
  nibble and the drive's status in its high one (1 enabled, 0 disabled, ``DAMIAO_STATUS``), then
  position, velocity and torque as above, then the MOSFET's and the rotor's temperatures (°C).

Each value maps linearly onto its model's range [lo, hi]: ``u = round((x − lo) (2^bits − 1) / (hi − lo))``
after clamping into the range (the reference firmware truncates; rounding halves the worst-case
error to half a step). Special frames: 7 × 0xFF then 0xFC (enter motor mode), 0xFD (exit motor
mode) or 0xFE (set the current position as zero). Motor side, SI units (rad, rad/s, N·m).

Damiao drives also have registers, read and written with frames to CAN id 0x7FF:
``[id & 0xFF] [id >> 8] [0x33 read | 0x55 write] [register] [value, 4 bytes little-endian]``; the
drive answers with the same layout. Register 9 (TIMEOUT, in 50 µs units) makes the drive disable
itself when no command came for that long (status 13, communication lost).
"""

from __future__ import annotations

from dataclasses import dataclass

REPLY_FORMATS = ("mit6", "cubemars", "damiao")
REPLY_LENGTH = {"mit6": 6, "cubemars": 8, "damiao": 8}

#: CubeMars AK-series fault codes, the reply's last byte (the VESC firmware's ``mc_fault_code``).
CUBEMARS_FAULTS = {1: "over-voltage", 2: "under-voltage", 3: "gate driver fault", 4: "over-current",
                   5: "MOSFET over-temperature", 6: "motor over-temperature", 7: "gate driver over-voltage",
                   8: "gate driver under-voltage", 9: "MCU under-voltage", 10: "booted from a watchdog reset",
                   11: "encoder SPI fault", 12: "encoder signal too weak", 13: "encoder signal too strong",
                   14: "flash corruption", 15: "current sensor 1 offset", 16: "current sensor 2 offset",
                   17: "current sensor 3 offset", 18: "unbalanced phase currents"}
#: Damiao status codes, the high nibble of the reply's first byte.
DAMIAO_STATUS = {0: "disabled", 1: "enabled", 8: "over-voltage", 9: "under-voltage", 10: "over-current",
                 11: "MOSFET over-temperature", 12: "rotor over-temperature",
                 13: "communication lost (its CAN timeout expired)", 14: "overload"}
DAMIAO_ENABLED = 1
PARAM_CAN_ID = 0x7FF
PARAM_READ, PARAM_WRITE = 0x33, 0x55
TIMEOUT_REGISTER = 9
TIMEOUT_UNIT = 50e-6  # [s] per count of the TIMEOUT register

ENABLE = bytes([0xFF] * 7 + [0xFC])
DISABLE = bytes([0xFF] * 7 + [0xFD])
SET_ZERO = bytes([0xFF] * 7 + [0xFE])
HOST_ID = 0


@dataclass(frozen=True)
class MitRanges:
    position: tuple[float, float]  # [rad]
    velocity: tuple[float, float]  # [rad/s]
    kp: tuple[float, float]  # [N·m/rad]
    kd: tuple[float, float]  # [N·m·s/rad]
    torque: tuple[float, float]  # [N·m]

    @classmethod
    def from_dict(cls, d: dict) -> "MitRanges":
        return cls(*(tuple(float(x) for x in d[k]) for k in ("position", "velocity", "kp", "kd", "torque")))

    def step(self, field: str) -> float:
        """One quantization step of ``field`` (its range over 2^bits − 1)."""
        lo, hi = getattr(self, field)
        return (hi - lo) / ((1 << BITS[field]) - 1)


BITS = {"position": 16, "velocity": 12, "kp": 12, "kd": 12, "torque": 12}


def float_to_uint(x: float, lo: float, hi: float, bits: int) -> int:
    if x != x:  # NaN never reaches a frame
        raise ValueError("cannot encode NaN")
    x = min(max(x, lo), hi)
    return int(round((x - lo) * ((1 << bits) - 1) / (hi - lo)))


def uint_to_float(u: int, lo: float, hi: float, bits: int) -> float:
    return lo + u * (hi - lo) / ((1 << bits) - 1)


def pack_command(p: float, v: float, kp: float, kd: float, t: float, r: MitRanges) -> bytes:
    pi = float_to_uint(p, *r.position, 16)
    vi = float_to_uint(v, *r.velocity, 12)
    kpi = float_to_uint(kp, *r.kp, 12)
    kdi = float_to_uint(kd, *r.kd, 12)
    ti = float_to_uint(t, *r.torque, 12)
    return bytes([pi >> 8, pi & 0xFF, vi >> 4, ((vi & 0xF) << 4) | (kpi >> 8), kpi & 0xFF, kdi >> 4,
                  ((kdi & 0xF) << 4) | (ti >> 8), ti & 0xFF])


def unpack_command(data: bytes, r: MitRanges) -> tuple[float, float, float, float, float]:
    """``(p, v, kp, kd, t)`` of a command frame (the motor's side of the bus)."""
    if len(data) != 8:
        raise ValueError(f"MIT command frames have 8 bytes, got {len(data)}")
    pi = (data[0] << 8) | data[1]
    vi = (data[2] << 4) | (data[3] >> 4)
    kpi = ((data[3] & 0xF) << 8) | data[4]
    kdi = (data[5] << 4) | (data[6] >> 4)
    ti = ((data[6] & 0xF) << 8) | data[7]
    return (uint_to_float(pi, *r.position, 16), uint_to_float(vi, *r.velocity, 12), uint_to_float(kpi, *r.kp, 12),
            uint_to_float(kdi, *r.kd, 12), uint_to_float(ti, *r.torque, 12))


@dataclass(frozen=True)
class MitReply:
    """One reply, motor side. ``temperature`` [°C] and ``fault`` (None when healthy) where the
    format carries them; ``enabled``: what a Damiao drive says of itself."""

    motor_id: int
    position: float  # [rad]
    velocity: float  # [rad/s]
    torque: float  # [N·m]
    temperature: float | None = None
    fault: str | None = None
    enabled: bool | None = None


def pack_reply(motor_id: int, p: float, v: float, t: float, r: MitRanges, fmt: str = "mit6",
               temperature: float = 25.0, code: int | None = None) -> bytes:
    """A reply frame in format ``fmt``; ``code``: the fault (CubeMars, default 0) or status
    (Damiao, default enabled) to report."""
    pi = float_to_uint(p, *r.position, 16)
    vi = float_to_uint(v, *r.velocity, 12)
    ti = float_to_uint(t, *r.torque, 12)
    body = [pi >> 8, pi & 0xFF, vi >> 4, ((vi & 0xF) << 4) | (ti >> 8), ti & 0xFF]
    celsius = int(min(max(round(temperature), 0), 255))
    if fmt == "mit6":
        return bytes([motor_id, *body])
    if fmt == "cubemars":
        return bytes([motor_id, *body, min(celsius + 40, 255), code or 0])
    status = DAMIAO_ENABLED if code is None else code
    return bytes([(motor_id & 0x0F) | (status << 4), *body, celsius, celsius])


def reply_motor_id(data: bytes, fmt: str) -> int | None:
    """The motor a reply frame of format ``fmt`` comes from, or None if it is not one."""
    if len(data) != REPLY_LENGTH[fmt]:
        return None
    return data[0] & 0x0F if fmt == "damiao" else data[0]


def unpack_reply(data: bytes, r: MitRanges, fmt: str = "mit6") -> MitReply:
    """The reply frame ``data`` of format ``fmt``."""
    if len(data) != REPLY_LENGTH[fmt]:
        raise ValueError(f"{fmt} reply frames have {REPLY_LENGTH[fmt]} bytes, got {len(data)}")
    pi = (data[1] << 8) | data[2]
    vi = (data[3] << 4) | (data[4] >> 4)
    ti = ((data[4] & 0xF) << 8) | data[5]
    values = (uint_to_float(pi, *r.position, 16), uint_to_float(vi, *r.velocity, 12), uint_to_float(ti, *r.torque, 12))
    if fmt == "mit6":
        return MitReply(data[0], *values)
    if fmt == "cubemars":
        fault = None if data[7] == 0 else CUBEMARS_FAULTS.get(data[7], f"fault code {data[7]}")
        return MitReply(data[0], *values, temperature=float(data[6] - 40), fault=fault)
    status = data[0] >> 4
    fault = None if status in (0, DAMIAO_ENABLED) else DAMIAO_STATUS.get(status, f"status {status}")
    return MitReply(data[0] & 0x0F, *values, temperature=float(max(data[6], data[7])), fault=fault,
                    enabled=status == DAMIAO_ENABLED)


def param_frame(motor_id: int, op: int, register: int, value: int = 0) -> bytes:
    """A Damiao register read (``PARAM_READ``) or write (``PARAM_WRITE``) frame, or its answer."""
    return bytes([motor_id & 0xFF, motor_id >> 8, op, register, *int(value).to_bytes(4, "little")])


def unpack_param(data: bytes) -> tuple[int, int, int, int] | None:
    """``(motor id, op, register, value)`` of a register frame, or None if it is not one."""
    if len(data) != 8 or data[2] not in (PARAM_READ, PARAM_WRITE):
        return None
    return data[0] | (data[1] << 8), data[2], data[3], int.from_bytes(data[4:8], "little")
