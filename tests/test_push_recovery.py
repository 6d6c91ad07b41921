"""The plan's take-up of a pushed DCM (control.push_recovery), and what it does on a pushed walk."""

import json

import numpy as np
import pytest

from robot_ctrl.cli import main
from robot_ctrl.control.controllers.push_recovery import DEAD_BAND, plan_velocity_change

OMEGA = 3.4


def test_the_plan_takes_up_only_the_departure_beyond_the_dead_band():
    planned = np.array([0.3, -0.02])
    assert plan_velocity_change(planned + [0.0, DEAD_BAND * 0.99], planned, OMEGA) is None
    measured = planned + [0.06, 0.08]  # 0.1 m away
    change = plan_velocity_change(measured, planned, OMEGA)
    np.testing.assert_allclose(change, OMEGA * (0.1 - DEAD_BAND) * np.array([0.6, 0.8]), atol=1e-12)
    # The plan's DCM (c + ċ/ω) ends on the dead band's edge, on the line to the measured one.
    taken_up = planned + change / OMEGA
    assert np.linalg.norm(measured - taken_up) == pytest.approx(DEAD_BAND)
    (a, b), (c, d) = measured - planned, taken_up - planned
    assert a * d - b * c == pytest.approx(0.0, abs=1e-12)


def test_a_push_forward_in_double_support_is_caught_only_with_the_recovery(tmp_path):
    """0.4 N·s/kg forward at the start of a double support of 0.5 s steps: the controller whose
    plan ignores the push falls; with the recovery the plan steps after the robot and the walk ends
    at its goal."""
    reports = {}
    for name, extra in (("on", []), ("off", ["--no-push-recovery"])):
        out = tmp_path / name
        main(["walk", "--distance", "3", "--single-support", "0.5", "--push", "2.6:0:0.4", "--quiet",
              "--out", str(out), *extra])
        reports[name] = json.loads((out / "report.json").read_text())
    on, off = reports["on"], reports["off"]
    assert off["fell"] is True and off["push_recovery"] is False and off["push_recoveries"] == 0
    assert on["fell"] is False and on["push_recovery"] is True and on["push_recoveries"] > 0
    assert on["final_position_error_m"] < 0.05
