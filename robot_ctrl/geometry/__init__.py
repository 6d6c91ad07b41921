"""The ground floor every layer may import: planar frames, support polygons, gravity,
minimum-jerk interpolation. Imports nothing from robot_ctrl."""

from robot_ctrl.geometry.frames import (
                                        GRAVITY,
                                        SIDES,
                                        PlanarMove,
                                        base_pose_xy_yaw,
                                        mean_yaw,
                                        other,
                                        relative_pose,
                                        rotation,
                                        wrap_angle,
                                        yaw_of,
)
from robot_ctrl.geometry.minimum_jerk import interpolate, minimum_jerk
from robot_ctrl.geometry.support_polygon import SupportPolygon, convex_hull, sole_corners

__all__ = ["GRAVITY", "SIDES", "PlanarMove", "SupportPolygon", "base_pose_xy_yaw", "convex_hull", "interpolate",
           "mean_yaw", "minimum_jerk", "other", "relative_pose", "rotation", "sole_corners", "wrap_angle", "yaw_of"]
