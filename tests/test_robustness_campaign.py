"""The robustness campaign runs real pushed and mismatched walks side by side and reports them."""

import json

import report_page

from robot_ctrl.cli import main
from robot_ctrl.eval.campaigns.campaign_backends import LocalBackend
from robot_ctrl.eval.campaigns.robustness_campaign import run_robustness
from robot_ctrl.eval.reports.robustness_report import render_robustness


def test_a_small_campaign(tmp_path):
    result = run_robustness(tmp_path, LocalBackend(2), directions=(-90,), phases=("single_mid",),
                            magnitudes=(0.2, 2.0), mismatch={"latency 10 ms": ("--latency-ms", "10")},
                            log=lambda _: None, progress=False)
    # 0.2 N·s/kg to the right mid-step is survived, 2 N·s/kg is not: the largest survived is 0.2.
    (cell,) = result["largest_survived_push"]
    bound, ended = cell["lip_capturable_ns_per_kg"], cell["final_position_error_m"]
    own = cell["lip_capturable_own_timing_ns_per_kg"]
    assert cell == {"direction_deg": -90, "phase": "single_mid", "impulse_ns_per_kg": 0.2,
                    "final_position_error_m": ended, "lip_capturable_ns_per_kg": bound,
                    "lip_capturable_own_timing_ns_per_kg": own}
    survived = json.loads((tmp_path / "trials" / "push_single_mid_-90_0.2" / "report.json").read_text())
    assert ended == survived["final_position_error_m"] < 0.05
    pushed = json.loads((tmp_path / "trials" / "push_single_mid_-90_2.0" / "report.json").read_text())
    assert pushed["fell"] is True and pushed["disturbances"]["pushes"][0]["impulse_ns_per_kg"] == 2.0
    # Mid-step on the right foot, pushed right: only the right sole's outer edge can catch it (the feet
    # do not cross), from a DCM a few centimetres inside that edge: a bound between the two pushes.
    assert pushed["push_capture"] == [{"time_s": 2.8, "support": "right", "lip_capturable_ns_per_kg": bound,
                                       "lip_capturable_own_timing_ns_per_kg": own}]
    assert 0.3 < bound < 0.6 and own == bound  # (on that side the landing's time does not matter)
    (latency,) = result["mismatch"]
    assert latency["walked"] and latency["final_position_error_m"] < 0.05
    page = (tmp_path / "robustness.html").read_text()
    assert f"<td>0.2 ({bound:.2f} | {own:.2f})</td>" in page
    weakest = min(c["impulse_ns_per_kg"] for c in result["largest_survived_push"])
    assert report_page.title(page) == f"Robustness — {result['walk']}"
    assert report_page.verdict(page) == ("ok", f"Every push direction and gait phase survived at least {weakest:g} "
                                               "N·s/kg; 1 of 1 model mismatches walked")
    assert "data:image/png;base64," in page and "latency 10 ms" in page and "http" not in page.replace("http-equiv", "")
    assert json.loads((tmp_path / "robustness.json").read_text()) == json.loads(json.dumps(result))
    assert "from the goal</td>" not in page
    cell["final_position_error_m"] = 0.24  # a walk that survived but ended far from its goal is marked
    assert "<td>0.2 (" + f"{bound:.2f} | {own:.2f}), ended 240 mm from the goal</td>" in render_robustness(
        result, tmp_path / "marked.html").read_text()


def test_campaign_options_are_checked(capsys):
    assert main(["robustness", "--jobs", "0"]) == 2
    assert "--jobs 0 is outside the allowed range [1, 64]" in capsys.readouterr().err
    assert main(["robustness", "--double-support", "0"]) == 2
    assert "--double-support 0.0 must be a multiple of 0.1 s in [0.1, 1] s" in capsys.readouterr().err
