"""The ground floor every layer may import: planar frames, sides, support polygons, gravity,
minimum-jerk interpolation, the drawer task's geometry. Imports nothing from robot_ctrl.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "frames": ["GRAVITY", "SIDES", "Side", "PlanarMove", "absolute_pose", "base_pose_xy_yaw", "left_sign", "mean_yaw", "other", "relative_pose", "rotation", "wrap_angle", "yaw_of"],
    "interpolation": ["interpolate", "minimum_jerk"],
    "support_polygon": ["SupportPolygon", "convex_hull", "sole_corners"],
})
