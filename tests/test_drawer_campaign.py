"""A drawer campaign's trials and summary without running any: the trial file's lines and errors, the
random draw, each trial's command line and the summary's groups, order and statistics."""

import dataclasses

import pytest

from robot_ctrl.eval.campaigns.drawer_campaign import (
    DrawerTrial,
    draw_trials,
    drawer_row,
    parse_methods,
    parse_speeds,
    read_trials,
    summarize,
)
from robot_ctrl.eval.campaigns.trial_process import TrialOutcome
from robot_ctrl.geometry.drawer_geometry import SLOTS
from robot_ctrl.modes import FilterMode, SpeedClass


def test_a_trial_file_runs_each_line_once_per_method(tmp_path):
    path = tmp_path / "trials.txt"
    path.write_text("# distance slot speed [jump]\n\n1.6 back_left slow  # a comment # with a hash\n"
                    "1.7 front_right fast 2.5 1.9\n")
    trials = read_trials(path, ("ours", "naive"), FilterMode.LEGS)
    assert trials == [DrawerTrial(0, "ours", 1.6, "back_left", SpeedClass.SLOW, None, FilterMode.LEGS),
                      DrawerTrial(1, "naive", 1.6, "back_left", SpeedClass.SLOW, None, FilterMode.LEGS),
                      DrawerTrial(2, "ours", 1.7, "front_right", SpeedClass.FAST, (2.5, 1.9), FilterMode.LEGS),
                      DrawerTrial(3, "naive", 1.7, "front_right", SpeedClass.FAST, (2.5, 1.9), FilterMode.LEGS)]
    # The goal jump reaches the drawer command as TIME:DISTANCE.
    assert trials[2].trial().argv == ("drawer", "--distance", "1.7", "--slot", "front_right", "--speed", "fast",
                                      "--dynfilter", "legs", "--sources", "3+2", "--goal-jump", "2.5:1.9", "--no-html")


@pytest.mark.parametrize("text,message", [
    ("1.6 back_left slow\n1.6 back_left\n", ":2: expected 'distance slot speed [jump_time jump_distance]', "
                                            "got '1.6 back_left'"),
    ("\n1.6 back_left slow 2.0\n", ":2: expected 'distance slot speed [jump_time jump_distance]', "
                                   "got '1.6 back_left slow 2.0'"),
    ("far back_left slow\n", ":1: distance and jump must be numbers, got 'far back_left slow'"),
    ("1.6 back_left slow 2.0 near\n", ":1: distance and jump must be numbers, got '1.6 back_left slow 2.0 near'"),
    ("1.6 top_shelf slow\n", f":1: slot 'top_shelf' is not one of {', '.join(SLOTS)}"),
    ("# nothing\n1.6 back_left warp\n", ":2: speed 'warp' is not one of slow, middle, nominal, fast"),
    ("# only a comment\n\n", ": no trial in it"),
])
def test_a_bad_trial_line_is_named_by_file_and_line(text, message, tmp_path):
    path = tmp_path / "trials.txt"
    path.write_text(text)
    with pytest.raises(ValueError) as raised:
        read_trials(path, ("ours",), FilterMode.FULL)
    assert str(raised.value) == f"{path}{message}"


def test_random_trials_are_drawn_once_and_run_once_per_method():
    trials = draw_trials(4, 7, (SpeedClass.SLOW, SpeedClass.FAST), ("ours", "naive"), FilterMode.OFF)
    assert [t.index for t in trials] == list(range(8))
    assert [t.method for t in trials] == ["ours", "naive"] * 4
    assert [t.speed for t in trials[::2]] == [SpeedClass.SLOW, SpeedClass.FAST] * 2
    for ours, naive in zip(trials[::2], trials[1::2]):  # one draw, both methods
        assert (ours.distance, ours.slot, ours.speed) == (naive.distance, naive.slot, naive.speed)
    for t in trials:
        assert t.slot in SLOTS and t.jump is None and t.dynfilter is FilterMode.OFF and t.seed == 7
        assert 2.0 <= t.distance <= 5.5 and round(t.distance, 3) == t.distance  # drawn to the millimetre
    assert len({t.distance for t in trials}) == 4 and len({t.slot for t in draw_trials(30, 7, (SpeedClass.SLOW,),
                                                                                     ("ours",), FilterMode.OFF)}) > 1


def row(method="ours", speed="slow", **fields):
    return {"method": method, "speed": speed, "fell": False, "success": True, "error": None} | fields


def test_the_summary_groups_by_method_sources_and_speed_in_speed_order():
    rows = [row(speed="fast", sources="4+3"), row(speed="slow", sources="4+3"), row(speed="middle", sources="4+3"),
            row("naive", "slow"), row(speed="nominal"),  # no sources: the default 3+2
            row(speed="nominal", sources="3+2", fell=True, success=False, error="timeout")]
    summary = summarize(rows)
    assert [(s["method"], s["sources"], s["speed"], s["trials"]) for s in summary] == [
        ("naive", "3+2", "slow", 1), ("ours", "3+2", "nominal", 2),
        ("ours", "4+3", "slow", 1), ("ours", "4+3", "middle", 1), ("ours", "4+3", "fast", 1)]
    nominal = summary[1]
    assert (nominal["falls"], nominal["successes"], nominal["errors"]) == (1, 1, 1)
    # Nothing measured (no step errors, hand, ankle or GRF figures): no statistic rather than a number.
    assert all(nominal[k] is None for k in ("step_length_error_median_m", "step_length_error_max_m",
                                            "hand_error_median_m", "hand_error_max_m",
                                            "peak_ankle_pitch_torque_ratio", "peak_grf_ratio"))


def test_the_summary_statistics_are_rounded_to_five_decimals():
    summary = summarize([row(step_length_errors_m=[0.0012344, -0.0023456789], hand_error_m=0.0011111111,
                             peak_ankle_pitch_torque_ratio=0.123456789, peak_grf_ratio=None),
                         row(step_length_errors_m=[], hand_error_m=None, peak_ankle_pitch_torque_ratio=None,
                             peak_grf_ratio=0.98765432)])
    [s] = summary
    assert s["step_length_error_median_m"] == 0.00179 and s["step_length_error_max_m"] == 0.00235
    assert s["hand_error_median_m"] == s["hand_error_max_m"] == 0.00111
    assert s["peak_ankle_pitch_torque_ratio"] == 0.12346 and s["peak_grf_ratio"] == 0.98765


def test_a_trials_row_holds_its_settings_and_its_reports_figures():
    trial = DrawerTrial(3, "ours", 2.5, "front_left", SpeedClass.MIDDLE, (2.0, 2.8), FilterMode.FULL, seed=5,
                        dataset="/data/feasible.npz", sources="4+3")
    settings = {"id": trial.id, "method": "ours", "distance_m": 2.5, "slot": "front_left", "speed": "middle",
                "jump": [2.0, 2.8], "seed": 5, "dataset": "/data/feasible.npz", "sources": "4+3", "dynfilter": "full",
                "cabinet": None, "room": None, "free_standing": False}
    report = {"fell": False, "fall_time_s": None, "success": True, "step_length_errors_m": [0.004, -0.006],
              "step_length_error_max_m": 0.006, "hand_to_object_m": 0.0009, "drawer_opening_m": 0.18,
              "peak_ankle_pitch_torque_ratio": {"left": 0.41, "right": 0.52},
              "peak_grf_n": {"left": 900.0, "right": 1234.56},
              "grf_limit_n": 1500.0, "zmp_error_rms_m": {"x": 0.03, "y": 0.012},
              "safety": {"interventions": {"torque_clamped": 2}}, "rtf": 3.1}
    assert drawer_row(trial, report, TrialOutcome(trial.id, wall_s=41.237)) == settings | {
        "wall_s": 41.24, "error": None, "fell": False, "fall_time_s": None, "success": True,
        "step_length_errors_m": [0.004, -0.006], "step_length_error_max_m": 0.006, "hand_error_m": 0.0009,
        "drawer_opening_m": 0.18, "peak_ankle_pitch_torque_ratio": 0.52, "peak_grf_ratio": 0.823,
        "zmp_lateral_error_rms_m": 0.012, "safety_interventions": {"torque_clamped": 2}, "rtf": 3.1, "cause": None,
        "pelvis_error_m": None, "pelvis_lateral_m": None, "pelvis_yaw_error_deg": None, "handover_error": None,
        "unintended_contacts": None}
    # A report that measured nothing of a kind, and no report at all (the run died: its error says why).
    bare = {"fell": True, "fall_time_s": 4.2, "success": False, "grf_limit_n": 1500.0,
            "safety": {"interventions": {}}, "rtf": 2.0}
    row = drawer_row(trial, bare, TrialOutcome(trial.id))
    assert row["step_length_errors_m"] == [] and row["fall_time_s"] == 4.2
    assert all(row[k] is None for k in ("step_length_error_max_m", "hand_error_m", "drawer_opening_m",
                                        "peak_ankle_pitch_torque_ratio", "peak_grf_ratio", "zmp_lateral_error_rms_m"))
    died = drawer_row(dataclasses.replace(trial, jump=None), None,
                      TrialOutcome(trial.id, error="timeout", wall_s=600.0))
    assert died == settings | {"jump": None, "wall_s": 600.0, "error": "timeout", "fell": None, "success": False,
                               "cause": "timeout"}


def test_methods_and_speed_classes_from_the_command_line():
    assert parse_methods(" ours, naive ,") == ("ours", "naive")
    for text, named in (("ours,magic,oracle", "magic, oracle"), (" , ", "' , '")):
        with pytest.raises(ValueError) as raised:
            parse_methods(text)
        assert str(raised.value) == f"method {named} is not one of ours, ours-no-feedback, naive, wpg-direct"
    assert parse_speeds("fast, slow") == (SpeedClass.FAST, SpeedClass.SLOW)
    assert parse_speeds(" ,") == (SpeedClass.SLOW, SpeedClass.MIDDLE, SpeedClass.FAST)
