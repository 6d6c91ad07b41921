"""Each script in examples/ runs as a user runs it (its own interpreter, short durations through
its arguments) and does what its docstring says, measured in the simulation."""

import json
import re
import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def run(name: str, *args: str) -> str:
    done = subprocess.run([sys.executable, str(EXAMPLES / name), *args], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_walk_in_your_own_loop_walks_the_velocities_it_was_given():
    report = json.loads(run("walk_your_own_loop.py", "--duration", "9"))
    assert report["fell"] is False and report["time_s"] == 9.0 and report["safety_interventions"] == {}
    x, y = report["final_base_xy_m"]
    assert 1.0 < x < 1.8 and 0.05 < y < 0.6  # 4 s straight at 0.25 m/s, then 3 s of a left arc
    assert report["steps"] >= 7 and report["peak_torque_ratio"] < 1.0


def test_a_custom_controller_draws_the_circle_with_the_measured_hand():
    line = run("hand_circle.py", "--turns", "1.2")
    error = float(re.search(r"largest hand error ([\d.]+) mm", line).group(1))
    assert "fell False" in line and "safety interventions {}" in line, line
    assert 0.0 < error < 15.0, line  # the real hand within 15 mm of the moving target


def test_the_drawer_task_through_the_api(tmp_path):
    line = run("drawer_task.py", "--distance", "1.6", "--slot", "back_left", "--out", str(tmp_path))
    assert "success True" in line and "fell False" in line, line
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["success"] and report["drawer_opening_m"] >= report["drawer_opening_required_m"]
