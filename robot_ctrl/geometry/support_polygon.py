"""SupportPolygon: convex support regions as half-planes ``H p ≤ h`` (world frame, m)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from robot_ctrl.kernels import FLOAT, MATRIX, VECTOR, kernel


def sole_corners(center, yaw: float, length: float, width: float) -> list[tuple[float, float]]:
    """The four corners of a sole rectangle centred at ``center`` (2,) with heading ``yaw``,
    counter-clockwise from the front left."""
    sole = np.array([[float(center[0]), float(center[1]), float(yaw)]])
    return [tuple(p) for p in _corners(sole, length, width).tolist()]


#: Turns smaller than this (cross product of the two edges, m²) count as straight: with edges of
#: sole size (0.1 m and more), a vertex within about 1e-11 m of its neighbours' line, or of a
#: neighbour, is dropped, so that no edge is too short for its normal to be computed.
COLLINEAR = 1e-12


def convex_hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Counter-clockwise convex hull of 2D points (Andrew's monotone chain)."""
    return [tuple(p) for p in _hull(np.array(points, dtype=float).reshape(-1, 2)).tolist()]


@dataclass(frozen=True)
class SupportPolygon:
    """Convex polygon given by its counter-clockwise vertices; ``H p ≤ h`` inside."""

    vertices: np.ndarray  # (k, 2)

    @classmethod
    def of_soles(cls, soles: list[tuple[np.ndarray, float]] | np.ndarray, length: float,
                 width: float) -> "SupportPolygon":
        """Convex hull of sole rectangles given as (centre (2,), yaw) pairs, or as the rows (x, y, yaw)
        of an array (k, 3)."""
        if not isinstance(soles, np.ndarray):
            soles = np.array([(float(c[0]), float(c[1]), float(yaw)) for c, yaw in soles])
        return cls(_sole_hull(soles, length, width))

    @cached_property
    def halfplanes(self) -> tuple[np.ndarray, np.ndarray]:
        return _halfplanes(self.vertices)

    def contains(self, p: np.ndarray, tol: float = 1e-9) -> bool:
        H, h = self.halfplanes
        return _inside(H, h, p, tol)

    def clamp(self, p: np.ndarray) -> np.ndarray:
        """``p`` (2,) if inside, else the closest point of the boundary."""
        return p if self.contains(p) else _closest_boundary_point(self.vertices, p)

    def distance_inside(self, p: np.ndarray) -> float:
        """Signed distance to the boundary: positive inside [m]."""
        H, h = self.halfplanes
        return float(np.min(h - H @ p))


# Compiled: the estimator builds a polygon, and the stabilizer asks it, on every tick.
@kernel((MATRIX,))
def _halfplanes(vertices):
    """``(H, h)``: each edge's outward unit normal (its (dy, −dx) for counter-clockwise
    ``vertices``) and offset, ``H p ≤ h`` inside."""
    k = vertices.shape[0]
    H, h = np.empty((k, 2)), np.empty(k)
    for i in range(k):
        ax, ay = vertices[i, 0], vertices[i, 1]
        bx, by = vertices[(i + 1) % k, 0], vertices[(i + 1) % k, 1]
        nx, ny = by - ay, ax - bx
        norm = math.sqrt(nx * nx + ny * ny)
        H[i, 0], H[i, 1] = nx / norm, ny / norm
        h[i] = H[i, 0] * ax + H[i, 1] * ay
    return H, h


@kernel((MATRIX, VECTOR, VECTOR, FLOAT))
def _inside(H, h, p, tol):
    """``H p ≤ h + tol``."""
    for i in range(h.size):
        if H[i, 0] * p[0] + H[i, 1] * p[1] > h[i] + tol:
            return False
    return True


@kernel()
def clamp_to_polygon(vertices, p):
    """:meth:`SupportPolygon.clamp` for compiled callers: ``p`` (2,) if it lies in the
    counter-clockwise polygon ``vertices`` (within 1e-9 m), else the closest point of its boundary."""
    H, h = _halfplanes(vertices)
    return p.copy() if _inside(H, h, p, 1e-9) else _closest_boundary_point(vertices, p)


@kernel((MATRIX, VECTOR))
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


@kernel((MATRIX,))
def _hull(points):
    """Counter-clockwise convex hull of ``points`` (n, 2) (Andrew's monotone chain): the points
    sorted by x then y, the lower chain, then the upper; a turn of at most ``COLLINEAR`` drops the
    middle vertex."""
    pts = points.copy()
    n = pts.shape[0]
    for i in range(1, n):  # insertion sort, lexicographic: a hull is of a few soles' corners
        x, y = pts[i, 0], pts[i, 1]
        j = i - 1
        while j >= 0 and (pts[j, 0] > x or (pts[j, 0] == x and pts[j, 1] > y)):
            pts[j + 1] = pts[j]
            j -= 1
        pts[j + 1, 0], pts[j + 1, 1] = x, y
    if n <= 2:
        return pts
    chain = np.empty((2 * n, 2))
    m = 0
    for half in range(2):
        start = m
        for k in range(n):
            i = k if half == 0 else n - 1 - k
            px, py = pts[i, 0], pts[i, 1]
            while m - start >= 2 and ((chain[m - 1, 0] - chain[m - 2, 0]) * (py - chain[m - 2, 1])
                                      - (chain[m - 1, 1] - chain[m - 2, 1]) * (px - chain[m - 2, 0])) <= COLLINEAR:
                m -= 1
            chain[m, 0], chain[m, 1] = px, py
            m += 1
        m -= 1  # each chain's last point starts the other
    return chain[:m].copy()


@kernel((MATRIX, FLOAT, FLOAT))
def _corners(soles, length, width):
    """The corners (4k, 2) of sole rectangles, ``soles`` (k, 3): centre x, y and yaw; each
    rectangle's four counter-clockwise from its front left."""
    hl, hw = 0.5 * length, 0.5 * width
    corners = np.empty((4 * soles.shape[0], 2))
    for k in range(soles.shape[0]):
        cx, cy = soles[k, 0], soles[k, 1]
        c, s = math.cos(soles[k, 2]), math.sin(soles[k, 2])
        for j, (x, y) in enumerate(((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))):
            corners[4 * k + j, 0], corners[4 * k + j, 1] = cx + c * x - s * y, cy + s * x + c * y
    return corners


@kernel()
def sole_halfplanes(soles, length, width):
    """Half-planes ``(H, h)`` of the hull of sole rectangles, ``soles`` (k, 3) as for
    :func:`_corners`: for other kernels (the walking MPC's supports)."""
    return _halfplanes(_sole_hull(soles, length, width))


@kernel((MATRIX, FLOAT, FLOAT))
def _sole_hull(soles, length, width):
    """Counter-clockwise hull of sole rectangles, ``soles`` (k, 3) as for :func:`_corners` (one
    rectangle: its corners, already in that order)."""
    corners = _corners(soles, length, width)
    return corners if soles.shape[0] == 1 else _hull(corners)
