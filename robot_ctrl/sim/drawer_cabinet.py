"""The chest of drawers of the walk-and-reach task, in the MuJoCo world.

Built from :class:`~robot_ctrl.geometry.drawer_geometry.DrawerGeometry` (the numbers the demonstrations
use) onto the robot's cached scene, and cached in turn. The cabinet is a mocap body, so that one
scene serves every distance: :class:`DrawerCabinet` places it at run time ``distance`` ahead of the
robot's start pose along its start heading, with the drawer's panel at the standing pelvis height
as the geometry's frame says, and moves it when a goal jump is due. The drawer slides on a joint
(0 closed .. ``travel`` open, toward the robot) with viscous damping and dry friction, so pulling it
takes a real force; a loose dowel of the geometry's mass stands in each of the four slots.

Everything collides: the robot touches the cabinet, its drawer, the handle and the dowels as it
would touch furniture. Nothing ties the robot to the world: the hand holds the handle by its
fingers' contacts and their friction alone. Friction cones are elliptic with ``IMPRATIO``
(MuJoCo's ``option/impratio``), which makes friction grasps hold without raising μ. What the cabinet
reports (``DRAWER_READINGS``) is measured from the physics' contacts and bodies.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from robot_ctrl import __version__
from robot_ctrl.geometry import Side, absolute_pose, other
from robot_ctrl.geometry.drawer_geometry import DRAWER_READINGS, SLOTS, DrawerGeometry, scheduled_at
from robot_ctrl.geometry.room import WALL_THICKNESS, Wall
from robot_ctrl.sim.contacts import geoms_of_bodies, robot_contacts, subtree

if TYPE_CHECKING:
    from robot_ctrl.robot.model import RobotModel

GRASP_SIDE: Side = "left"
IMPRATIO = 10.0  # frictional to normal constraint impedance (MuJoCo's option/impratio)
WALLS = 4
WALL_HEIGHT = 1.0  # [m] low enough for the cameras to film over


@dataclass(frozen=True)
class DrawerPlacement:
    """Where the cabinet stands: its closed drawer's front panel ``distance`` [m] ahead of the
    robot's start pelvis along the start heading (in a room: ahead of ``frame``, the pose where the
    synthesis takes over, in the start frame); ``jumps``: (time [s], new distance [m]) at which
    it is moved (thesis Fig. 3.39), in a room ``moves``: (time [s], new frame); ``slot``: the
    object the right hand reaches for; ``geometry``: the cabinet, by default the robot's (its
    config's ``drawer:``)."""

    distance: float
    slot: str = "front_left"
    jumps: tuple[tuple[float, float], ...] = ()
    geometry: DrawerGeometry | None = None
    frame: tuple[float, float, float] = (0.0, 0.0, 0.0)  # start-frame pose (x, y, yaw) the distance is along
    walls: tuple[Wall, ...] = ()  # the room's, start frame (none: an open floor)
    moves: tuple[tuple[float, tuple[float, float, float]], ...] = ()  # in a room: (time [s], the frame from then on)

    def distance_at(self, t: float) -> float:
        return scheduled_at(self.distance, self.jumps, t)

    def frame_at(self, t: float) -> tuple[float, float, float]:
        return scheduled_at(self.frame, self.moves, t)

    # The prop interface (``sim/prop.py``) ------------------------------------------------------
    def scene_mjcf(self, robot: RobotModel) -> Path:
        return drawer_scene_mjcf(robot.mjcf_path, self.geometry or robot.config.drawer)

    def in_world(self, m: mujoco.MjModel, robot: RobotModel, prefix: str, start_xy_yaw: np.ndarray) -> DrawerCabinet:
        return DrawerCabinet(m, self, self.geometry or robot.config.drawer, prefix, start_xy_yaw, robot.config.hands)


def _box(body, name: str, lo, hi, rgba) -> None:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=(hi - lo) / 2, pos=(hi + lo) / 2, rgba=rgba)


def add_cabinet(spec: mujoco.MjSpec, geometry: DrawerGeometry) -> None:
    """The cabinet (mocap body ``cabinet``), its drawer on the slide ``drawer_slide`` with the handle
    (geoms ``handle_*``), the sites ``handle_grip`` and ``slot_<slot>``, and a loose dowel
    ``object_<slot>`` per slot (placed at run time). Frame of the cabinet body: the pelvis-at-comfort
    frame of the geometry, moved so that the closed panel is at x = 0."""
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = IMPRATIO
    g = geometry
    wood, dark, metal = [0.62, 0.45, 0.3, 1], [0.45, 0.32, 0.2, 1], [0.75, 0.75, 0.78, 1]
    cabinet = spec.worldbody.add_body(name="cabinet", mocap=True)
    y0, y1 = g.drawer_y
    z_top = g.front_panel_z[1] + 0.03
    floor = -1.0  # the parts standing on the floor are stretched down to it when placed (pelvis height)
    _box(cabinet, "cabinet_left", [0.0, y1 + 0.005, floor], [g.cabinet_depth, y1 + 0.025, z_top], wood)
    _box(cabinet, "cabinet_right", [0.0, y0 - 0.025, floor], [g.cabinet_depth, y0 - 0.005, z_top], wood)
    _box(cabinet, "cabinet_top", [0.0, y0 - 0.025, z_top], [g.cabinet_depth, y1 + 0.025, z_top + 0.025], wood)
    _box(cabinet, "cabinet_back", [g.cabinet_depth - 0.02, y0 - 0.005, floor], [g.cabinet_depth, y1 + 0.005, z_top],
         wood)
    _box(cabinet, "cabinet_base", [0.0, y0 - 0.005, floor], [g.cabinet_depth - 0.02, y1 + 0.005,
                                                              g.front_panel_z[0] - 0.005], wood)
    # The drawer's mass is the geometry's, its inertia a uniform box of its outline (its geoms only show it).
    size = np.array([g.drawer_depth, y1 - y0, g.front_panel_z[1] - g.drawer_bottom_z + 0.01])
    drawer = cabinet.add_body(name="drawer", mass=g.drawer_mass, explicitinertial=True,
                              ipos=[g.drawer_depth / 2, (y0 + y1) / 2, (g.front_panel_z[1] + g.drawer_bottom_z) / 2],
                              inertia=g.drawer_mass / 12 * (size[[1, 0, 0]] ** 2 + size[[2, 2, 1]] ** 2))
    drawer.add_joint(name="drawer_slide", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[-1, 0, 0], range=[0, g.travel],
                     damping=g.slide_damping, frictionloss=g.slide_friction)
    zb, zw = g.drawer_bottom_z, g.drawer_bottom_z + g.drawer_wall_height
    _box(drawer, "drawer_front", [0.0, y0, g.front_panel_z[0]], [0.02, y1, g.front_panel_z[1]], dark)
    _box(drawer, "drawer_bottom", [0.02, y0, zb - 0.01], [g.drawer_depth, y1, zb], wood)
    _box(drawer, "drawer_back", [g.drawer_depth - 0.01, y0, zb], [g.drawer_depth, y1, zw], wood)
    _box(drawer, "drawer_left", [0.02, y1 - 0.01, zb], [g.drawer_depth, y1, zw], wood)
    _box(drawer, "drawer_right", [0.02, y0, zb], [g.drawer_depth, y0 + 0.01, zw], wood)
    grip = np.array(g.handle_grip)
    bar = grip + g.bar_from_grip
    half = np.array([0.0, 0.0, g.handle_span / 2])
    for name, a, b in (("handle_bar", bar - half - [0, 0, 0.01], bar + half + [0, 0, 0.01]),
                       ("handle_upper", bar + half, [0.0, bar[1], bar[2] + half[2]]),
                       ("handle_lower", bar - half, [0.0, bar[1], bar[2] - half[2]])):
        drawer.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[g.handle_radius, 0, 0], rgba=metal,
                        fromto=np.concatenate([a, b]))
    drawer.add_site(name="handle_grip", pos=grip, size=[0.008, 0, 0], rgba=[0.1, 0.8, 0.1, 1])
    for i in range(WALLS):  # sized and placed at run time, hidden without a room
        wall = spec.worldbody.add_body(name=f"wall_{i}", mocap=True)
        wall.add_geom(name=f"wall_{i}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[1.0, WALL_THICKNESS / 2, WALL_HEIGHT / 2],
                      pos=[0.0, 0.0, WALL_HEIGHT / 2], rgba=[0.85, 0.85, 0.8, 1])
    for slot in SLOTS:
        drawer.add_site(name=f"slot_{slot}", pos=g.object_in_drawer(slot), size=[0.008, 0, 0], rgba=[0.9, 0.9, 0.1, 1])
        dowel = spec.worldbody.add_body(name=f"object_{slot}")
        dowel.add_freejoint(name=f"object_{slot}")
        dowel.add_geom(name=f"dowel_{slot}", type=mujoco.mjtGeom.mjGEOM_CYLINDER, mass=g.object_mass,
                       size=[g.dowel_radius, g.dowel_height / 2, 0], rgba=[0.85, 0.2, 0.15, 1])


def drawer_scene_mjcf(robot_scene: Path, geometry: DrawerGeometry) -> Path:
    """The robot's cached scene with the cabinet added, cached next to it (keyed by both and by this
    builder's own source)."""
    key = hashlib.sha256(b"".join(part.encode() if isinstance(part, str) else part for part in (
        __version__, mujoco.__version__, repr(geometry), robot_scene.read_bytes(),
        Path(__file__).read_bytes()))).hexdigest()[:16]
    path = robot_scene.with_name(f"{robot_scene.stem}-drawer-{key}.xml")
    if path.is_file():
        return path
    spec = mujoco.MjSpec.from_file(str(robot_scene))
    add_cabinet(spec, geometry)
    spec.compile()
    with tempfile.NamedTemporaryFile("w", dir=path.parent, suffix=".tmp", delete=False) as tmp:
        tmp.write(spec.to_xml())
    os.replace(tmp.name, path)
    return path


class DrawerCabinet:
    """The cabinet at run time, in the backend's process: placement, goal jumps, and the scene's
    ground truth for the report (``JointState.scene``), measured from the physics."""

    STANDING = ("cabinet_left", "cabinet_right", "cabinet_back", "cabinet_base")  # geoms down to the floor

    def __init__(self, m: mujoco.MjModel, placement: DrawerPlacement, geometry: DrawerGeometry, prefix: str,
                 start_xy_yaw: np.ndarray, hands: dict[str, str]):
        """``hands``: side → the robot's hand body (without ``prefix``); the bodies below a hand are its
        fingers."""
        self.m, self.placement, self.geometry = m, placement, geometry
        self.start = np.asarray(start_xy_yaw, dtype=float)
        self.mocap = int(m.body("cabinet").mocapid[0])
        self.drawer = m.body("drawer").id
        slide = m.joint("drawer_slide")
        self.slide_qpos, self.slide_dof = int(slide.qposadr[0]), int(slide.dofadr[0])
        self.hand = m.body(prefix + hands[GRASP_SIDE]).id
        self.reaching_hand = m.body(prefix + hands[other(GRASP_SIDE)]).id
        self.grip_site, self.slot_site = m.site("handle_grip").id, m.site(f"slot_{placement.slot}").id
        self.object = m.body(f"object_{placement.slot}").id
        self.objects = [m.body(f"object_{slot}").id for slot in SLOTS]
        self.object_rest_z = np.nan
        # Geom groups: the two hands (with their fingers), the handle, the object, the robot and the furniture.
        root = m.body(prefix + hands[GRASP_SIDE]).rootid[0]
        self.robot_geoms = geoms_of_bodies(m, subtree(m, int(root)))
        self.hand_geoms = geoms_of_bodies(m, subtree(m, self.hand))
        self.reaching_geoms = geoms_of_bodies(m, subtree(m, self.reaching_hand))
        self.handle_geoms = np.array([m.geom(i).name.startswith("handle_") for i in range(m.ngeom)])
        self.object_geoms = geoms_of_bodies(m, [self.object])
        self.drawer_geoms = geoms_of_bodies(m, [self.drawer])
        self.walls = [m.body(f"wall_{i}") for i in range(WALLS)]
        self.furniture_geoms = geoms_of_bodies(m, [m.body("cabinet").id, self.drawer, *self.objects,
                                                   *(w.id for w in self.walls)])
        self.pelvis_height = 0.0
        self.distance, self.frame = placement.distance, placement.frame
        self._grip_in_hand: np.ndarray | None = None  # the handle's grip point in the hand frame at first touch

    def place(self, d: mujoco.MjData, pelvis_height: float, t: float = 0.0) -> None:
        """Put the cabinet at the placement's distance for time ``t`` (panel at ``pelvis_height``), and
        each dowel standing in its slot."""
        for name in self.STANDING:  # stretch down to the floor
            geom = self.m.geom(name)
            top = geom.pos[2] + geom.size[2]
            geom.size[2], geom.pos[2] = (top + pelvis_height) / 2, (top - pelvis_height) / 2
        self.pelvis_height = pelvis_height
        self.distance = self.placement.distance_at(t)
        self.frame = self.placement.frame_at(t)
        fx, fy, fyaw = self.frame
        x, y, yaw = absolute_pose([fx + self.distance * np.cos(fyaw), fy + self.distance * np.sin(fyaw), fyaw],
                                  self.start)
        d.mocap_pos[self.mocap] = [x, y, pelvis_height]
        d.mocap_quat[self.mocap] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
        self._place_walls(d)
        mujoco.mj_kinematics(self.m, d)
        g = self.geometry
        for slot, body in zip(SLOTS, self.objects):  # upright on the drawer's bottom, under the slot's site
            x, y, z = d.site_xpos[self.m.site(f"slot_{slot}").id]
            adr = int(self.m.jnt_qposadr[self.m.body_jntadr[body]])
            dof = int(self.m.jnt_dofadr[self.m.body_jntadr[body]])
            d.qpos[adr:adr + 7] = [x, y, z - g.object_z + g.drawer_bottom_z + g.dowel_height / 2, 1.0, 0.0, 0.0, 0.0]
            d.qvel[dof:dof + 6] = 0.0
        mujoco.mj_kinematics(self.m, d)
        self.object_rest_z = float(d.xpos[self.object][2])

    def _place_walls(self, d: mujoco.MjData) -> None:
        """The room's walls where the placement says; without a room they neither show nor collide."""
        for i, body in enumerate(self.walls):
            geom = int(self.m.body_geomadr[body.id])
            if i >= len(self.placement.walls):
                self.m.geom_contype[geom] = self.m.geom_conaffinity[geom] = 0
                self.m.geom_rgba[geom, 3] = 0.0
                continue
            w = self.placement.walls[i]
            self.m.geom_contype[geom] = self.m.geom_conaffinity[geom] = 1
            self.m.geom_rgba[geom, 3] = 1.0
            x, y, yaw = absolute_pose([w.x, w.y, w.yaw], self.start)
            d.mocap_pos[body.mocapid[0]] = [x, y, 0.0]
            d.mocap_quat[body.mocapid[0]] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
            size = np.array([w.length / 2, WALL_THICKNESS / 2, WALL_HEIGHT / 2])
            self.m.geom_size[geom] = size  # the broad phase's bounds follow the size
            self.m.geom_rbound[geom] = float(np.linalg.norm(size))
            self.m.geom_aabb[geom] = [0.0, 0.0, 0.0, *size]

    def before_period(self, d: mujoco.MjData) -> None:
        """Move the cabinet (and the dowels with it) when a jump is due."""
        if self.placement.distance_at(d.time) != self.distance or self.placement.frame_at(d.time) != self.frame:
            self.place(d, self.pelvis_height, d.time)

    def hand_to_handle(self, d: mujoco.MjData) -> float:
        return float(np.linalg.norm(d.xpos[self.hand] - d.site_xpos[self.grip_site]))

    def _handle_slip(self, d: mujoco.MjData, touching: bool) -> float:
        """How far the handle's grip point moved in the hand's frame since the fingers first touched it [m]."""
        rotation = d.xmat[self.hand].reshape(3, 3)
        grip = rotation.T @ (d.site_xpos[self.grip_site] - d.xpos[self.hand])
        if self._grip_in_hand is None:
            if not touching:
                return 0.0
            self._grip_in_hand = grip
        return float(np.linalg.norm(grip - self._grip_in_hand))

    def reading(self, d: mujoco.MjData) -> np.ndarray:
        """``DRAWER_READINGS`` now."""
        m = self.m
        opening = d.xmat[self.drawer].reshape(3, 3) @ m.jnt_axis[m.dof_jntid[self.slide_dof]]
        ours, theirs, forces = robot_contacts(m, d, self.robot_geoms)  # one pass over the contacts
        on_drawer = forces[self.drawer_geoms[theirs]]
        grip = forces[self.handle_geoms[theirs] & self.hand_geoms[ours]]
        held = forces[self.object_geoms[theirs] & self.reaching_geoms[ours]]
        intended = self.handle_geoms | self.object_geoms
        unintended = forces[(self.furniture_geoms & ~intended)[theirs]
                            | (self.handle_geoms[theirs] & ~self.hand_geoms[ours])
                            | (self.object_geoms[theirs] & ~self.reaching_geoms[ours])]
        touching = len(grip) > 0
        values = {"drawer_opening_m": d.qpos[self.slide_qpos], "drawer_velocity_mps": d.qvel[self.slide_dof],
                  "drawer_pull_force_n": float(on_drawer.sum(axis=0) @ opening) if len(on_drawer) else 0.0,
                  "grasped": float(touching), "grip_force_n": _squeeze(grip),
                  "handle_slip_m": self._handle_slip(d, touching),
                  "left_hand_to_handle_m": self.hand_to_handle(d),
                  "right_hand_to_object_m": np.linalg.norm(d.xpos[self.reaching_hand] - d.site_xpos[self.slot_site]),
                  "cabinet_distance_m": self.distance,
                  "object_lift_m": d.xpos[self.object][2] - self.object_rest_z,
                  "object_held": float(len(held) > 0), "object_grip_force_n": _squeeze(held),
                  "unintended_contacts": float(len(unintended)),
                  "unintended_force_n": float(np.linalg.norm(unintended, axis=1).max()) if len(unintended) else 0.0}
        return np.array([values[name] for name in DRAWER_READINGS], dtype=float)


def _squeeze(forces: np.ndarray) -> float:
    """The contact forces' magnitudes, summed [N]: what fingers press on a thing from all sides."""
    return float(np.linalg.norm(forces, axis=1).sum())
