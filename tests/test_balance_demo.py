"""The balance demo end to end, through the CLI, in MuJoCo (issue acceptance numbers)."""

import json
import time

import numpy as np
import pinocchio as pin
import pytest

from robot_ctrl.cli import main
from robot_ctrl.control.controllers.static_feedforward import static_torques, weight_shares
from robot_ctrl.robot import load_robot


@pytest.mark.parametrize("robot", ["talos", "g1"])
def test_balance_demo_cli(robot, tmp_path):
    began = time.perf_counter()
    assert main(["balance", "--robot", robot, "--out", str(tmp_path)]) == 0
    wall = time.perf_counter() - began
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fell"] is False
    assert report["time_s"] == pytest.approx(15.5)
    assert report["hand_error_m"] < 0.02
    assert report["peak_torque_ratio"] <= 1.0
    # Within the servos' limits by itself: the safety layer never acts, nothing is asked beyond a limit.
    assert not report["safety"]["interventions"] and max(report["safety"]["demanded_peak_torque_ratio"].values()) <= 1.0
    weight = load_robot(robot).mass * 9.81
    # In single support the left foot carries the whole robot; the right foot is never overloaded.
    assert weight * 0.95 < report["peak_grf_n"]["left"] < weight * 1.4
    assert report["peak_grf_n"]["right"] < weight * 1.4
    # Real-time factor: simulated over the control loop's wall time, which is part of the command's.
    assert report["time_s"] / wall <= report["rtf"] < 10 * report["time_s"] / wall


def test_unknown_robot_exits_with_a_clear_error(capsys):
    assert main(["balance", "--robot", "asimo"]) == 2
    assert "unknown robot 'asimo'; available robots: g1, g1_dex3, talos" in capsys.readouterr().err


def test_static_feedforward_puts_the_zmp_under_the_com(talos):
    """Single support: the sole wrench balances gravity, so its ZMP is the CoM's ground projection."""
    data = talos.pin.createData()
    q = talos.q_half_sitting
    sole = talos.frame_ids["left_foot"]
    tau, (wrench,) = static_torques(talos.pin, data, q, [sole], [1.0])
    assert np.abs(tau[:6]).max() < 1e-9
    # Express the wrench in the world frame (the sole is tilted by 1.7 mrad in half-sitting).
    rotation, origin = data.oMf[sole].rotation, data.oMf[sole].translation
    force, moment = rotation @ wrench[:3], rotation @ wrench[3:]
    np.testing.assert_allclose(force, [0.0, 0.0, talos.mass * 9.81], atol=1e-6)
    zmp = origin[:2] + np.array([-moment[1], moment[0]]) / force[2]
    com = pin.centerOfMass(talos.pin, data, q)
    np.testing.assert_allclose(zmp, com[:2], atol=1e-9)


def test_weight_shares_follow_the_com():
    left, right = np.array([0.0, 0.1]), np.array([0.0, -0.1])
    assert weight_shares(np.array([0.0, 0.0]), left, right) == pytest.approx((0.5, 0.5))
    assert weight_shares(np.array([0.0, 0.05]), left, right) == pytest.approx((0.75, 0.25))
    assert weight_shares(np.array([0.0, 0.5]), left, right) == pytest.approx((0.98, 0.02))
