"""Three robots (Talos, G1) in one MuJoCo world, gaits coupled through the crowd laws and the gait bridge."""

import json

import pytest

from robot_ctrl.cli import main
from robot_ctrl.robot import load_robot
from robot_ctrl.scenarios.group_walk import GroupWalk, run_group_walk


# The feet land together, measured by contact: within 0.1 rad of the gait cycle (20 ms) for Talos.
# G1: in the last cycle two robots' swing feet touch the floor 40 ms before the third's, bounce and
# touch again with it (docs/robots.md): 0.157 rad.
@pytest.mark.parametrize("robot,touchdown_spread", [("talos", 0.1), ("g1", 0.2)])
def test_three_robots_synchronize_their_steps_without_falling(robot, touchdown_spread, tmp_path):
    # Seed 0 starts near the 3-phase splay (phase spread 2.36 rad), the slowest case we know.
    group = GroupWalk(n=3, graph="all", k=1.0, coupled_time=8.0, seed=0)
    report = run_group_walk(load_robot(robot), group, out_dir=tmp_path,
                            log=lambda _: None)
    assert not report["fell"] and not any(r["fell"] for r in report["robots"])
    assert report["initial_phase_spread_rad"] > 2.0
    assert report["final_phase_spread_rad"] < 0.1 and report["synchronized_after_s"] < 8.0
    assert report["empirical_phase_rate_per_s"] >= report["certified_phase_rate_per_s"] == pytest.approx(3.0)
    assert report["measured_touchdown_phase_difference_rad"] < touchdown_spread
    assert report["final_position_spread_m"] < 0.02  # abreast: step-length coupling
    assert all(r["peak_torque_ratio"] < 1.0 and not r["safety"]["interventions"] for r in report["robots"])
    assert json.loads((tmp_path / "report.json").read_text())["n"] == 3 and (tmp_path / "phases.png").is_file()


def test_an_uncertified_group_needs_allow_unstable(capsys):
    assert main(["crowd", "walk", "--k", "-0.5", "--coupled-time", "2"]) == 2
    err = capsys.readouterr().err
    assert "phase_coupling" in err and "--allow-unstable" in err
    assert main(["crowd", "walk", "--spacing", "0.3"]) == 2
    assert "spacing = 0.3 is outside the allowed range [0.8, 5.0]" in capsys.readouterr().err
