"""SupportPolygon: convex support regions as half-planes ``H p ≤ h`` (world frame, m)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numba import njit


def sole_corners(center, yaw: float, length: float, width: float) -> list[tuple[float, float]]:
    """The four corners of a sole rectangle centred at ``center`` (2,) with heading ``yaw``,
    counter-clockwise from the front left. Plain floats: numpy costs more than the arithmetic
    on arrays this small (the estimator builds a polygon every tick, the MPC one per sample)."""
    cx, cy = float(center[0]), float(center[1])
    c, s = math.cos(yaw), math.sin(yaw)
    hl, hw = 0.5 * length, 0.5 * width
    return [(cx + c * x - s * y, cy + s * x + c * y) for x, y in ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))]


#: Turns smaller than this (cross product of the two edges, m²) count as straight: with edges of
#: sole size (0.1 m and more), a vertex within about 1e-11 m of its neighbours' line, or of a
#: neighbour, is dropped, so that no edge is too short for its normal to be computed.
COLLINEAR = 1e-12


def convex_hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Counter-clockwise convex hull of 2D points (Andrew's monotone chain)."""
    pts = sorted(points)
    if len(pts) <= 2:
        return pts

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= COLLINEAR:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= COLLINEAR:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


@dataclass(frozen=True)
class SupportPolygon:
    """Convex polygon given by its counter-clockwise vertices; ``H p ≤ h`` inside."""

    vertices: np.ndarray  # (k, 2)

    @classmethod
    def of_soles(cls, soles: list[tuple[np.ndarray, float]], length: float, width: float) -> "SupportPolygon":
        """Convex hull of sole rectangles given as (centre (2,), yaw)."""
        if len(soles) == 1:  # a rectangle's corners are already in counter-clockwise order
            return cls(np.array(sole_corners(soles[0][0], soles[0][1], length, width)))
        return cls(np.array(convex_hull([p for c, yaw in soles for p in sole_corners(c, yaw, length, width)])))

    @cached_property
    def halfplanes(self) -> tuple[np.ndarray, np.ndarray]:
        v = self.vertices.tolist()
        normals, offsets = [], []
        for (ax, ay), (bx, by) in zip(v, v[1:] + v[:1]):
            nx, ny = by - ay, ax - bx  # (dy, −dx) of the edge: outward for CCW order
            norm = math.sqrt(nx * nx + ny * ny)
            nx, ny = nx / norm, ny / norm
            normals.append((nx, ny))
            offsets.append(nx * ax + ny * ay)
        return np.array(normals), np.array(offsets)

    def contains(self, p: np.ndarray, tol: float = 1e-9) -> bool:
        return _contains(self.vertices, p, tol)

    def clamp(self, p: np.ndarray) -> np.ndarray:
        """``p`` (2,) if inside, else the closest point of the boundary."""
        return p if _contains(self.vertices, p, 1e-9) else _closest_boundary_point(self.vertices, p)

    def distance_inside(self, p: np.ndarray) -> float:
        """Signed distance to the boundary: positive inside [m]."""
        H, h = self.halfplanes
        return float(np.min(h - H @ p))


# Compiled: the stabilizer asks them of a new polygon (the measured support) on every tick.
@njit(cache=True)
def _contains(vertices, p, tol):
    """``H p ≤ h + tol`` for every edge's outward unit normal (counter-clockwise ``vertices``)."""
    k = vertices.shape[0]
    for i in range(k):
        ax, ay = vertices[i]
        bx, by = vertices[(i + 1) % k]
        nx, ny = by - ay, ax - bx
        norm = math.sqrt(nx * nx + ny * ny)
        nx, ny = nx / norm, ny / norm
        if nx * p[0] + ny * p[1] > nx * ax + ny * ay + tol:
            return False
    return True


@njit(cache=True)
def _closest_boundary_point(vertices, p):
    """The point of the polygon's edges closest to ``p``."""
    k = vertices.shape[0]
    px, py = p[0], p[1]
    best, best_d = (px, py), np.inf
    for i in range(k):
        ax, ay = vertices[i]
        bx, by = vertices[(i + 1) % k]
        ex, ey = bx - ax, by - ay
        t = min(max(((px - ax) * ex + (py - ay) * ey) / max(ex * ex + ey * ey, 1e-12), 0.0), 1.0)
        cx, cy = ax + t * ex, ay + t * ey
        d = math.sqrt((px - cx) ** 2 + (py - cy) ** 2)
        if d < best_d:
            best, best_d = (cx, cy), d
    return np.array(best)
