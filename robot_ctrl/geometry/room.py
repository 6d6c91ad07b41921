"""The drawer task in a room: where the cabinet stands, the room's walls, and the path the robot
walks from its start to the pose where the walk-and-reach synthesis takes over.

Frames (planar, metres, radians):

- the **start frame**: the start pelvis on the floor, x forward, y left;
- the **cabinet frame**: origin on the floor below the point of the closed front panel straight ahead
  of the standing pelvis (the drawer geometry's x = 0, y = 0), x pointing into the cabinet, y left.
  A cabinet whose front faces ``front_yaw`` has its x axis at ``front_yaw + π``.

The room is a rectangle square to the cabinet (furniture stands parallel to walls): ``depth`` along
the cabinet's x, ``width`` along its y; with ``against_wall`` the cabinet's back touches the wall
behind it, otherwise the room is centred on what it holds (the start, the cabinet, the walk in to it).

The path is the shortest one in the visibility graph of the cabinet's footprint grown by the robot's
radius (its corners, the start, the hand-over pose and a point ``LEAD_IN`` before it on the
cabinet's axis), inside the room shrunk by the same radius. The robot walks it as the walking stack
does well: it turns on the spot to face the next corner, walks straight to it, and comes in to the
hand-over pose along the cabinet's axis, facing the cabinet.

When the cabinet moves (a goal jump in a room), the room stays where it was placed for the first
pose (:class:`PlacedRoom`, a box of that pose's frame) and the path is planned again from where the
robot is to the moved cabinet's front.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from robot_ctrl.geometry.frames import rotation, wrap_angle

LEAD_IN = 0.6  # [m] the last straight stretch, along the cabinet's axis, into the hand-over pose
AXIS_ANGLE = np.radians(25.0)  # a path may come into the hand-over pose this far off the cabinet's axis
CORNER_OFFSET = 0.03  # [m] a path's corner keeps this clear of the grown footprint's corner
NEAREST, FARTHEST = 1.2, 6.0  # [m] of the front panel from the start
WALL_THICKNESS = 0.1  # [m]


@dataclass(frozen=True)
class CabinetPose:
    """The cabinet in the start frame: the frame's origin (x, y) [m] and the direction its front
    faces, ``front_yaw`` [rad] (π: facing the robot's start)."""

    x: float
    y: float
    front_yaw: float

    def __str__(self) -> str:
        """As the command line gives it: X,Y,YAW_DEG."""
        return f"{self.x:g},{self.y:g},{np.degrees(self.front_yaw):g}"

    @property
    def yaw(self) -> float:
        """Heading of the cabinet frame's x axis (into the cabinet) [rad]."""
        return wrap_angle(self.front_yaw + np.pi)

    def to_start(self, p: np.ndarray) -> np.ndarray:
        """Point(s) (..., 2) of the cabinet frame in the start frame."""
        return np.asarray(p, float) @ rotation(self.yaw).T + [self.x, self.y]

    def from_start(self, p: np.ndarray) -> np.ndarray:
        """Point(s) (..., 2) of the start frame in the cabinet frame."""
        return (np.asarray(p, float) - [self.x, self.y]) @ rotation(self.yaw)

    @property
    def straight_ahead(self) -> bool:
        """Straight ahead of the start, facing it: the task without a room (``--distance``)."""
        return self.y == 0.0 and self.x > 0.0 and abs(wrap_angle(self.front_yaw - np.pi)) < 1e-12


@dataclass(frozen=True)
class CabinetMove:
    """A goal jump in a room: at ``time`` [s] the cabinet stands at ``pose`` instead (start frame)."""

    time: float
    pose: CabinetPose


@dataclass(frozen=True)
class Room:
    """``width`` [m] along the cabinet's front, ``depth`` [m] along the way it faces; its back against
    the wall behind it (``against_wall``) or standing free."""

    width: float = 6.0
    depth: float = 6.0
    against_wall: bool = True


@dataclass(frozen=True)
class Box:
    """An axis-aligned rectangle of the cabinet frame: x in [x0, x1], y in [y0, y1] [m]."""

    x0: float
    x1: float
    y0: float
    y1: float

    def grown(self, r: float) -> "Box":
        return Box(self.x0 - r, self.x1 + r, self.y0 - r, self.y1 + r)

    def contains(self, p: np.ndarray) -> bool:
        x, y = p
        return self.x0 <= x <= self.x1 and self.y0 <= y <= self.y1

    def corners(self) -> np.ndarray:
        return np.array([[self.x0, self.y0], [self.x1, self.y0], [self.x1, self.y1], [self.x0, self.y1]])

    def crosses(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the segment a-b passes through the open rectangle (slab test; touching its
        boundary does not count)."""
        d = b - a
        lo, hi = 0.0, 1.0
        for k, (low, high) in enumerate(((self.x0, self.x1), (self.y0, self.y1))):
            if abs(d[k]) < 1e-12:
                if not low < a[k] < high:
                    return False
                continue
            t0, t1 = (low - a[k]) / d[k], (high - a[k]) / d[k]
            lo, hi = max(lo, min(t0, t1)), min(hi, max(t0, t1))
        return hi - lo > 1e-9


@dataclass(frozen=True)
class Wall:
    """One wall, start frame: the middle (x, y) [m] of the box ``WALL_THICKNESS`` thick whose inner face
    bounds the room, the heading [rad] of that face and its length [m] (corners included)."""

    x: float
    y: float
    yaw: float
    length: float


@dataclass(frozen=True)
class PlacedRoom:
    """A room as it stands: its inside, ``interior``, a box of ``frame`` (the frame of the cabinet
    pose it was placed for, which a moved cabinet leaves behind)."""

    frame: CabinetPose
    interior: Box

    def holds(self, p: np.ndarray, margin: float) -> bool:
        """Whether the start-frame point ``p`` is inside, ``margin`` [m] from every wall."""
        return self.interior.grown(-margin).contains(self.frame.from_start(p))


@dataclass(frozen=True)
class Approach:
    """The plan to the hand-over: ``waypoints`` (n, 2) [m] from the start to the hand-over pose
    (start frame), ``handover`` (x, y, yaw) [m, rad] the pelvis pose (start frame) facing the cabinet
    ``handover_distance`` [m] in front of its panel, the room's ``walls`` and where it stands."""

    waypoints: np.ndarray
    handover: np.ndarray
    handover_distance: float
    walls: tuple[Wall, ...]
    room: PlacedRoom

    @property
    def interior(self) -> Box:
        """The room's inside, a box of ``room.frame`` (the planned cabinet's frame, unless it moved)."""
        return self.room.interior

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.waypoints, axis=0), axis=1).sum())

    @property
    def walks(self) -> bool:
        """Whether the robot walks to the hand-over before the sequence (not when it starts there)."""
        return len(self.waypoints) > 1


def room_interior(room: Room, cabinet: CabinetPose, footprint: Box, start: np.ndarray, walk_in: float) -> Box:
    """The room's inside in the cabinet frame, placed as :class:`Room` says, for a robot starting
    at ``start`` (start frame) and walking in to the cabinet from ``walk_in`` [m] in front of it: centred
    on what it holds (the start, the cabinet, the walk in), its back against the cabinet's if so."""
    s = cabinet.from_start(start)
    cy = 0.5 * (min(s[1], footprint.y0) + max(s[1], footprint.y1))
    if room.against_wall:
        x1 = footprint.x1
        return Box(x1 - room.depth, x1, cy - room.width / 2, cy + room.width / 2)
    cx = 0.5 * (min(s[0], -walk_in) + max(s[0], footprint.x1))
    return Box(cx - room.depth / 2, cx + room.depth / 2, cy - room.width / 2, cy + room.width / 2)


def room_walls(interior: Box, cabinet: CabinetPose) -> tuple[Wall, ...]:
    """The four walls round ``interior`` (cabinet frame), in the start frame."""
    b, t = interior, WALL_THICKNESS / 2
    lines = [((b.x0 - t, (b.y0 + b.y1) / 2), np.pi / 2, b.y1 - b.y0 + 4 * t),
             ((b.x1 + t, (b.y0 + b.y1) / 2), np.pi / 2, b.y1 - b.y0 + 4 * t),
             (((b.x0 + b.x1) / 2, b.y0 - t), 0.0, b.x1 - b.x0 + 4 * t),
             (((b.x0 + b.x1) / 2, b.y1 + t), 0.0, b.x1 - b.x0 + 4 * t)]
    walls = []
    for mid, yaw, length in lines:
        x, y = cabinet.to_start(np.array(mid))
        walls.append(Wall(float(x), float(y), wrap_angle(cabinet.yaw + yaw), float(length)))
    return tuple(walls)


def handover_pose(cabinet: CabinetPose, distance: float) -> np.ndarray:
    """The pelvis pose (x, y, yaw) [m, rad] (start frame) on the cabinet's axis ``distance`` [m] in
    front of its panel, facing it."""
    x, y = cabinet.to_start(np.array([-distance, 0.0]))
    return np.array([x, y, cabinet.yaw])


def plan_approach(cabinet: CabinetPose, footprint: Box, room: Room, radius: float, handover_distance: float,
                  start=(0.0, 0.0), placed: PlacedRoom | None = None) -> Approach:
    """The path from ``start`` (start frame) to the pelvis ``handover_distance`` [m] in front of the
    cabinet's panel on its axis, facing it, clear by ``radius`` [m] of the cabinet's ``footprint``
    (cabinet frame: the cabinet with its open drawer and handle) and of the walls; a cabinet straight
    ahead of the start, facing it, is walked to by the sequence itself (a one-point path). The room
    is placed as ``room`` says round the cabinet, or stands where it was (``placed``: the cabinet has
    moved, the robot is at ``start``). Raises ValueError saying why when there is none (too near or
    far from the start frame's origin, overlapping, no room, no way)."""
    start = np.asarray(start, float)
    distance = float(np.hypot(cabinet.x, cabinet.y))
    if not NEAREST <= distance <= FARTHEST:
        raise ValueError(f"the front panel is {distance:.2f} m from the start: allowed {NEAREST}-{FARTHEST} m")
    obstacle = footprint.grown(radius)
    s = cabinet.from_start(start)
    if obstacle.contains(s):
        raise ValueError(f"the cabinet overlaps the robot's {'start' if placed is None else 'path'} "
                         f"(it needs {radius:.2f} m round it)")
    if placed is None:
        placed = PlacedRoom(cabinet, room_interior(room, cabinet, footprint, start, handover_distance + LEAD_IN))
        if not placed.holds(start, radius):
            raise ValueError(f"the start is not inside the {room.width:g} x {room.depth:g} m room "
                             f"({'its back against the wall' if room.against_wall else 'free-standing'}) with "
                             f"{radius:.2f} m to the walls: a larger --room, or the cabinet elsewhere")
        if cabinet.straight_ahead:  # the sequence takes over where the robot stands
            return Approach(start[None, :], np.array([*start, 0.0]), float(-s[0]),
                            room_walls(placed.interior, cabinet), placed)
    elif not all(placed.holds(c, 0.0) for c in cabinet.to_start(footprint.corners())):
        raise ValueError("the cabinet does not fit inside the room where it stands")

    def free(p: np.ndarray) -> bool:  # a cabinet-frame point the robot's pelvis may be at
        return placed.holds(cabinet.to_start(p), radius)

    goal = np.array([-handover_distance, 0.0])
    if not free(goal):
        raise ValueError(f"the room leaves no {handover_distance:.2f} m in front of the cabinet to walk in from")
    lead_in = goal - [LEAD_IN, 0.0]
    nodes = [s, goal] + ([lead_in] if free(lead_in) else [])
    out = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * CORNER_OFFSET
    nodes += [c for c in obstacle.corners() + out if free(c)]

    def edge(i: int, j: int) -> bool:  # the room is convex: a segment between two free points stays in it
        a, b = nodes[i], nodes[j]
        if obstacle.crosses(a, b):
            return False
        if j == 1:  # into the hand-over pose: along the cabinet's axis
            d = b - a
            return abs(np.arctan2(d[1], d[0])) <= AXIS_ANGLE + 1e-9
        return True

    best = {0: 0.0}
    previous: dict[int, int] = {}
    queue = [(0.0, 0)]
    while queue:
        cost, i = heapq.heappop(queue)
        if i == 1:
            break
        if cost > best[i]:
            continue
        for j in range(len(nodes)):
            if j != i and edge(i, j):
                c = cost + float(np.linalg.norm(nodes[j] - nodes[i]))
                if c < best.get(j, np.inf) - 1e-12:
                    best[j], previous[j] = c, i
                    heapq.heappush(queue, (c, j))
    if 1 not in best:
        raise ValueError("no way round the cabinet to its front inside the room")
    path, i = [1], 1
    while i != 0:
        i = previous[i]
        path.append(i)
    local = np.array([nodes[i] for i in reversed(path)])
    waypoints = cabinet.to_start(local)
    waypoints[0] = start
    return Approach(waypoints, handover_pose(cabinet, handover_distance), handover_distance,
                    room_walls(placed.interior, placed.frame), placed)


def check_move(first: Approach, pose: CabinetPose, footprint: Box, radius: float) -> Approach:
    """The approach from the start to the cabinet moved to ``pose`` inside the room that ``first``
    placed: what a goal jump must allow, the cabinet (grown by ``radius``) off the path walked to it
    first, inside the room, with a way to its front. ValueError saying why not."""
    path = pose.from_start(first.waypoints)
    grown = footprint.grown(radius)
    if any(grown.contains(a) or grown.crosses(a, b) for a, b in zip(path, path[1:])):
        raise ValueError(f"the cabinet would land on the robot's path (it needs {radius:.2f} m round it)")
    return plan_approach(pose, footprint, Room(), radius, first.handover_distance, placed=first.room)
