"""N-step capture regions of the LIP with rectangular soles, checked against the pendulum itself."""

import numpy as np
import pytest

from robot_ctrl.wpg.capturability import CaptureModel, capture_box, capture_boxes, largest_capturable_impulse

OMEGA = np.sqrt(9.81 / 0.85)
MODEL = CaptureModel(OMEGA, (0.21, 0.13), (-0.2, 0.3), (0.218, 0.368), min_swing=0.3)


def dcm_after(xi0: float, zmp: float, duration: float, force: float = 0.0, dt: float = 1e-5) -> float:
    """ξ̇ = ω (ξ − p) + f/ω (f: external force per kg), integrated numerically."""
    xi = xi0
    for _ in range(int(round(duration / dt))):
        xi += dt * (OMEGA * (xi - zmp) + force / OMEGA)
    return xi


def test_one_step_forward_bound_is_where_the_pendulum_just_reaches_the_farthest_sole():
    model = CaptureModel(OMEGA, (0.21, 0.13), (-0.2, 0.3), (0.218, 0.368), min_swing=0.3, steps=1)
    (x_lo, _), (x_hi, _) = capture_box(model, "right", wait=0.4)
    for margin, captured in ((-1e-3, True), (1e-3, False)):
        xi = x_hi + margin
        # Best the stance foot can do: the ZMP at its toe until the earliest landing, at the reach's far end.
        landed = dcm_after(xi, 0.105, 0.4)
        assert bool(landed <= 0.3 + 0.105) is captured
    assert x_lo == pytest.approx(-0.105 + (-0.2) * np.exp(-OMEGA * 0.4))


def test_beyond_the_stance_soles_outer_edge_no_number_of_steps_captures():
    # The feet do not cross: a DCM right of a right stance sole can only run away from every later support.
    for steps in (0, 1, 4, 12):
        model = CaptureModel(OMEGA, (0.21, 0.13), (-0.2, 0.3), (0.218, 0.368), 0.3, steps)
        for wait in (0.0, 0.3, 1.0):
            assert capture_box(model, "right", wait)[0][1] == pytest.approx(-0.065)
            assert capture_box(model, "left", wait)[1][1] == pytest.approx(0.065)


def test_more_steps_and_earlier_landings_capture_more():
    regions = [capture_box(CaptureModel(OMEGA, (0.21, 0.13), (-0.2, 0.3), (0.218, 0.368), 0.3, n), "right", 0.3)
               for n in range(5)]
    for (lo0, hi0), (lo1, hi1) in zip(regions, regions[1:]):
        assert np.all(lo1 <= lo0 + 1e-12) and np.all(hi1 >= hi0 - 1e-12)
    assert regions[2][1][0] > regions[1][1][0] + 0.01  # a second step adds reach forward
    early, late = capture_box(MODEL, "right", 0.1), capture_box(MODEL, "right", 0.5)
    assert early[1][0] > late[1][0] and early[1][1] > late[1][1]


def test_largest_capturable_impulse_against_a_pushed_pendulum():
    boxes = capture_boxes(MODEL, {"right": np.zeros(2)}, wait=0.3)
    bound = largest_capturable_impulse(MODEL, np.array([0.0, 0.0]), np.array([0.0, -1.0]), boxes, resolution=0.001)
    # To the right of a right stance only the ankle can catch it: ξ = −J/ω must stay on the sole.
    assert bound == pytest.approx(0.065 * OMEGA, abs=0.001)
    # Spread over 0.1 s, the sole pushes back during the push: the same DCM needs J / ((1 − e^{−ωD}) / (ωD)).
    spread = largest_capturable_impulse(MODEL, np.zeros(2), np.array([0.0, -1.0]), boxes, 0.1, resolution=0.001)
    assert spread == pytest.approx(bound * OMEGA * 0.1 / (1 - np.exp(-OMEGA * 0.1)), abs=0.002)
    # The pendulum pushed for 0.1 s with its ZMP on the sole's edge ends the push on the edge (held) or beyond it.
    for impulse, held in ((spread - 0.003, True), (spread + 0.003, False)):
        assert bool(dcm_after(0.0, -0.065, 0.1, force=-impulse / 0.1) >= -0.065) is held
    # Outside every region from the start: nothing is capturable.
    assert largest_capturable_impulse(MODEL, np.array([0.0, -0.07]), np.array([0.0, -1.0]), boxes) == 0.0


def test_double_support_adds_the_hull_and_either_foot_stepping():
    support = {"right": np.zeros(2), "left": np.array([0.1, 0.22])}
    hull, *steps = capture_boxes(MODEL, support, wait=0.0)
    np.testing.assert_allclose(hull[0], [-0.105, -0.065])
    np.testing.assert_allclose(hull[1], [0.205, 0.285])
    assert len(steps) == 2 and steps[0][0][1] == pytest.approx(-0.065)  # the right foot standing: its own edge
    # With the step timing kept, only the trailing foot lifts: the left one stays.
    hull_kept, kept = capture_boxes(MODEL, support, wait=0.0, stays="left")
    np.testing.assert_allclose(hull_kept, hull)
    np.testing.assert_allclose(kept, steps[1])
    assert kept[1][1] == pytest.approx(0.22 + 0.065)  # the left foot standing: its own outer edge


def test_crossing_feet_are_refused():
    with pytest.raises(ValueError, match="cross"):
        CaptureModel(OMEGA, (0.21, 0.13), (-0.2, 0.3), (-0.05, 0.3), 0.3)
