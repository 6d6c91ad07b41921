"""DrawerTargets: where the walk-and-reach task's targets are in the world, as the robot knows them.

The drawer's geometry (:class:`~robot_ctrl.geometry.drawer_geometry.DrawerGeometry`) is in the frame of the
pelvis standing at the comfort distance; the cabinet stands ``distance(t)`` ahead of the start pose
(goal jumps move it), its heights are from the standing pelvis's. These are the task's given
targets (the robot has no perception); how far the drawer is open, the robot measures with its hand.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from robot_ctrl.geometry import rotation
from robot_ctrl.geometry.drawer_geometry import DrawerGeometry, scheduled_at
from robot_ctrl.synthesis.synthesizer import GoalJump


@dataclass(frozen=True)
class DrawerTargets:
    start_pose: Callable[[], np.ndarray]  # world (x, y, yaw) of the base at the start, as the robot now knows it
    pelvis_height: float  # [m] of the standing pelvis above the floor
    distance0: float  # [m] closed front panel from the start pelvis along the start heading
    slot: str
    jumps: tuple[GoalJump, ...] = ()
    geometry: DrawerGeometry = field(default_factory=DrawerGeometry)

    @property
    def start(self) -> np.ndarray:
        """World (x, y, yaw) of the base at the start: the task's frame."""
        return self.start_pose()

    @property
    def forward(self) -> np.ndarray:
        """The start heading, a world-frame unit vector (3,)."""
        return np.array([np.cos(self.start[2]), np.sin(self.start[2]), 0.0])

    def distance(self, t: float) -> float:
        """The front panel's distance from the start pelvis at time ``t`` [s]."""
        return scheduled_at(self.distance0, [(j.time, j.distance) for j in self.jumps], t)

    def world(self, x: float, y: float, z: float) -> np.ndarray:
        """A point of the start frame (x along the heading, y left, z above the floor) in the world."""
        start = self.start
        return np.array([*(start[:2] + rotation(start[2]) @ [x, y]), z])

    def advance(self, xy: np.ndarray) -> float:
        """How far the world point ``xy`` is ahead of the start along its heading [m]."""
        start = self.start
        return float((np.asarray(xy)[:2] - start[:2]) @ rotation(start[2])[:, 0])

    def handle(self, t: float) -> np.ndarray:
        """Where the left gripper base holds the closed drawer's handle (world) [m]."""
        g = self.geometry.handle_grip
        return self.world(self.distance(t) + g[0], g[1], self.pelvis_height + g[2])

    def object(self, t: float, opening: float) -> np.ndarray:
        """Where the right gripper base reaches the object with the drawer ``opening`` open (world) [m]."""
        o = self.geometry.object_in_drawer(self.slot)
        return self.world(self.distance(t) + o[0] - opening, o[1], self.pelvis_height + o[2])

    @property
    def opening(self) -> float:
        """How far the task pulls the drawer [m]."""
        return self.geometry.opening(self.slot)
