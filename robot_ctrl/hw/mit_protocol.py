"""The MIT-style CAN servo protocol (mini-cheetah actuators and the many drives that copied it).

Command frame, 8 bytes, to the motor's CAN id: position 16 bit, velocity 12, kp 12, kd 12,
feedforward torque 12, big-endian bit-packed::

    [p15..8] [p7..0] [v11..4] [v3..0 kp11..8] [kp7..0] [kd11..4] [kd3..0 t11..8] [t7..0]

Reply, 6 bytes (sent to the host, id 0): motor id, position 16 bit, velocity 12, torque 12::

    [id] [p15..8] [p7..0] [v11..4] [v3..0 t11..8] [t7..0]

Each value maps linearly onto its model's range [lo, hi]: ``u = round((x − lo) (2^bits − 1) / (hi − lo))``
after clamping into the range (the reference firmware truncates; rounding halves the worst-case
error to half a step). Special frames: 7 × 0xFF then 0xFC (enter motor mode), 0xFD (exit motor
mode) or 0xFE (set the current position as zero). Motor side, SI units (rad, rad/s, N·m).
"""

from __future__ import annotations

from dataclasses import dataclass

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


def pack_reply(motor_id: int, p: float, v: float, t: float, r: MitRanges) -> bytes:
    pi = float_to_uint(p, *r.position, 16)
    vi = float_to_uint(v, *r.velocity, 12)
    ti = float_to_uint(t, *r.torque, 12)
    return bytes([motor_id, pi >> 8, pi & 0xFF, vi >> 4, ((vi & 0xF) << 4) | (ti >> 8), ti & 0xFF])


def unpack_reply(data: bytes, r: MitRanges) -> tuple[int, float, float, float]:
    """``(motor id, p, v, t)`` of a reply frame."""
    if len(data) != 6:
        raise ValueError(f"MIT reply frames have 6 bytes, got {len(data)}")
    pi = (data[1] << 8) | data[2]
    vi = (data[3] << 4) | (data[4] >> 4)
    ti = ((data[4] & 0xF) << 8) | data[5]
    return data[0], uint_to_float(pi, *r.position, 16), uint_to_float(vi, *r.velocity, 12), uint_to_float(ti, *r.torque, 12)
