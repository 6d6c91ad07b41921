"""A run's report.html read as a person reads it: the first screen names the task, says whether it
worked and why not, and gives the key figures against their goals; the same look for every report."""

import copy
import json
import threading
import time

import pytest
import report_page

from robot_ctrl.eval.reports.html_report import render_report
from robot_ctrl.kernels import _REGISTERED, load_kernels

#: A drawer run's report as the scenario writes it (fields the page reads; the per-joint ones cut short).
DRAWER = {
    "fell": False, "fall_time_s": None, "fall_reason": None, "time_s": 14.29, "peak_torque_ratio": 0.9868,
    "peak_torque_joint": "arm_left_4_joint", "peak_grf_n": {"left": 941.65, "right": 950.33}, "robot": "talos",
    "distance_m": 2.0, "slot": "front_left", "goal_jumps": [], "dynfilter": "full", "speed": "nominal",
    "method": "ours", "success": True, "step_length_errors_m": [-0.00374, -0.00396, 0.00438, -0.00039],
    "step_length_error_max_m": 0.00438, "comfort_distance_m": 0.6471, "final_pelvis_to_drawer_m": 0.6476,
    "drawer_opening_m": 0.18, "drawer_opening_required_m": 0.14, "drawer_pull_force_peak_n": 33.98, "grasp": "contact",
    "hand_to_object_m": 0.0003, "zmp_in_support_ratio": 1.0, "grf_limit_n": 1239.8, "base_estimate_error": None,
    "safety": {"interventions": {}, "mode": "normal", "demanded_peak_torque_ratio": {"arm_left_4_joint": 0.95}},
    "command": "robot-ctrl drawer --distance 2.0 --slot front_left --out runs/drawer",
}


def rendered(tmp_path, report: dict) -> str:
    (tmp_path / "report.json").write_text(json.dumps(report))
    return render_report(tmp_path).read_text()


def test_a_successful_drawer_run_says_so_with_its_figures_against_their_goals(tmp_path):
    page = rendered(tmp_path, DRAWER)
    assert report_page.title(page) == "Drawer task — Talos, 2.0 m, front-left slot"
    assert report_page.verdict(page)[0] == "ok" and report_page.verdict(page)[1].startswith("Success")
    figures = report_page.key_figures(page)
    assert figures["drawer_opening_m"] == ("18.0 cm", "≥ 95% of 14 cm (the hand's clearance)", True)
    assert figures["hand_to_object_m"] == ("0.3 mm", "≤ 20 mm", True)
    assert figures["step_length_error_max_m"] == ("4.4 mm", "≤ 10 mm (thesis Fig. 3.41)", True)
    assert figures["final_pelvis_to_drawer_m"] == ("0.648 m", "0.647 ± 30 mm (comfort)", True)
    assert figures["peak_torque_ratio"] == ("0.99 (arm_left_4)", "≤ 1", True)
    assert figures["peak_grf_n"] == ("950 N", "≤ 1240 N", True)
    assert figures["safety.interventions"] == ("0", "0", True)
    assert report_page.command(page) == DRAWER["command"]
    rest = report_page.fields(page)
    assert "base_estimate_error" not in rest and "fall_time_s" not in rest  # no None rows
    assert rest["grasp"] == "contact" and rest["distance_m"] == "2.000 m"
    assert '<a href="report.json">' in page and "http" not in page


@pytest.mark.parametrize("change, verdict, failed_key", [
    (dict(drawer_opening_m=0.10, success=False), "Failed: not drawer opened", "drawer_opening_m"),
    (dict(hand_to_object_m=0.05, success=False), "Failed: not object reached", "hand_to_object_m"),
    (dict(step_length_error_max_m=0.012, success=False), "Failed: not steps within 10 mm", "step_length_error_max_m"),
    (dict(final_pelvis_to_drawer_m=0.70, success=False), "Failed: not pelvis at the comfort distance",
     "final_pelvis_to_drawer_m"),
    (dict(fell=True, fall_time_s=6.25, fall_reason="base below 60 % of its start height", success=False),
     "Fell at 6.25 s: base below 60 % of its start height", None),
])
def test_a_failed_drawer_run_names_what_failed(tmp_path, change, verdict, failed_key):
    page = rendered(tmp_path, copy.deepcopy(DRAWER) | change)
    assert report_page.verdict(page) == ("fail", verdict)
    marks = {key: mark for key, (_, _, mark) in report_page.key_figures(page).items()}
    assert [key for key, mark in marks.items() if mark is False] == ([failed_key] if failed_key else [])


def test_limits_missed_are_marked(tmp_path):
    report = copy.deepcopy(DRAWER) | dict(peak_torque_ratio=1.3, zmp_in_support_ratio=0.9,
                                          peak_grf_n={"left": 1300.0, "right": 900.0})
    report["safety"]["interventions"] = {"torque_clamped": 4, "position_step": 2}
    figures = report_page.key_figures(rendered(tmp_path, report))
    assert figures["peak_torque_ratio"][2] is False and figures["zmp_in_support_ratio"] == ("90.0%", "≥ 99%", False)
    assert figures["peak_grf_n"] == ("1300 N", "≤ 1240 N", False)
    assert figures["safety.interventions"] == ("6", "0", False)


def test_balance_and_group_walk_pages_have_their_own_key_figures(tmp_path):
    balance = {"fell": False, "robot": "g1", "hand_error_m": 0.0121, "hand_target_floor_m": [0.4, -0.2, 0.8],
               "peak_torque_ratio": 0.38, "peak_torque_joint": "left_ankle_pitch_joint",
               "safety": {"interventions": {}}}
    page = rendered(tmp_path, balance)
    assert report_page.title(page) == "Balance demo — G1"
    assert report_page.verdict(page)[0] == "fail"  # 12.1 mm: beyond the hand's 1 cm
    assert report_page.key_figures(page)["hand_error_m"] == ("12.1 mm", "≤ 10 mm", False)
    group = {"robot": "talos", "n": 3, "graph": "ring", "gains": {"k": 0.5}, "fell": False,
             "robots": [{"fell": False, "peak_torque_ratio": 0.5}, {"fell": False, "peak_torque_ratio": 0.61}],
             "synchronized_after_s": 5.22, "final_phase_spread_rad": 0.0, "sync_tolerance_rad": 0.1,
             "empirical_phase_rate_per_s": 2.9, "certified_phase_rate_per_s": 3.0}
    page = rendered(tmp_path, group)
    assert report_page.title(page) == "Group walk — 3 × Talos, ring coupling, k = 0.5"
    assert report_page.verdict(page) == ("ok", "Synchronized 5.22 s after the coupling came on; nobody fell")
    figures = report_page.key_figures(page)
    assert figures["empirical_phase_rate_per_s"] == ("2.90 1/s", "≥ 3.00 1/s (certified)", False)
    assert figures["robots[].peak_torque_ratio"] == ("0.61", "≤ 1", True)


def test_a_slow_kernel_load_is_announced_while_it_runs():
    """A first run compiles for tens of seconds: ``slow`` hears of it after ``after`` seconds and
    then every ``every``, from another thread, with the kernels done so far."""

    class SlowCompile:  # stands for a dispatcher whose machine code is not cached yet
        def compile(self, signature):
            time.sleep(0.25)

    heard = []
    _REGISTERED.append((SlowCompile(), ((), ())))
    try:
        seconds = load_kernels(lambda done, total: heard.append((done, total, threading.current_thread().name)),
                               after=0.1, every=0.2)
    finally:
        _REGISTERED.pop()
    assert seconds >= 0.5
    assert len(heard) >= 2 and all(name == "kernel-progress" for *_, name in heard)
    done = [d for d, *_ in heard]
    assert done == sorted(done) and done[-1] < heard[0][1] == sum(len(s) for _, s in _REGISTERED) + 2
    quiet = []
    load_kernels(lambda done, total: quiet.append(done), after=5.0)  # all loaded: quick and silent
    assert not quiet


def test_the_page_shows_a_frame_of_the_runs_video_near_its_end(tmp_path):
    """A run recorded with --video: the first screen shows the frame at 95 % of the video (here a
    synthetic one: black, then white for its last 10 %)."""
    import base64
    import io
    import re

    import imageio_ffmpeg
    import matplotlib.pyplot as plt
    import numpy as np

    video = tmp_path / "run.mp4"
    writer = imageio_ffmpeg.write_frames(str(video), (64, 48), fps=30, macro_block_size=16)
    writer.send(None)
    for k in range(60):
        writer.send(np.full((48, 64, 3), 255 if k >= 54 else 0, np.uint8).tobytes())
    writer.close()
    page = rendered(tmp_path, copy.deepcopy(DRAWER) | {"video": str(video)})
    png = re.search(r'<img alt="The video \(run.mp4\) near its end" src="data:image/png;base64,([^"]+)"', page).group(1)
    frame = plt.imread(io.BytesIO(base64.b64decode(png)))
    assert frame.shape[:2] == (48, 64) and frame[..., :3].mean() > 0.9
    assert "near its end" not in rendered(tmp_path, copy.deepcopy(DRAWER) | {"video": str(tmp_path / "gone.mp4")})
