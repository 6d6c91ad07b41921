"""The support segments of the pattern generator's horizon: which feet carry the robot, for how
long, and where the ZMP reference moves; the support polygon of a segment as half-planes, and the
swing foot's path between two segments (for the dynamic filter's preview). World frame."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robot_ctrl.geometry import Side, rotation, wrap_angle
from robot_ctrl.geometry.support_polygon import sole_halfplanes
from robot_ctrl.kernels import FLOAT, INDICES, INT, STACK, VECTOR, kernel
from robot_ctrl.wpg.footstep import FootRef, Footstep

MAX_EDGES = 8  # a hull of two rectangles has at most 8 edges


@dataclass
class Segment:
    duration: float  # [s] nominal (inf for standing)
    feet: list[FootRef]  # one (single support) or two (double support)
    zmp_from: FootRef | None  # ZMP reference moves linearly from this …
    zmp_to: FootRef | None = None  # … to this over the segment (None: stays at zmp_from)


def midpoint(a: FootRef, b: FootRef) -> FootRef:
    return FootRef(a.side, a.yaw, (a.offset + b.offset) / 2, (a.S + b.S) / 2)


def blend(a: FootRef, b: FootRef, s: float) -> FootRef:
    return FootRef(b.side, b.yaw, (1 - s) * a.offset + s * b.offset, (1 - s) * a.S + s * b.S)


def segment_at(segments: list[Segment], t: float) -> tuple[int, float]:
    """Index of the segment that holds nominal time ``t`` [s] from the horizon's start, and its start
    time; past the end, the last segment."""
    start = 0.0
    for k, seg in enumerate(segments):
        if t <= start + seg.duration + 1e-9 or k == len(segments) - 1:
            return k, start
        start += seg.duration
    raise ValueError("no segments")


def swing_point(segments: list[Segment], k: int, side: Side, F: np.ndarray, s: float, apex: float,
                fallback: Footstep) -> tuple[np.ndarray, float]:
    """Swing foot ``side`` at fraction ``s`` of single-support segment ``k``: from where it stood in
    the segment before to where it lands in the segment after (min-jerk in the plane and yaw,
    ``16 apex s²(1 − s)²`` in height). A landing the plan does not hold yet (beyond its footstep
    variables) repeats the last step: the lift foot mirrored through the stance foot's heading line
    and carried the step's length ahead, so the preview's legs keep up with its CoM."""
    def where(seg):
        return next(((f.position(F), f.yaw) for f in seg.feet if f.side == side), None)

    lift = where(segments[k - 1]) if k > 0 else None
    land = where(segments[k + 1]) if k + 1 < len(segments) else None
    lift = lift or (fallback.xy, fallback.yaw)
    if land is None:
        stance = segments[k].feet[0]
        R = rotation(stance.yaw)
        step = R.T @ (stance.position(F) - lift[0])  # lift → stance, in the stance foot's frame
        land = (stance.position(F) + R @ np.array([step[0], -step[1]]), stance.yaw)
    s = min(max(s, 0.0), 1.0)
    weight = s**3 * (10 - 15 * s + 6 * s * s)
    xy = lift[0] + weight * (land[0] - lift[0])
    yaw = lift[1] + weight * wrap_angle(land[1] - lift[1])
    return np.array([xy[0], xy[1], 16.0 * apex * s * s * (1 - s) ** 2]), float(yaw)


#: A foot as one row of floats for the compiled horizon: x, y [m] and yaw [rad] (world frame), then
#: its selection ``S`` of the footstep variables, row by row (``FootRef``).
FOOT_ROW = 11


def packed_segments(segments: list[Segment]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The segments as arrays for :func:`horizon_supports`: durations (n,), numbers of feet (n,),
    feet (n, 2, ``FOOT_ROW``) and ZMP references from and to (n, 2, ``FOOT_ROW``)."""
    n = len(segments)
    durations, counts = np.empty(n), np.empty(n, dtype=np.int64)
    feet, zmp = np.zeros((n, 2, FOOT_ROW)), np.zeros((n, 2, FOOT_ROW))
    for i, seg in enumerate(segments):
        durations[i], counts[i] = seg.duration, len(seg.feet)
        for k, foot in enumerate(seg.feet):
            _pack(foot, feet[i, k])
        _pack(seg.zmp_from, zmp[i, 0])
        _pack(seg.zmp_from if seg.zmp_to is None else seg.zmp_to, zmp[i, 1])
    return durations, counts, feet, zmp


def _pack(ref: FootRef, row: np.ndarray) -> None:
    row[:2] = ref.offset
    row[2] = ref.yaw
    row[3:] = ref.S.ravel()


@kernel((VECTOR, INDICES, STACK, STACK, FLOAT, INT, FLOAT, FLOAT))
def horizon_supports(durations, counts, feet, zmp, sample_time, horizon, length, width):
    """Per sample ``j`` of the horizon (its end, ``(j + 1) T`` nominal), from the segments
    (:func:`packed_segments`): the support half-planes ``H (z − anchor) ≤ h`` as ``MAX_EDGES`` rows
    (those beyond the hull's edges: zero normal, ``h = ∞``) of the soles ``length × width``, the
    anchor ``offset + S F``, and the reference ZMP at the fraction ``s`` of the segment from its
    ``zmp_from`` to its ``zmp_to``. Returns ``(H, h, anchor_S, anchor_offset, zmp_ref_S,
    zmp_ref_offset)`` (``SampleSupports``). In double support towards a foot that is still a decision
    variable, the hull would not be linear in it: the ZMP is kept in the rear foot for the first
    half, in the front one after (a subset of the hull). Compiled: per sample and per segment,
    Python's and numpy's calls cost more than the arithmetic."""
    N = horizon
    H, h = np.zeros((N, MAX_EDGES, 2)), np.full((N, MAX_EDGES), np.inf)
    anchor_S, anchor_offset = np.empty((N, 2, 4)), np.empty((N, 2))
    ref_S, ref_offset = np.empty((N, 2, 4)), np.empty((N, 2))
    k, start, last = 0, 0.0, durations.size - 1
    piece_k, piece_second = -1, False  # the (segment, half) whose polygon is in piece_H, piece_h
    piece_H, piece_h = np.zeros((0, 2)), np.zeros(0)
    anchor = feet[0, 0]
    for j in range(N):
        t = (j + 1) * sample_time
        while k < last and t > start + durations[k] + 1e-9:
            start += durations[k]
            k += 1
        d = durations[k]
        s = 1.0 if not math.isfinite(d) or d == 0 else (t - start) / d
        s = min(max(s, 0.0), 1.0)
        second = s >= 0.5
        if k != piece_k or second != piece_second:
            piece_k, piece_second = k, second
            n, first = counts[k], 0
            if n == 2 and (feet[k, 0, 3:] != feet[k, 1, 3:]).any():
                n, first = 1, (1 if second else 0)
            anchor = feet[k, first]
            soles = np.empty((n, 3))
            soles[0, 0], soles[0, 1], soles[0, 2] = 0.0, 0.0, anchor[2]
            for i in range(1, n):
                soles[i, 0], soles[i, 1] = feet[k, i, 0] - anchor[0], feet[k, i, 1] - anchor[1]
                soles[i, 2] = feet[k, i, 2]
            piece_H, piece_h = sole_halfplanes(soles, length, width)
        H[j, :piece_h.size] = piece_H
        h[j, :piece_h.size] = piece_h
        for r in range(2):
            anchor_offset[j, r] = anchor[r]
            ref_offset[j, r] = (1 - s) * zmp[k, 0, r] + s * zmp[k, 1, r]
            for c in range(4):
                anchor_S[j, r, c] = anchor[3 + 4 * r + c]
                ref_S[j, r, c] = (1 - s) * zmp[k, 0, 3 + 4 * r + c] + s * zmp[k, 1, 3 + 4 * r + c]
    return H, h, anchor_S, anchor_offset, ref_S, ref_offset
