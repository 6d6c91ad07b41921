"""The support segments of the pattern generator's horizon: which feet carry the robot, for how
long, and where the ZMP reference moves; the support polygon of a segment as half-planes, and the
swing foot's path between two segments (for the dynamic filter's preview). World frame."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from robot_ctrl.geometry import rotation, wrap_angle
from robot_ctrl.geometry.support_polygon import SupportPolygon
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


def swing_point(segments: list[Segment], k: int, side: str, F: np.ndarray, s: float, apex: float,
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


def support_halfplanes(seg: Segment, s: float, half: np.ndarray) -> tuple[np.ndarray, np.ndarray, FootRef]:
    """Support half-planes ``H (z − anchor) ≤ h`` of a segment at fraction ``s`` of it, as
    ``MAX_EDGES`` rows (those beyond the hull's edges: zero normal, ``h = ∞``)."""
    if len(seg.feet) == 2 and not seg.feet[0].same_anchor(seg.feet[1]):
        # Double support towards a foot that is still a decision variable: the hull would not be
        # linear in it, so the ZMP is kept in the rear foot for the first half, in the front one after
        # (a subset of the hull).
        feet = [seg.feet[0] if s < 0.5 else seg.feet[1]]
    else:
        feet = seg.feet
    anchor = feet[0]
    soles = ((0.0, 0.0, anchor.yaw), *((*(f.offset - anchor.offset).tolist(), f.yaw) for f in feet[1:]))
    H, h = _halfplanes(soles, 2 * float(half[0]), 2 * float(half[1]))
    return H, h, anchor


@lru_cache(maxsize=256)
def _halfplanes(soles: tuple[tuple[float, float, float], ...], length: float, width: float):
    """Half-planes of the soles' hull, (x, y, yaw) each relative to the anchor, padded to
    ``MAX_EDGES``: the same few shapes recur sample after sample (one per stance and per double
    support), so they are computed once. Read-only: every caller shares them."""
    hull_H, hull_h = SupportPolygon.of_soles([((x, y), yaw) for x, y, yaw in soles], length, width).halfplanes
    H, h = np.zeros((MAX_EDGES, 2)), np.full(MAX_EDGES, np.inf)
    H[: len(hull_h)], h[: len(hull_h)] = hull_H, hull_h
    H.flags.writeable = h.flags.writeable = False
    return H, h
