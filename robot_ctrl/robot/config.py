"""Robot configuration: the immutable description of a robot, as ``configs/robots/<name>.yaml``
states it (read and checked by :mod:`robot_ctrl.robot.config_file`).

Everything here is static data (frames, posture, gains, limits). Mutable state lives elsewhere.
Units are SI; angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping

from robot_ctrl.geometry import Side
from robot_ctrl.geometry.drawer_geometry import DrawerGeometry
from robot_ctrl.modes import FilterMode


class ConfigError(ValueError):
    """A configuration file is missing, malformed or out of range. The message names the field."""


@dataclass(frozen=True)
class FootGeometry:
    """Sole rectangle in the sole frame (x forward, y left) [m]. ``box_height``: when set, the foot's
    collision geometry from the URDF is replaced at conversion by a box of the sole rectangle, this
    tall, its bottom face on the sole frame (for URDFs whose feet are meshes or a few spheres)."""

    length: float
    width: float
    center_offset: tuple[float, float]
    box_height: float | None = None


@dataclass(frozen=True)
class AddedFrame:
    """An operational frame the URDF lacks (a sole under an ankle link), fixed to a link: its
    position ``xyz`` [m] and orientation ``rpy`` [rad] in that link's frame."""

    name: str
    parent: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ServoGains:
    """Position-servo gain rule: kp = kp_per_effort * effort limit, kd from a damping ratio."""

    kp_per_effort: float
    damping_ratio: float
    # "srdf", one rotor inertia reflected to the joint for every joint, or one per joint [kg·m²]
    armature: str | float | Mapping[str, float]


#: Walking speed of a robot whose config gives none (``walking.speed``) [m/s].
DEFAULT_WALKING_SPEED = 0.25

#: The joint roles a robot config names per side (``joints:``).
JOINT_ROLES = ("ankle_pitch", "elbows")
#: Roles only the walk-and-reach task needs: a robot without them runs everything else. The arm's
#: shoulder, elbow and wrist joints measure its length (the demonstrations' comfort distance).
REACH_ROLES = ("grippers", "shoulders", "wrists")


@dataclass(frozen=True)
class GaitSwing:
    """One joint's share of the walking demonstrations' upper-body motion: ``amplitude`` [rad] of a
    ``waveform`` (``swing``: once per gait cycle; ``bob``: twice) shifted by ``phase`` [rad]."""

    joint: str
    amplitude: float
    waveform: str
    phase: float


@dataclass(frozen=True)
class Grippers:
    """How the walk-and-reach task's gripper joints (``joints.grippers``) close: per side, toward the
    joint's ``upper`` or ``lower`` limit; ``opening`` [rad]: how far from there a gripper opens to
    take the handle."""

    closes_toward: Mapping[str, str]
    opening: float
    # The left hand frame's orientation at the handle, as roll, pitch, yaw [rad] in the task's frame
    # (x toward the drawer, z up); None: left to the synthesized posture.
    hand_rpy: tuple[float, float, float] | None = None
    # True: the hand holds the handle as a hook, its fingers open behind the bar (their open limit
    # takes the pull); False: the gripper closes round the bar.
    hook: bool = False

    def closing_sign(self, side: Side) -> float:
        """+1 where the gripper closes toward its upper limit, -1 toward its lower."""
        return 1.0 if self.closes_toward[side] == "upper" else -1.0


#: A gripper that closes toward its upper limit and opens 0.25 rad to take the handle (Talos's).
DEFAULT_GRIPPERS = Grippers({"left": "upper", "right": "upper"}, 0.25)


@dataclass(frozen=True)
class RobotConfig:
    """Static description of one robot (see ``configs/robots/talos.yaml`` for the fields)."""

    name: str
    package_dir: str
    urdf: str
    srdf: str | None  # None: self-collision exclusions are computed (robot_ctrl.robot.self_collision)
    base_link: str
    added_frames: tuple[AddedFrame, ...]
    feet: Mapping[str, str]  # side ("left"/"right") -> sole frame
    hands: Mapping[str, str]  # side -> hand frame
    torso: str
    waist: str
    joint_roles: Mapping[str, Mapping[str, str]]  # role (JOINT_ROLES, REACH_ROLES) -> side -> joint
    foot: FootGeometry
    joint_names: tuple[str, ...]  # the robot's joint order for every hardware array
    half_sitting: tuple[float, ...]  # [rad], in joint_names order
    servo: ServoGains
    position_margin: float  # [rad]
    velocity_fraction: float
    acceleration_fraction: float | None  # of the effort limit the IK may spend accelerating a joint; None: unbounded
    braking_fraction: float | None  # of the effort limit the IK brakes a joint with before a soft limit; None: as above
    max_gain_ratio: float  # the largest kp and kd a command may carry, over the default gains
    servo_torque_fraction: float | None  # of the effort limit an upper-body command may demand; None: unbounded
    timestep: float  # [s] physics step of the simulation backend
    walking: Mapping[str, Any]  # WalkParams fields this robot's size calls for (robot_ctrl.wpg.params)
    stabilizer: Mapping[str, Any]  # StabilizerGains fields this robot calls for (robot_ctrl.control.controllers.stabilizer)
    gait_swing: tuple[GaitSwing, ...]  # the walking demonstrations' upper-body motion
    walking_speed: float = DEFAULT_WALKING_SPEED  # [m/s] the walk's default speed (``walking.speed``)
    grippers: Grippers = DEFAULT_GRIPPERS  # how the walk-and-reach task's grippers close (``grasp:``)
    # The walk-and-reach task at this robot's size (``drawer.scale``, Talos 1): the cabinet, and the
    # demonstrations' gait lengths (robot_ctrl/synthesis/demonstrations.py)
    drawer_scale: float = 1.0
    # Where this robot's hand holds the handle, at its own size (``drawer.handle_grip``,
    # ``drawer.bar_from_grip`` [m]); None: the scaled cabinet's
    drawer_grip: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    drawer_dynfilter: FilterMode = FilterMode.FULL  # the drawer task's default dynamic filter (``drawer.dynfilter``)
    # joint -> (lower, upper) [rad]: ranges the IK keeps narrower than the URDF's (``limits.ik_ranges``)
    ik_ranges: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    # Links the simulation leaves without collision geometry (``simulation.links_without_collision``)
    links_without_collision: tuple[str, ...] = ()

    @property
    def drawer(self) -> DrawerGeometry:
        """The walk-and-reach task's cabinet at this robot's size."""
        geometry = DrawerGeometry().scaled(self.drawer_scale)
        if self.drawer_grip is None:
            return geometry
        return replace(geometry, handle_grip=self.drawer_grip[0], bar_from_grip=self.drawer_grip[1])

    @property
    def frames(self) -> dict[str, str]:
        """Every named operational frame: ``left_foot``, ``right_hand``, ``torso``, ``waist``..."""
        out = {f"{side}_foot": f for side, f in self.feet.items()}
        out.update({f"{side}_hand": f for side, f in self.hands.items()})
        out.update(torso=self.torso, waist=self.waist)
        return out

    def joint_index(self, role: str, side: Side) -> int:
        """Index (in ``joint_names``) of the joint with ``role`` on ``side``, e.g. the left gripper."""
        return self.joint_names.index(self.joint_roles[role][side])

    def require_reach(self, command: str) -> None:
        """Refuse the walk-and-reach task for a robot whose config does not name the joints it needs
        (``REACH_ROLES``): a ConfigError that says which."""
        missing = [role for role in REACH_ROLES if role not in self.joint_roles]
        if missing:
            roles = ", ".join(f"joints.{r}" for r in missing)
            raise ConfigError(f"{command}: robot {self.name} names no {roles} in its config: the walk-and-reach task "
                              "needs a gripper that closes round the drawer's handle")
