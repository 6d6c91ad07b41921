"""Props: things placed in a simulated robot's world (the chest of drawers), through a small interface.

A prop is a picklable value (it crosses to the robot's process) that builds the robot's scene with
itself in it and, once that scene is compiled, its run-time part in the world. The MuJoCo backend
calls that part's three hooks and knows nothing else of the prop; what the prop measures reaches the
report through ``JointState.scene``, never the controller's commands.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import mujoco
import numpy as np

if TYPE_CHECKING:
    from robot_ctrl.robot.model import RobotModel


class PropInWorld(Protocol):
    """A prop in a compiled world, in the backend's process."""

    def place(self, d: mujoco.MjData, base_height: float) -> None:
        """Put the prop where it starts, the robot's base standing ``base_height`` [m] above the floor."""

    def before_period(self, d: mujoco.MjData) -> None:
        """What the prop does before each control period of the physics (move, switch constraints)."""

    def reading(self, d: mujoco.MjData) -> np.ndarray:
        """The prop's ground truth now, for ``JointState.scene``."""


class Prop(Protocol):
    """A prop's placement: how the scene is built with it, and its run-time part."""

    def scene_mjcf(self, robot: RobotModel) -> Path:
        """The robot's cached single-robot scene with the prop added (an MJCF file)."""

    def in_world(self, m: mujoco.MjModel, robot: RobotModel, prefix: str, start_xy_yaw: np.ndarray) -> PropInWorld:
        """The prop in the world compiled from :meth:`scene_mjcf`; ``prefix`` names the robot's bodies
        and joints there, ``start_xy_yaw`` its start pose (world x [m], y [m], yaw [rad])."""
