"""SupportPolygon: convex support regions as half-planes ``H p ≤ h`` (world frame, m)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from robot_ctrl.wpg.footstep import rotation


_CLOCKWISE = np.array([[0.0, -1.0], [1.0, 0.0]])  # row vector (x, y) @ it = (y, −x)
_HALF_SOLE = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=float)


def sole_corners(center: np.ndarray, yaw: float, length: float, width: float) -> np.ndarray:
    """The four corners (4×2) of a sole rectangle centred at ``center`` with heading ``yaw``."""
    return center + (_HALF_SOLE * (0.5 * length, 0.5 * width)) @ rotation(yaw).T


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of 2D points (Andrew's monotone chain)."""
    pts = sorted(map(tuple, np.round(points, 12).tolist()))  # Python floats: fast in the loops below
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


@dataclass(frozen=True)
class SupportPolygon:
    """Convex polygon given by its counter-clockwise vertices; ``H p ≤ h`` inside."""

    vertices: np.ndarray  # (k, 2)

    @classmethod
    def of_soles(cls, soles: list[tuple[np.ndarray, float]], length: float, width: float) -> "SupportPolygon":
        """Convex hull of sole rectangles given as (centre (2,), yaw)."""
        if len(soles) == 1:  # a rectangle's corners are already in counter-clockwise order
            return cls(sole_corners(soles[0][0], soles[0][1], length, width))
        return cls(convex_hull(np.vstack([sole_corners(c, yaw, length, width) for c, yaw in soles])))

    @cached_property
    def halfplanes(self) -> tuple[np.ndarray, np.ndarray]:
        v = self.vertices
        edges = np.empty_like(v)
        edges[:-1] = v[1:] - v[:-1]
        edges[-1] = v[0] - v[-1]
        normals = edges @ _CLOCKWISE  # (dy, −dx): outward for CCW order
        normals /= np.sqrt((normals * normals).sum(axis=1))[:, None]
        return normals, (normals * v).sum(axis=1)

    def contains(self, p: np.ndarray, tol: float = 1e-9) -> bool:
        H, h = self.halfplanes
        return bool((H @ p <= h + tol).all())

    def distance_inside(self, p: np.ndarray) -> float:
        """Signed distance to the boundary: positive inside [m]."""
        H, h = self.halfplanes
        return float(np.min(h - H @ p))
