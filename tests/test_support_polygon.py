"""SupportPolygon: the hull of sole rectangles, containment and the closest boundary point,
against figures worked out by hand (world frame, m)."""

import math

import numpy as np

from robot_ctrl.geometry import SupportPolygon, convex_hull

LENGTH, WIDTH = 0.2, 0.1


def test_two_soles_side_by_side_make_one_rectangle_without_collinear_vertices():
    feet = SupportPolygon.of_soles([(np.array([0.0, 0.1]), 0.0), (np.array([0.0, -0.1]), 0.0)], LENGTH, WIDTH)
    # counter-clockwise from the lowest-leftmost corner; the inner corners lie on the outer edges' lines
    np.testing.assert_allclose(feet.vertices, [[-0.1, -0.15], [0.1, -0.15], [0.1, 0.15], [-0.1, 0.15]], atol=1e-15)


def test_one_turned_sole_keeps_its_four_corners():
    sole = SupportPolygon.of_soles([(np.array([1.0, 2.0]), math.pi / 2)], LENGTH, WIDTH)
    np.testing.assert_allclose(sole.vertices, [[0.95, 2.1], [0.95, 1.9], [1.05, 1.9], [1.05, 2.1]], atol=1e-15)


def test_a_staggered_stance_drops_the_hidden_corners():
    feet = SupportPolygon.of_soles([(np.array([0.1, 0.1]), 0.0), (np.array([-0.1, -0.1]), 0.0)], LENGTH, WIDTH)
    np.testing.assert_allclose(feet.vertices, [[-0.2, -0.15], [0.0, -0.15], [0.2, 0.05], [0.2, 0.15], [0.0, 0.15],
                                               [-0.2, -0.05]], atol=1e-15)


def test_convex_hull_of_points_in_a_square():
    points = [(0.0, 0.0), (1.0, 0.0), (0.5, 0.5), (1.0, 1.0), (0.0, 1.0), (0.5, 0.0), (1.0, 1.0)]
    assert convex_hull(points) == [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    assert convex_hull([(1.0, 2.0), (0.0, 3.0)]) == [(0.0, 3.0), (1.0, 2.0)]


def test_contains_and_clamp_to_the_closest_boundary_point():
    feet = SupportPolygon.of_soles([(np.array([0.0, 0.1]), 0.0), (np.array([0.0, -0.1]), 0.0)], LENGTH, WIDTH)
    inside = np.array([0.05, -0.1])
    assert feet.contains(inside) and feet.clamp(inside) is inside
    assert not feet.contains(np.array([0.1 + 1e-6, 0.0])) and feet.contains(np.array([0.1 + 1e-10, 0.0]))
    np.testing.assert_allclose(feet.clamp(np.array([0.3, 0.05])), [0.1, 0.05])  # in front: onto the toe edge
    np.testing.assert_allclose(feet.clamp(np.array([-0.4, 0.5])), [-0.1, 0.15])  # beyond a corner: the corner
