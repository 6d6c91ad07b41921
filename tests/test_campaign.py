"""Drawer campaigns: trials from a file or drawn at random, run in processes of their own on the
local and the Ray backend with the same rows, resumable after Ctrl-C and after SIGKILL."""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import report_page

from robot_ctrl.cli import main
from robot_ctrl.eval.campaigns.drawer_campaign import (
    DRAWN_DISTANCES,
    draw_trials,
    method_dataset,
    read_trials,
    summarize,
)
from robot_ctrl.modes import FilterMode, SpeedClass
from robot_ctrl.synthesis.demonstrations import kinematic_dataset_path

TRIALS = """# distance slot speed [jump_time jump_distance]
1.6 back_left slow
1.7 front_right fast   # a comment after a trial
1.6 front_left nominal 2.0 1.9
"""
#: What differs between two runs of the same trial: its timing.
TIMING = ("wall_s", "rtf")


def campaign(out, trials_file, *extra):
    return [sys.executable, "-m", "robot_ctrl.cli", "campaign", "--trials", str(trials_file), "--out", str(out),
            "--quiet", *extra]


def rows(out):
    return {r["id"]: {k: v for k, v in r.items() if k not in TIMING}
            for r in json.loads((out / "campaign.json").read_text())["trials"]}


def trial_processes(temp: Path) -> int:
    """Processes of the trials of the campaign that runs with ``TMPDIR=temp`` (each trial's command
    line names its output folder there; the simulated robot and the filter worker are forks of it).
    Only this test's own campaign counts: other campaigns on the machine have other folders."""
    mine = f"{temp}/robot-ctrl-trial-"
    count = 0
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            args = cmdline.read_bytes().split(b"\0")
        except OSError:  # the process ended meanwhile
            continue
        count += any(arg.decode(errors="replace").startswith(mine) for arg in args)
    return count


def wait_for_rows(out, n, process, limit=300.0):
    """Until ``n`` trial rows exist in ``out`` (the campaign still running)."""
    start = time.monotonic()
    while len(list((out / "trials").glob("*/row.json"))) < n:
        assert process.poll() is None and time.monotonic() - start < limit
        time.sleep(0.2)


def test_trials_from_a_file_and_drawn_at_random(tmp_path):
    path = tmp_path / "trials.txt"
    path.write_text(TRIALS)
    trials = read_trials(path, ("ours",), FilterMode.FULL)
    assert [(t.distance, t.slot, t.speed, t.jump) for t in trials] == [
        (1.6, "back_left", SpeedClass.SLOW, None), (1.7, "front_right", SpeedClass.FAST, None),
        (1.6, "front_left", SpeedClass.NOMINAL, (2.0, 1.9))]
    # A trial keeps its report and time series; its campaign draws the page (no report.html to render).
    assert trials[1].trial().argv == ("drawer", "--distance", "1.7", "--slot", "front_right", "--speed", "fast",
                                      "--dynfilter", "full", "--sources", "3+2", "--no-html")
    assert dataclasses.replace(trials[1], method="ours-no-feedback").trial().argv[-1] == "--no-position-feedback"
    # campaign --robot: each trial runs on the campaign's robot
    assert dataclasses.replace(trials[1], robot="g1").trial().argv[:3] == ("drawer", "--robot", "g1")
    naive = dataclasses.replace(trials[1], method="naive", sources="5+4", dataset="/data/feasible.npz").trial()
    assert naive.argv[-7:] == ("--sources", "5+4", "--dataset", "/data/feasible.npz", "--no-html", "--method", "naive")
    assert naive.id == "001_naive_5+4_front_right_1.700m_fast"
    # the thesis's "WPG": the pipeline on the primitives the feasible runs came from, whatever --dataset says
    wpg = dataclasses.replace(trials[1], method="wpg-direct",
                              dataset=method_dataset("wpg-direct", "/data/feasible.npz", "talos"))
    assert wpg.trial().argv[-3:] == ("--dataset", str(kinematic_dataset_path("talos")), "--no-html")
    assert method_dataset("ours", "/data/feasible.npz", "talos") == "/data/feasible.npz"
    drawn = draw_trials(30, 1, (SpeedClass.SLOW, SpeedClass.MIDDLE, SpeedClass.FAST), ("ours",), FilterMode.FULL)
    classes = (SpeedClass.SLOW, SpeedClass.MIDDLE, SpeedClass.FAST)
    assert drawn == draw_trials(30, 1, classes, ("ours",), FilterMode.FULL)
    assert [sum(t.speed is s for t in drawn) for s in (SpeedClass.SLOW, SpeedClass.MIDDLE, SpeedClass.FAST)] == [10] * 3
    assert all(DRAWN_DISTANCES[0] <= t.distance <= DRAWN_DISTANCES[1] for t in drawn)
    assert len({t.id for t in drawn}) == 30 and len({t.distance for t in drawn}) > 25
    summary = summarize([{"method": "ours", "sources": "4+3", "speed": "fast", "fell": False, "success": True, "error": None,
                          "step_length_errors_m": [0.004, -0.006], "hand_error_m": 0.001,
                          "peak_ankle_pitch_torque_ratio": 0.4, "peak_grf_ratio": 0.8, "pelvis_error_m": -0.012,
                          "pelvis_lateral_m": 0.004, "pelvis_yaw_error_deg": -1.5},
                         {"method": "ours", "sources": "4+3", "speed": "fast", "fell": True, "success": False, "error": None,
                          "step_length_errors_m": [0.002], "hand_error_m": 0.003,
                          "peak_ankle_pitch_torque_ratio": 0.9, "peak_grf_ratio": 1.2, "pelvis_error_m": 0.008,
                          "pelvis_lateral_m": -0.011, "pelvis_yaw_error_deg": 0.5}])
    assert summary == [{"method": "ours", "sources": "4+3", "speed": "fast", "trials": 2, "falls": 1, "successes": 1, "errors": 0,
                        "step_length_error_median_m": 0.004, "step_length_error_max_m": 0.006,
                        "hand_error_median_m": 0.002, "hand_error_max_m": 0.003,
                        "peak_ankle_pitch_torque_ratio": 0.9, "peak_grf_ratio": 1.2, "pelvis_error_max_m": 0.012,
                        "pelvis_lateral_max_m": 0.011, "pelvis_yaw_error_max_deg": 1.5}]


@pytest.mark.parametrize("args,message", [
    (["--n", "0"], "--n 0 is outside the allowed range"),
    (["--n", "2", "--speeds", "slow,warp"], "--speeds 'warp' is not one of slow, middle, nominal, fast"),
    (["--n", "2", "--method", "magic"], "--method magic is not one of ours, ours-no-feedback, naive"),
    (["--n", "2", "--sources", "3+2,9+1"], "--sources 9+1: FIRST must be in [1, 8]"),
    (["--n", "2", "--method", "naive", "--dataset", "models/talos_walk_reach_demos.npz"],
     "demonstration set has no whole-body channels"),
    (["--n", "2", "--address", "1.2.3.4:6379"], "--address names a Ray cluster"),
    (["--trials", "/nonexistent/trials.txt"], "No such file"),
    (["--trials", "TRIALS_TOO_NEAR"],
     "trial 000_ours_3+2_back_left_0.500m_slow: distance = 0.5 m is outside the allowed range"),
])
def test_bad_campaign_input_is_refused_with_one_line(args, message, capsys, tmp_path):
    too_near = tmp_path / "too_near.txt"
    too_near.write_text("0.5 back_left slow\n")  # nearer than the comfort distance and a short step
    args = [str(too_near) if a == "TRIALS_TOO_NEAR" else a for a in args]
    assert main(["campaign", *args, "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err


def test_a_bad_trials_line_is_named(tmp_path, capsys):
    path = tmp_path / "trials.txt"
    path.write_text("1.6 back_left slow\n1.7 sideways fast\n")
    assert main(["campaign", "--trials", str(path), "--out", str(tmp_path / "c")]) == 2
    assert f"{path}:2: slot 'sideways' is not one of" in capsys.readouterr().err


def test_stopped_campaigns_resume_and_ray_gives_the_local_rows(tmp_path):
    pytest.importorskip("ray", reason="the cluster extra: pip install 'robot-ctrl[cluster]' (make test installs it)")
    path = tmp_path / "trials.txt"
    path.write_text(TRIALS)
    local = tmp_path / "local"
    # Ctrl-C while the second trial runs: it ends and keeps its row, the third never starts.
    # As from a terminal: SIGINT at its default (a test run started in the background has it ignored,
    # and a child would inherit that).
    process = subprocess.Popen(campaign(local, path, "--jobs", "1"), stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    wait_for_rows(local, 1, process)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=300)
    assert process.returncode == 130 and "run the same command again" in err, err[-500:]
    assert len(list((local / "trials").glob("*/row.json"))) == 2 and not (local / "campaign.json").exists()
    # SIGKILL while the third runs (its controller, simulated robot and filter worker all up): nothing
    # of it is left, and no process of it outlives the campaign.
    temp = tmp_path / "tmp"
    temp.mkdir()
    process = subprocess.Popen(campaign(local, path, "--jobs", "1"), stderr=subprocess.DEVNULL,
                               env=os.environ | {"TMPDIR": str(temp)})
    start = time.monotonic()
    while trial_processes(temp) < 3:
        assert time.monotonic() - start < 60
        time.sleep(0.1)
    time.sleep(1.0)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    time.sleep(1.5)
    assert len(list((local / "trials").glob("*/row.json"))) == 2 and not list((local / "trials").glob(".*"))
    assert trial_processes(temp) == 0
    # The same command finishes the third trial only.
    done = subprocess.run(campaign(local, path, "--jobs", "1"), capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-1000:]
    assert len(rows(local)) == 3 and all(r["success"] and not r["fell"] and r["error"] is None
                                         for r in rows(local).values())
    # The same trials on a Ray instance started here: the same rows (the physics is deterministic).
    ray = tmp_path / "ray"
    done = subprocess.run(campaign(ray, path, "--jobs", "2", "--backend", "ray"), capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-1000:]
    assert rows(ray) == rows(local)
    page = (ray / "campaign.html").read_text()
    assert "data:image/png;base64," in page and "Table 3.1" in page and "<td>slow</td>" in page


def test_the_campaign_page_sets_falls_beside_the_thesis(tmp_path):
    """Table 3.1's layout: a row per method and source count, falls per speed class, the thesis's
    row beside it where it has one; and the figures of Figs. 3.47, 3.41 and 3.46."""
    from robot_ctrl.eval.reports.campaign_report import render_campaign

    rows = [{"id": f"{k:03d}", "method": method, "sources": "3+2", "speed": speed, "fell": fell, "success": not fell,
             "error": None, "step_length_errors_m": [0.002, -0.004], "hand_error_m": 0.001,
             "peak_ankle_pitch_torque_ratio": 1.0 if fell else 0.5, "peak_grf_ratio": 1.2 if fell else 0.8,
             "zmp_lateral_error_rms_m": 0.012}
            for k, (method, speed, fell) in enumerate([("naive", "slow", True), ("naive", "fast", False),
                                                       ("ours", "slow", False), ("ours", "fast", False)])]
    page = render_campaign({"trials": rows, "summary": summarize(rows)}, tmp_path).read_text()
    table = page.split("speed class (thesis Table 3.1)</h2>")[1].split("</table>")[0]
    assert "<td>naive 3+2</td><td>1 of 1</td><td>0 of 1</td><td>0 of 10</td><td>10 of 10</td><td>7 of 10</td>" in table
    assert "<td>ours 3+2</td><td>0 of 1</td><td>0 of 1</td><td>–</td><td>–</td><td>–</td>" in table
    assert page.count("data:image/png;base64,") == 4 and "Fig. 3.46" in page
    # The first screen: how many fell and met every criterion, in the look every report has.
    assert report_page.title(page) == "Drawer campaign — 4 trials"
    assert report_page.verdict(page) == ("fail", "3 of 4 trials met every criterion, 1 fell, 0 ended in an error "
                                                 "(naive, ours)")


def test_the_campaign_page_shows_the_posture_after_the_step_before(tmp_path, talos):
    """Fig. 3.38 for the primitives of the campaign's own trials: two goals whose last short cycles
    differ end in different standing postures, per demonstration set and source count."""
    from robot_ctrl.eval.campaigns.drawer_campaign import campaign_transitions, transition_figure
    from robot_ctrl.eval.reports.campaign_report import render_campaign
    from robot_ctrl.eval.reports.transition_postures import transition_summary
    from robot_ctrl.synthesis.demonstrations import feasible_dataset_path

    rows = [{"id": "000", "method": method, "dataset": str(feasible_dataset_path("talos")), "sources": "3+2",
             "speed": "slow", "fell": False, "success": True, "error": None}
            for method in ("ours", "naive")]  # the naive method has no standing posture of its own
    transitions = campaign_transitions(rows, talos)
    assert [group for group, _ in transitions] == [{"dataset": rows[0]["dataset"], "sources": "3+2"}]
    summary = transition_summary(transitions[0][1])
    assert summary["short_cycles_m"] == [0.1746, 0.2516] and summary["transition_left_hand_distance_m"] > 0.002
    page = render_campaign({"trials": rows, "summary": summarize(rows),
                            "transition_postures": [g | transition_summary(p) for g, p in transitions]},
                           tmp_path, transition_figure(talos, transitions)).read_text()
    section = page.split("Fig. 3.38", 1)[1]
    assert "<td>talos_walk_reach_feasible.npz</td><td>3+2</td><td>17.5 / 25.2</td>" in section
    assert "data:image/png;base64," in section
