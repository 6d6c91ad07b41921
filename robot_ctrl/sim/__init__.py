"""The simulated robot and its world, behind the hardware interface: the MuJoCo backend and the
world it steps, the robot's own process, props placed in the scene (the chest of drawers),
disturbances (pushes, model mismatch, latency, sensor noise) and offscreen video.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "mujoco_backend": ["MujocoBackend"],
    "mujoco_world": ["MujocoWorld"],
    "robot_process": ["RobotProcess"],
    "prop": ["Prop", "PropInWorld"],
    "drawer_cabinet": ["DrawerCabinet", "DrawerPlacement"],
    "disturbances": ["Disturbances", "Push"],
    "mujoco_video": ["Video", "WorldVideo"],
    "contacts": ["geoms_of_bodies", "robot_contacts", "subtree"],
})
