"""Drawer campaigns in rooms: cabinet poses from a trials file or drawn in random rooms, each
trial's command line, why a trial failed, and the campaign page's top view of the poses."""

import numpy as np
import pytest

from robot_ctrl.cli import main
from robot_ctrl.cli.campaign import _reachable
from robot_ctrl.eval.campaigns.drawer_campaign import (
    DRAWN_POSE_DISTANCES,
    DRAWN_ROOM_SIDES,
    draw_poses,
    failure_cause,
    read_trials,
    summarize,
)
from robot_ctrl.eval.reports.campaign_report import render_campaign
from robot_ctrl.geometry.drawer_geometry import DrawerGeometry
from robot_ctrl.geometry.room import CabinetPose, Room, plan_approach
from robot_ctrl.modes import FilterMode, SpeedClass

POSES = """# X,Y,YAW_DEG [slot] [speed] [room=W,D] [free-standing]
-2.5,1.0,0
1.6,-1.2,120 back_right slow room=7,6.5
2.5,0,90 free-standing fast   # beside the robot, facing left
"""
SPEEDS = (SpeedClass.SLOW, SpeedClass.MIDDLE, SpeedClass.FAST)
HANDOVER = 1.65  # [m] Talos's comfort distance and its drawer.handover_walk


def test_cabinet_poses_from_a_file_become_drawer_runs_in_their_rooms(tmp_path):
    path = tmp_path / "poses.txt"
    path.write_text(POSES)
    trials = read_trials(path, ("ours", "ours-no-feedback"), FilterMode.FULL)
    assert [(t.cabinet, t.slot, t.speed, t.room, t.free_standing) for t in trials[::2]] == [
        ((-2.5, 1.0, 0.0), "front_left", SpeedClass.NOMINAL, (6.0, 6.0), False),
        ((1.6, -1.2, 120.0), "back_right", SpeedClass.SLOW, (7.0, 6.5), False),
        ((2.5, 0.0, 90.0), "front_left", SpeedClass.FAST, (6.0, 6.0), True)]
    assert [t.method for t in trials[:2]] == ["ours", "ours-no-feedback"] and trials[2].distance == 2.0
    # What a user would type: the pose in one word (a negative X is no option), the room and its placement.
    assert trials[0].trial().argv[:5] == ("drawer", "--cabinet=-2.5,1,0", "--room", "6,6", "--slot")
    assert trials[4].trial().argv[1:5] == ("--cabinet=2.5,0,90", "--room", "6,6", "--free-standing")
    assert trials[2].id == "002_ours_3+2_back_right_at+1.60-1.20+120deg_slow"
    assert len({t.id for t in trials}) == len(trials)


@pytest.mark.parametrize("line,message", [
    ("1.6,-1.2 back_right", "the cabinet's pose X,Y,YAW_DEG must be 3 finite numbers"),
    ("1.6,-1.2,nan", "the cabinet's pose X,Y,YAW_DEG must be 3 finite numbers"),
    ("1.6,-1.2,120 sideways", "'sideways' is not a slot"),
    ("1.6,-1.2,120 room=7", "room=W,D must be 2 finite numbers"),
])
def test_a_bad_pose_line_is_named(line, message, tmp_path, capsys):
    path = tmp_path / "poses.txt"
    path.write_text(f"-2.5,1.0,0\n{line}\n")
    assert main(["campaign", "--trials", str(path), "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert f"{path}:2: {message}" in err and len(err.strip().splitlines()) == 1, err


def test_an_unreachable_pose_in_a_file_is_refused_before_any_trial_runs(tmp_path, capsys):
    path = tmp_path / "poses.txt"
    path.write_text("-2.5,1.0,0\n0.9,0,180 back_left\n")
    assert main(["campaign", "--trials", str(path), "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "trial 001_ours_3+2_back_left_at+0.90+0.00+180deg_nominal: cabinet = 0.9,0,180: the front panel is " \
           "0.90 m from the start" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "c").exists()


def test_random_poses_are_reachable_rooms_of_every_kind(talos):
    reachable = _reachable(talos, None)
    drawn = draw_poses(30, 7, SPEEDS, ("ours",), FilterMode.FULL, reachable)
    assert drawn == draw_poses(30, 7, SPEEDS, ("ours",), FilterMode.FULL, reachable)
    assert drawn != draw_poses(30, 8, SPEEDS, ("ours",), FilterMode.FULL, reachable)
    assert [t.index for t in drawn] == list(range(30)) and len({t.id for t in drawn}) == 30
    assert [sum(t.speed is s for t in drawn) for s in SPEEDS] == [10] * 3
    geometry = talos.config.drawer
    for t in drawn:  # each walked to: a path exists to its hand-over pose, in its own room
        x, y, yaw = t.cabinet
        assert DRAWN_POSE_DISTANCES[0] <= np.hypot(x, y) <= DRAWN_POSE_DISTANCES[1]
        assert all(DRAWN_ROOM_SIDES[0] <= side <= DRAWN_ROOM_SIDES[1] for side in t.room)
        plan = plan_approach(CabinetPose(x, y, np.radians(yaw)), geometry.footprint(),
                             Room(*t.room, against_wall=not t.free_standing), geometry.body_radius, HANDOVER)
        assert plan.walks
    # Rooms of both kinds, cabinets all round the robot and facing every way.
    assert 3 <= sum(not t.free_standing for t in drawn) <= 27
    bearings = np.degrees([np.arctan2(t.cabinet[1], t.cabinet[0]) for t in drawn])
    assert np.histogram(bearings, bins=4, range=(-180, 180))[0].min() >= 3
    assert np.ptp([t.cabinet[2] for t in drawn]) > 270
    # Per method, the same poses; a predicate that refuses every pose ends the draw with a reason.
    both = draw_poses(3, 7, SPEEDS, ("ours", "naive"), FilterMode.FULL, reachable)
    assert [(t.method, t.cabinet) for t in both[:2]] == [("ours", drawn[0].cabinet), ("naive", drawn[0].cabinet)]
    with pytest.raises(ValueError, match="no reachable cabinet pose in 100 draws"):
        draw_poses(1, 7, SPEEDS, ("ours",), FilterMode.FULL, lambda trial: False)


def test_random_poses_need_a_count(tmp_path, capsys):
    path = tmp_path / "poses.txt"
    path.write_text(POSES)
    assert main(["campaign", "--trials", str(path), "--poses", "random", "--out", str(tmp_path / "c")]) == 2
    assert "--poses random draws --n trials" in capsys.readouterr().err


REPORT = {"success": True, "fell": False, "fall_time_s": None, "step_length_error_max_m": 0.004,
          "hand_to_object_m": 0.003, "final_pelvis_to_drawer_m": 0.70, "comfort_distance_m": 0.6965,
          "drawer_opening_m": 0.30, "drawer_opening_required_m": 0.28, "approach": {"handover_time_s": 15.0},
          "stop_reason": "the task ended"}


def test_a_failed_trial_says_why():
    assert failure_cause(REPORT) is None
    fell_early = REPORT | {"success": False, "fell": True, "fall_time_s": 6.25}
    assert failure_cause(fell_early) == "fell at 6.25 s on the approach"
    assert failure_cause(REPORT | {"success": False, "fell": True, "fall_time_s": 18.0}) == "fell at 18.00 s"
    missed = REPORT | {"success": False, "drawer_opening_m": 0.2, "hand_to_object_m": 0.05}
    assert failure_cause(missed) == "not drawer opened, not object reached"
    assert failure_cause(REPORT | {"success": False, "final_pelvis_to_drawer_m": 0.74}) == \
        "not pelvis at the comfort distance"
    assert failure_cause(REPORT | {"success": False, "stop_reason": "the task did not end"}) == "the task did not end"


def test_the_campaign_page_shows_where_each_cabinet_stood_and_why_a_trial_failed(tmp_path):
    base = {"method": "ours", "sources": "3+2", "speed": "slow", "error": None, "step_length_errors_m": [0.003],
            "hand_error_m": 0.002, "peak_ankle_pitch_torque_ratio": 0.5, "peak_grf_ratio": 0.8,
            "zmp_lateral_error_rms_m": 0.01, "pelvis_lateral_m": 0.01, "room": [6.0, 6.0]}
    rows = [base | {"id": "000_a", "cabinet": [-2.5, 1.0, 0.0], "fell": False, "success": True, "cause": None,
                    "pelvis_error_m": 0.004, "pelvis_yaw_error_deg": 1.0},
            base | {"id": "001_b", "cabinet": [2.5, 0.0, 90.0], "fell": True, "success": False,
                    "cause": "fell at 6.25 s on the approach", "pelvis_error_m": 0.041, "pelvis_yaw_error_deg": -7.0}]
    page = render_campaign({"trials": rows, "summary": summarize(rows)}, tmp_path).read_text()
    assert page.count("data:image/png;base64,") == 5 and "Where each trial&#x27;s cabinet stood" in page
    assert "<li>001_b: fell at 6.25 s on the approach</li>" in page
    assert "Largest pelvis error from the comfort distance" in page and "41.0 mm" in page and "7.0°" in page
    straight = [r | {"cabinet": None} for r in rows]
    page = render_campaign({"trials": straight, "summary": summarize(straight)}, tmp_path).read_text()
    assert page.count("data:image/png;base64,") == 4 and "Largest pelvis error" not in page


def test_the_shipped_hard_rooms_are_ten_reachable_trials(talos):
    """configs/trials/hard_rooms.txt, the hard poses docs/drawer.md reports: behind the robot, facing
    sideways or away, a small room, a far corner; every one walked to by a planned path."""
    from pathlib import Path

    trials = read_trials(Path(__file__).parent.parent / "configs/trials/hard_rooms.txt", ("ours",), FilterMode.FULL)
    reachable = _reachable(talos, None)
    assert len(trials) == 10 and all(reachable(t) for t in trials)
    assert sum(t.free_standing for t in trials) == 3
    assert {t.room for t in trials} == {(6.0, 6.0), (5.0, 5.0), (8.0, 8.0)}
