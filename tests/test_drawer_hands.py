"""DrawerHands' measured-hand correction, on a stand-in for the walking controller's hand interface
(the hands' logic alone; the physics of a reach is in test_drawer.py)."""

from types import SimpleNamespace

import numpy as np

from robot_ctrl.control.commanders.drawer_hands import BIAS_SPEED, MAX_HAND_BIAS, DrawerHands

DT = 0.005


class ArmInterface:
    """What DrawerHands reads from and sends to the controller: the IK's reference hand, the
    measured (estimated) hand, the commanded hand targets."""

    def __init__(self, robot):
        self.robot, self.dt = robot, DT
        self.reference = np.zeros(3)
        self.estimate = SimpleNamespace(hands={"left": np.zeros(3), "right": np.zeros(3)})
        self.targets: dict = {}

    def reference_hand(self, side):
        return self.reference.copy()

    def set_hand_target(self, side, target, velocity=None, rotation=None):
        self.targets[side] = target


def run(talos, reference_velocity, lag):
    """1 s of a free right hand whose reference moves at ``reference_velocity`` [m/s] and whose
    measured hand sits ``lag`` [m] behind it (along x); the bias the hands learned."""
    arm = ArmInterface(talos)
    hands = DrawerHands(arm, targets=None, body=None)
    for k in range(200):
        arm.reference = np.array([reference_velocity * k * DT, 0.0, 0.0])
        arm.estimate.hands["right"] = arm.reference - [lag, 0.0, 0.0]
        hands._free("right", arm.reference + [0.1, 0.0, 0.0])
    return hands._bias["right"]


def test_a_still_hand_learns_its_sag_and_a_moving_one_not_its_lag(talos):
    sag = run(talos, 0.0, 0.01)  # servo sag under the arm's weight: learned (τ = 0.5 s: 86 % in 1 s)
    np.testing.assert_allclose(sag, [-0.01 * (1 - np.exp(-2.0)), 0.0, 0.0], atol=2e-4)
    lag = run(talos, 4 * BIAS_SPEED, 0.03)  # a reach's lag: not taken for an offset (but on the first tick)
    assert np.abs(lag).max() < 0.001  # 26 mm if it were
    assert np.linalg.norm(run(talos, 0.0, 0.2)) <= MAX_HAND_BIAS + 1e-12
