"""The drawer of the walk-and-reach task: one source of truth for the demonstrations that teach the
synthesis where the hands go and for the cabinet simulated in MuJoCo.

Frame: the pelvis (base_link) standing at the comfort distance in front of the closed drawer, x
toward the drawer, y left, z up, metres. x is measured from the drawer's front panel (negative: on
the robot's side of it), y from the pelvis's sagittal plane, z from the standing pelvis height.
The cabinet's proportions are ours, scaled to Talos (the top drawer of a tall chest, its handle a
little above the pelvis, so that the forearm passes above the hip when the drawer is pulled 32 cm);
the opening clearances are the thesis's (3.3.1). Another robot's config scales the whole
(``drawer.scale``, :meth:`DrawerGeometry.scaled`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

from robot_ctrl.geometry.room import Box

#: What the drawer cabinet's prop reports each tick in simulation (``JointState.scene``, in this
#: order), all from the physics' contacts and bodies: the drawer's opening [m] and velocity [m/s];
#: the robot's contact force on the drawer along its opening [N]; the left hand's fingers touching the
#: handle (1 or 0) and their contact force [N]; the left hand's slip along the handle since its
#: fingers first touched it [m]; the left hand to the handle's grip point and the right hand to the
#: object's reach point [m]; the cabinet's distance [m]; the object's height gain [m], its contact
#: with the right hand's fingers (1 or 0) and their force on it [N]; the robot's other contacts with
#: the cabinet, its drawer and the objects: how many, and the largest force [N].
DRAWER_READINGS = ("drawer_opening_m", "drawer_velocity_mps", "drawer_pull_force_n", "grasped", "grip_force_n",
                   "handle_slip_m", "left_hand_to_handle_m", "right_hand_to_object_m", "cabinet_distance_m",
                   "object_lift_m", "object_held", "object_grip_force_n", "unintended_contacts",
                   "unintended_force_n")

SLOTS = ("front_left", "front_right", "back_left", "back_right")


_MASS_LIKE = ("drawer_mass", "object_mass", "slide_damping", "slide_friction")


def scheduled_at(first, jumps, t: float):
    """Where a goal jumping at times stands at time ``t`` [s] (the cabinet's distance [m], or its
    frame): ``first`` until the last of the ``jumps`` ((time [s], new value) pairs) at or before ``t``."""
    return next((v for t0, v in sorted(jumps, reverse=True) if t >= t0 - 1e-9), first)


@dataclass(frozen=True)
class DrawerGeometry:
    # Where the left gripper base sits when its fingers are round the handle bar; the bar lies in
    # front of it by ``bar_from_grip``: 8.5 cm out along Talos's fingers (pointing at the drawer),
    # between the palm and the fingertip pads, which closed cage it. The bar stands on long posts, so
    # that the 15 cm fingers reaching past it stay clear of the panel.
    handle_grip: tuple[float, float, float] = (-0.11, 0.22, 0.09)
    bar_from_grip: tuple[float, float, float] = (0.02, -0.12, 0.0)
    handle_radius: float = 0.011  # [m] the bar's
    handle_span: float = 0.14  # [m] between the bar's two posts: room for the fingers along it
    clearance: dict = field(default_factory=lambda: {"front": 0.14, "back": 0.28})  # thesis 3.3.1
    margin: float = 0.02  # extra opening beyond the clearance
    # Objects (dowels) stand in the drawer: depth behind the front panel, y; the right gripper base
    # reaches ``object_z``, above the dowel's top, its wrist clear of the drawer's front panel.
    object_depth: dict = field(default_factory=lambda: {"front": 0.06, "back": 0.26})
    object_y: dict = field(default_factory=lambda: {"left": -0.02, "right": -0.16})
    object_z: float = 0.36
    dowel_height: float = 0.10  # [m] standing on the drawer's bottom, loose
    dowel_radius: float = 0.02
    object_mass: float = 0.3  # [kg] each dowel's
    # The drawer: a box behind its front panel, on a slide joint along x.
    drawer_depth: float = 0.40
    drawer_y: tuple[float, float] = (-0.28, 0.24)
    drawer_bottom_z: float = -0.10
    drawer_wall_height: float = 0.10
    front_panel_z: tuple[float, float] = (-0.12, 0.16)
    travel: float = 0.35  # [m] slide range 0 .. travel (open toward the robot)
    drawer_mass: float = 3.0  # [kg]
    slide_damping: float = 10.0  # [N·s/m] viscous friction: 3 N more at 0.3 m/s
    slide_friction: float = 15.0  # [N] dry friction of the runners: the force to start it moving
    cabinet_depth: float = 0.50
    body_radius: float = 0.55  # [m] the walking robot's reach round its pelvis: arms, hands, swinging feet, turning
    # In a room, the synthesis takes over this far (the walk-in, a normal and a short cycle) before
    # the comfort distance.
    handover_walk: float = 0.95

    def scaled(self, s: float) -> "DrawerGeometry":
        """The same cabinet ``s`` times the size: every length × s; the drawer's mass and its slide's
        damping and friction × s³, as a robot's mass goes with the cube of its size."""
        if s == 1.0:
            return self
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            k = s ** 3 if f.name in _MASS_LIKE else s
            out[f.name] = ({key: x * k for key, x in v.items()} if isinstance(v, dict) else
                           tuple(x * k for x in v) if isinstance(v, tuple) else v * k)
        return replace(self, **out)

    def footprint(self) -> Box:
        """The closed cabinet's outline on the floor with its handle, in its frame (room.py's cabinet
        frame: x from the panel into the cabinet, y left)."""
        bar = np.array(self.handle_grip) + self.bar_from_grip
        return Box(min(0.0, float(bar[0])) - self.handle_radius, self.cabinet_depth,
                   self.drawer_y[0] - 0.025, self.drawer_y[1] + 0.025)

    def opening(self, slot: str) -> float:
        """How far the drawer is pulled for ``slot`` [m]: the clearance plus the margin."""
        return self.clearance[slot.split("_")[0]] + self.margin

    def required_opening(self, slot: str) -> float:
        """The thesis's clearance for ``slot``: the least opening that lets the hand in [m]."""
        return self.clearance[slot.split("_")[0]]

    def object_in_drawer(self, slot: str) -> np.ndarray:
        """The right gripper base's target above the object, relative to the closed front panel."""
        depth, side = slot.split("_")
        return np.array([self.object_depth[depth], self.object_y[side], self.object_z])

    def object_target(self, slot: str, comfort: float) -> np.ndarray:
        """The same target with the drawer open by :meth:`opening`, in the pelvis frame."""
        return self.object_in_drawer(slot) + [comfort - self.opening(slot), 0.0, 0.0]

    def handle_target(self, comfort: float) -> np.ndarray:
        """The left gripper base at the handle of the closed drawer, in the pelvis frame."""
        return np.array(self.handle_grip) + [comfort, 0.0, 0.0]
