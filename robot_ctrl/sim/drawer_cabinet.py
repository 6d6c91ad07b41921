"""The chest of drawers of the walk-and-reach task, in the MuJoCo world.

Built from :class:`~robot_ctrl.geometry.drawer_geometry.DrawerGeometry` (the numbers the demonstrations
use) onto the robot's cached scene, and cached in turn. The cabinet is a mocap body, so that one
scene serves every distance: :class:`DrawerCabinet` places it at run time ``distance`` ahead of the
robot's start pose along its start heading, with the drawer's panel at the standing pelvis height
as the geometry's frame says, and moves it when a goal jump is due. The drawer slides on a joint
(0 closed .. ``travel`` open, toward the robot) with viscous damping and dry friction, so pulling it
takes a real force; a dowel stands in each of the four slots.

Grasp, stated: the converted Talos model's fingers are fixed links (only the gripper joint moves),
so they cannot close round a bar. The grasp is a weld of position (a MuJoCo ``connect`` equality:
the gripper base's origin pinned to the drawer, free to turn about it as a hand round a bar can),
switched on from measured quantities only: the gripper joint closed and the gripper base within
``GRASP_DISTANCE`` of the handle's grip point. The cabinet does not collide with the robot (the
hand's collision shapes would fight the weld); the drawer's travel is its joint's range.
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
from robot_ctrl.geometry import Side, other
from robot_ctrl.geometry.drawer_geometry import DRAWER_READINGS, SLOTS, DrawerGeometry, cabinet_distance

if TYPE_CHECKING:
    from robot_ctrl.robot.model import RobotModel

GRASP_DISTANCE = 0.01  # [m] gripper base to the handle's grip point for the weld to switch on
GRIPPER_CLOSED = 0.1  # [rad] the gripper joint within this of its closed end is closed
GRASP_SIDE: Side = "left"


@dataclass(frozen=True)
class DrawerPlacement:
    """Where the cabinet stands: its closed drawer's front panel ``distance`` [m] ahead of the
    robot's start pelvis along the start heading; ``jumps``: (time [s], new distance [m]) at which
    it is moved (thesis Fig. 3.39); ``slot``: the object the right hand reaches for; ``geometry``:
    the cabinet, by default the robot's (its config's ``drawer:``)."""

    distance: float
    slot: str = "front_left"
    jumps: tuple[tuple[float, float], ...] = ()
    geometry: DrawerGeometry | None = None

    def distance_at(self, t: float) -> float:
        return cabinet_distance(self.distance, self.jumps, t)

    # The prop interface (``sim/prop.py``) ------------------------------------------------------
    def scene_mjcf(self, robot: RobotModel) -> Path:
        return drawer_scene_mjcf(robot.mjcf_path, self.geometry or robot.config.drawer,
                                 f"{robot.name}/{robot.config.hands[GRASP_SIDE]}")

    def in_world(self, m: mujoco.MjModel, robot: RobotModel, prefix: str, start_xy_yaw: np.ndarray) -> DrawerCabinet:
        return DrawerCabinet(m, self, prefix, start_xy_yaw, robot.config.hands,
                             robot.config.joint_roles["grippers"][GRASP_SIDE],
                             robot.config.grippers.closing_sign(GRASP_SIDE))


def _box(body, name: str, lo, hi, rgba) -> None:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    geom = body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=(hi - lo) / 2, pos=(hi + lo) / 2,
                         rgba=rgba)
    geom.contype = geom.conaffinity = 0


def add_cabinet(spec: mujoco.MjSpec, geometry: DrawerGeometry, hand_body: str) -> None:
    """The cabinet (mocap body ``cabinet``), its drawer on the slide ``drawer_slide``, the dowels, the
    sites ``handle_grip`` and ``slot_<slot>``, and the inactive position weld ``grasp`` of ``hand_body``
    to the drawer. Frame of the cabinet body: the pelvis-at-comfort frame of the geometry, moved so that
    the closed panel is at x = 0."""
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
    for name, a, b in (("handle_bar", bar - [0, 0, 0.06], bar + [0, 0, 0.06]),
                       ("handle_upper", bar + [0, 0, 0.05], [0.0, bar[1], bar[2] + 0.05]),
                       ("handle_lower", bar - [0, 0, 0.05], [0.0, bar[1], bar[2] - 0.05])):
        geom = drawer.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.011, 0, 0], rgba=metal,
                               fromto=np.concatenate([a, b]))
        geom.contype = geom.conaffinity = 0
    drawer.add_site(name="handle_grip", pos=grip, size=[0.008, 0, 0], rgba=[0.1, 0.8, 0.1, 1])
    for slot in SLOTS:
        target = g.object_in_drawer(slot)
        geom = drawer.add_geom(name=f"dowel_{slot}", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                               size=[g.dowel_radius, g.dowel_height / 2, 0], rgba=[0.85, 0.2, 0.15, 1],
                               pos=[target[0], target[1], zb + g.dowel_height / 2])
        geom.contype = geom.conaffinity = 0
        drawer.add_site(name=f"slot_{slot}", pos=target, size=[0.008, 0, 0], rgba=[0.9, 0.9, 0.1, 1])
    weld = spec.add_equality(name="grasp", type=mujoco.mjtEq.mjEQ_CONNECT, objtype=mujoco.mjtObj.mjOBJ_BODY,
                             name1=hand_body, name2="drawer")
    weld.active = False


def drawer_scene_mjcf(robot_scene: Path, geometry: DrawerGeometry, hand_body: str) -> Path:
    """The robot's cached scene with the cabinet added, cached next to it (keyed by both and by this
    builder's own source)."""
    key = hashlib.sha256(b"".join(part.encode() if isinstance(part, str) else part for part in (
        __version__, mujoco.__version__, repr(geometry), hand_body, robot_scene.read_bytes(),
        Path(__file__).read_bytes()))).hexdigest()[:16]
    path = robot_scene.with_name(f"{robot_scene.stem}-drawer-{key}.xml")
    if path.is_file():
        return path
    spec = mujoco.MjSpec.from_file(str(robot_scene))
    add_cabinet(spec, geometry, hand_body)
    spec.compile()
    with tempfile.NamedTemporaryFile("w", dir=path.parent, suffix=".tmp", delete=False) as tmp:
        tmp.write(spec.to_xml())
    os.replace(tmp.name, path)
    return path


class DrawerCabinet:
    """The cabinet at run time, in the backend's process: placement, goal jumps, the grasp's
    switch, and the scene's ground truth for the report (``JointState.scene``)."""

    STANDING = ("cabinet_left", "cabinet_right", "cabinet_back", "cabinet_base")  # geoms down to the floor

    def __init__(self, m: mujoco.MjModel, placement: DrawerPlacement, prefix: str,
                 start_xy_yaw: np.ndarray, hands: dict[str, str], gripper_joint: str, closing_sign: float = 1.0):
        """``hands``: side → the robot's hand body (without ``prefix``); ``gripper_joint``: the
        grasping hand's gripper, closing toward its upper limit (``closing_sign`` +1) or its lower (-1)."""
        self.m, self.placement = m, placement
        self.start = np.asarray(start_xy_yaw, dtype=float)
        self.mocap = int(m.body("cabinet").mocapid[0])
        self.drawer = m.body("drawer").id
        slide = m.joint("drawer_slide")
        self.slide_qpos, self.slide_dof = int(slide.qposadr[0]), int(slide.dofadr[0])
        self.hand = m.body(prefix + hands[GRASP_SIDE]).id
        self.reaching_hand = m.body(prefix + hands[other(GRASP_SIDE)]).id
        gripper = m.joint(prefix + gripper_joint)
        self.gripper_qpos, self.closing_sign = int(gripper.qposadr[0]), closing_sign
        self.gripper_closed_at = float(gripper.range[1] if closing_sign > 0 else gripper.range[0])
        self.grip_site, self.slot_site = m.site("handle_grip").id, m.site(f"slot_{placement.slot}").id
        self.weld = m.equality("grasp").id
        self.pelvis_height = 0.0
        self.distance = placement.distance
        self.grasp_time = np.nan
        self._force = np.zeros(m.nv)

    def place(self, d: mujoco.MjData, pelvis_height: float, t: float = 0.0) -> None:
        """Put the cabinet at the placement's distance for time ``t`` (panel at ``pelvis_height``)."""
        self.pelvis_height = pelvis_height
        for name in self.STANDING:  # stretch down to the floor
            geom = self.m.geom(name)
            top = geom.pos[2] + geom.size[2]
            geom.size[2], geom.pos[2] = (top + pelvis_height) / 2, (top - pelvis_height) / 2
        self.distance = self.placement.distance_at(t)
        x, y, yaw = self.start
        d.mocap_pos[self.mocap] = [x + self.distance * np.cos(yaw), y + self.distance * np.sin(yaw), pelvis_height]
        d.mocap_quat[self.mocap] = [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]

    def before_period(self, d: mujoco.MjData) -> None:
        """Move the cabinet when a jump is due; switch the grasp on when its measured condition holds."""
        if self.placement.distance_at(d.time) != self.distance:
            self.place(d, self.pelvis_height, d.time)
            mujoco.mj_kinematics(self.m, d)
        if not d.eq_active[self.weld] and self.grasp_ready(d):
            self._weld_as_is(d)
            self.grasp_time = float(d.time)

    def grasp_ready(self, d: mujoco.MjData) -> bool:
        closed = self.closing_sign * (d.qpos[self.gripper_qpos] - self.gripper_closed_at) >= -GRIPPER_CLOSED
        return bool(closed and self.hand_to_handle(d) <= GRASP_DISTANCE)

    def hand_to_handle(self, d: mujoco.MjData) -> float:
        return float(np.linalg.norm(d.xpos[self.hand] - d.site_xpos[self.grip_site]))

    def _weld_as_is(self, d: mujoco.MjData) -> None:
        """Pin the hand's origin to the drawer where it is now (no jump when it switches on)."""
        drawer_rot = d.xmat[self.drawer].reshape(3, 3)
        self.m.eq_data[self.weld, 0:3] = 0.0  # the hand body's origin ...
        self.m.eq_data[self.weld, 3:6] = drawer_rot.T @ (d.xpos[self.hand] - d.xpos[self.drawer])  # ... in the drawer
        d.eq_active[self.weld] = 1

    def pull_force(self, d: mujoco.MjData) -> float:
        """The hand's force on the drawer along its opening direction [N]: the weld's constraint force
        on the slide."""
        if not d.eq_active[self.weld]:
            return 0.0
        rows = (d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY) & (d.efc_id == self.weld)
        mujoco.mj_mulJacTVec(self.m, d, self._force, np.where(rows, d.efc_force, 0.0))
        return float(self._force[self.slide_dof])

    def reading(self, d: mujoco.MjData) -> np.ndarray:
        """``DRAWER_READINGS`` now."""
        values = {"drawer_opening_m": d.qpos[self.slide_qpos], "drawer_velocity_mps": d.qvel[self.slide_dof],
                  "drawer_pull_force_n": self.pull_force(d), "grasped": float(d.eq_active[self.weld]),
                  "left_hand_to_handle_m": self.hand_to_handle(d),
                  "right_hand_to_object_m": np.linalg.norm(d.xpos[self.reaching_hand] - d.site_xpos[self.slot_site]),
                  "cabinet_distance_m": self.distance}
        return np.array([values[name] for name in DRAWER_READINGS], dtype=float)
