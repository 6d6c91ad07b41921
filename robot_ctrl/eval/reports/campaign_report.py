"""``DIR/campaign.html``: a drawer campaign on one self-contained page (figures as embedded PNG):
falls per method, source count and speed class beside the thesis's (Table 3.1), the summary per
method and speed class, histograms of the step-length and hand errors (thesis Fig. 3.41, right),
each trial's peak ankle pitch torque and vertical ground reaction force against the limits per
method (Fig. 3.47), each trial's lateral ZMP error (Fig. 3.46), the peaks against time for the
trials with the largest ones, and the learned posture's dependence on the step before standing
(Fig. 3.38)."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from robot_ctrl.eval.recording.drawer_recorder import COMFORT_TOLERANCE
from robot_ctrl.eval.reports.figures import figure_png
from robot_ctrl.eval.reports.page import KeyFigure, Summary, Verdict, first_screen, page

#: The thesis's numbers for its method (3.8.4): falls of 30 new trials per speed class (Table 3.1),
#: step-length errors (Fig. 3.41), peak torque and GRF within the robot's limits (Fig. 3.47).
THESIS = {"falls": "0 of 10 per speed class (Table 3.1)", "step_length_error": "< 10 mm, often < 5 mm (Fig. 3.41)",
          "peaks": "within the robot's limits, ratio < 1 (Fig. 3.47)"}
SUMMARY_COLUMNS = (("method", "method"), ("sources", "sources"), ("speed", "speed"), ("trials", "trials"), ("falls", "falls"),
                   ("successes", "successes"), ("errors", "errors"),
                   ("step_length_error_median_m", "step error median [mm]"),
                   ("step_length_error_max_m", "step error max [mm]"),
                   ("hand_error_median_m", "hand error median [mm]"),
                   ("hand_error_max_m", "hand error max [mm]"),
                   ("peak_ankle_pitch_torque_ratio", "peak ankle pitch torque / limit"),
                   ("peak_grf_ratio", "peak vertical GRF / limit"),
                   ("pelvis_error_max_m", "pelvis off the comfort distance, max [mm]"),
                   ("pelvis_lateral_max_m", "pelvis off the cabinet's axis, max [mm]"),
                   ("pelvis_yaw_error_max_deg", "pelvis heading off the cabinet's, max [°]"))
PEAK_TRIALS = 3  # trials shown against time
HEADING_TOLERANCE_DEG = 5.0  # a pelvis facing the cabinet, in a room
ERROR_BINS_MM = np.logspace(-1, 4, 41)  # 0.1 mm to 10 m
SPEEDS = ("slow", "middle", "fast")
#: Table 3.1: falls of 10 new trials per speed class (slow, middle, fast), naive ML per source count.
THESIS_FALLS = {"naive 3+2": (0, 10, 7), "naive 4+3": (1, 0, 2), "naive 5+4": (0, 5, 10), "ours 4+3": (0, 0, 0)}


def _cell(key: str, value) -> str:
    if value is None:
        return "–"
    if key.endswith("_m"):
        return f"{value * 1e3:.1f}"
    if key.endswith("_deg"):
        return f"{value:.1f}"
    return f"{value:.3f}" if isinstance(value, float) else str(value)


def _label(axes, xlabels, ylabels) -> None:
    for ax, x, y in zip(axes, xlabels, ylabels):
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        if ax.get_legend_handles_labels()[1]:  # a panel with nothing to plot (no trial of its kind) has no legend
            ax.legend(fontsize=7)


def _group(row: dict) -> str:
    return f"{row['method']} {row.get('sources', '3+2')}"


def _falls_table(summary: list[dict]) -> str:
    """Table 3.1's layout: a row per method and source count, falls of trials per speed class, and
    the thesis's row where it has one."""
    cells: dict[str, dict[str, str]] = {}
    for s in summary:
        cells.setdefault(f"{s['method']} {s.get('sources', '3+2')}", {})[s["speed"]] = f"{s['falls']} of {s['trials']}"
    speeds = [v for v in SPEEDS if any(v in row for row in cells.values())] + \
        sorted({v for row in cells.values() for v in row} - set(SPEEDS))
    head = "".join(f"<th>{v}</th>" for v in speeds) + "".join(f"<th>thesis {v}</th>" for v in SPEEDS)
    rows = "".join(
        f"<tr><td>{html.escape(label)}</td>" + "".join(f"<td>{row.get(v, '–')}</td>" for v in speeds)
        + "".join(f"<td>{n} of 10</td>" if label in THESIS_FALLS else "<td>–</td>"
                  for n in THESIS_FALLS.get(label, (None,) * 3)) + "</tr>" for label, row in sorted(cells.items()))
    return f"<table><tr><th>falls</th>{head}</tr>{rows}</table>"


def _peaks_per_method(rows: list[dict]):
    """Each trial's peak ankle pitch torque and peak vertical GRF over their limits, per method and
    source count (thesis Fig. 3.47: a ratio above 1 is beyond what the robot can do)."""
    import matplotlib.pyplot as plt

    labels = sorted({_group(r) for r in rows})
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4))
    for ax, key in zip(axes, ("peak_ankle_pitch_torque_ratio", "peak_grf_ratio")):
        for k, label in enumerate(labels):
            values = [r[key] for r in rows if _group(r) == label and r.get(key) is not None]
            ax.plot(np.full(len(values), k) + np.linspace(-0.2, 0.2, len(values)), values, "o", ms=3, alpha=0.7)
        ax.axhline(1.0, color="r", ls="--", lw=1, label="limit")
        ax.set_xticks(range(len(labels)), labels, rotation=20, fontsize=8)
    _label(axes, ("", ""), ("peak |ankle pitch torque| / limit", "peak vertical GRF / limit"))
    return fig


def _lateral_zmp(rows: list[dict]):
    """Each trial's lateral ZMP error (measured − planned across the heading, RMS over single
    support) per method and source count (thesis Fig. 3.46); none for a method without a plan."""
    import matplotlib.pyplot as plt

    labels = sorted({_group(r) for r in rows if r.get("method") != "naive"})
    fig, ax = plt.subplots(figsize=(10, 3.0))
    for k, label in enumerate(labels):
        values = [r["zmp_lateral_error_rms_m"] * 1e3 for r in rows
                  if _group(r) == label and r.get("zmp_lateral_error_rms_m") is not None]
        ax.plot(np.full(len(values), k) + np.linspace(-0.2, 0.2, len(values)), values, "o", ms=3, alpha=0.7)
    ax.set_xticks(range(len(labels)), labels, rotation=20, fontsize=8)
    ax.set_ylabel("lateral ZMP error, RMS [mm]")
    return fig


def _poses(rows: list[dict]):
    """Top view of the trials in rooms: each cabinet's front panel point and the way it faces, the
    robot's start at the origin."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    ax.annotate("", (0.4, 0.0), (0.0, 0.0), arrowprops=dict(arrowstyle="->", color="k", lw=2))
    ax.plot(0.0, 0.0, "ko", label="start")
    for r in rows:
        if not r.get("cabinet"):
            continue
        x, y, yaw = r["cabinet"]
        color = "tab:green" if r["success"] and not r["fell"] else "tab:red"
        ax.annotate("", (x + 0.35 * np.cos(np.radians(yaw)), y + 0.35 * np.sin(np.radians(yaw))), (x, y),
                    arrowprops=dict(arrowstyle="->", color=color, lw=1.5))
        ax.plot(x, y, "s", color=color, ms=5)
        ax.text(x, y, f" {r['id'][:3]}", fontsize=7, color=color)
    ax.set_aspect("equal")
    ax.grid(alpha=0.3)
    ax.set_xlabel("x, start frame [m]")
    ax.set_ylabel("y, start frame [m]")
    return fig


def _histograms(rows: list[dict]):
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4))
    for label in sorted({_group(r) for r in rows}):
        group = [r for r in rows if _group(r) == label]
        steps = [abs(e) * 1e3 for r in group for e in r.get("step_length_errors_m") or []]
        hands = [r["hand_error_m"] * 1e3 for r in group if r.get("hand_error_m") is not None]
        # Log bins: errors of a tenth of a millimetre and of metres on one axis.
        axes[0].hist(np.clip(steps, 0.1, None), bins=ERROR_BINS_MM, histtype="step", lw=1.5, label=label)
        axes[1].hist(np.clip(hands, 0.1, None), bins=ERROR_BINS_MM, histtype="step", lw=1.5, label=label)
    for ax in axes:
        ax.set_xscale("log")
    axes[0].axvline(10.0, color="k", ls="--", lw=1, label="thesis: < 10 mm")
    _label(axes, ("|realized − planned step length| [mm]", "right hand to object at the end [mm]"), ("count", "count"))
    return fig


def _peaks_over_time(rows: list[dict], out_dir: Path):
    """Ankle pitch torque and vertical GRF of the trials with the largest peaks, against time."""
    import matplotlib.pyplot as plt

    ranked = sorted((r for r in rows if r.get("peak_ankle_pitch_torque_ratio") is not None),
                    key=lambda r: -max(r["peak_ankle_pitch_torque_ratio"], r["peak_grf_ratio"] or 0.0))[:PEAK_TRIALS]
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4))
    for r in ranked:
        path = out_dir / "trials" / r["id"] / "timeseries.npz"
        if not path.is_file():
            continue
        s = np.load(path)
        line, = axes[0].plot(s["drawer_t"], np.abs(s["ankle_pitch_torque"]).max(axis=1), lw=0.8, label=r["id"])
        axes[1].plot(s["t"], s["grf"].max(axis=1), lw=0.8, color=line.get_color(), label=r["id"])
        axes[0].axhline(float(np.min(s["ankle_pitch_limit_nm"])), color="k", ls="--", lw=1)
        axes[1].axhline(float(s["grf_limit_n"]), color="k", ls="--", lw=1)
    _label(axes, ("time [s]", "time [s]"),
           ("|ankle pitch torque|, larger foot [N·m]", "vertical GRF, larger foot [N]"))
    return fig


def demonstrations_label(dataset: str | None) -> str:
    """How a campaign row's demonstration set is shown: its file name (None: the robot's default)."""
    return Path(dataset).name if dataset else "default set"


def _transitions_section(transitions: list[dict], png: str) -> str:
    """Fig. 3.38: a row per primitives (how far the two postures are apart) and their side views."""
    rows = "".join(f"<tr><td>{html.escape(demonstrations_label(t['dataset']))}</td>"
                   f"<td>{html.escape(t['sources'])}</td><td>{t['short_cycles_m'][0] * 100:.1f} / "
                   f"{t['short_cycles_m'][1] * 100:.1f}</td><td>{t['transition_max_joint_difference_rad']:.3f}</td>"
                   f"<td>{t['transition_left_hand_distance_m'] * 1e3:.1f}</td></tr>" for t in transitions)
    title = "Posture at the switch to standing after a shorter and a longer last step (thesis Fig. 3.38)"
    return (f"<h2>{html.escape(title)}</h2><p>The synthesis alone (kinematic), two goals ending at the same comfort "
            "distance: the learned standing posture depends on the step before it.</p><table><tr><th>demonstrations"
            "</th><th>sources</th><th>short cycles [cm]</th><th>upper body apart [rad]</th><th>left hand apart [mm]"
            f'</th></tr>{rows}</table><img alt="{html.escape(title)}" src="data:image/png;base64,{png}">')


def _summary(campaign: dict) -> Summary:
    """The campaign's first screen: falls, successes and errors over all trials, each method's falls."""
    rows = campaign["trials"]
    falls = sum(bool(r["fell"]) for r in rows)
    successes = sum(bool(r["success"]) for r in rows)
    errors = sum(bool(r["error"]) for r in rows)
    steps = [abs(e) for r in rows if not r["error"] for e in (r.get("step_length_errors_m") or [])]
    figures = [KeyFigure("Falls", f"{falls} of {len(rows)}", "0 (thesis Table 3.1: 0 of 30 for its method)",
                         falls == 0),
               KeyFigure("Trials meeting every criterion", f"{successes} of {len(rows)}", f"{len(rows)}",
                         successes == len(rows)),
               KeyFigure("Trials that ended in an error", f"{errors}", "0", errors == 0)]
    if steps:
        figures.append(KeyFigure("Largest step-length error", f"{max(steps) * 1000:.1f} mm",
                                 "≤ 10 mm (thesis Fig. 3.41)", max(steps) <= 0.010))
    if any(r.get("cabinet") for r in rows):  # in rooms: where the walk round ended
        pelvis = [abs(r["pelvis_error_m"]) for r in rows if r.get("pelvis_error_m") is not None]
        yaw = [abs(r["pelvis_yaw_error_deg"]) for r in rows if r.get("pelvis_yaw_error_deg") is not None]
        if pelvis:
            figures.append(KeyFigure("Largest pelvis error from the comfort distance", f"{max(pelvis) * 1000:.1f} mm",
                                     f"≤ {COMFORT_TOLERANCE * 1000:.0f} mm", max(pelvis) <= COMFORT_TOLERANCE))
        if yaw:
            figures.append(KeyFigure("Largest pelvis heading error against the cabinet's", f"{max(yaw):.1f}°",
                                     f"≤ {HEADING_TOLERANCE_DEG:.0f}°", max(yaw) <= HEADING_TOLERANCE_DEG))
    methods = sorted({r["method"] for r in rows})
    ok = falls == 0 and errors == 0 and successes == len(rows)
    text = (f"{successes} of {len(rows)} trials met every criterion, {falls} fell, {errors} ended in an error "
            f"({', '.join(methods)})")
    return Summary(f"Drawer campaign — {len(rows)} trials", Verdict(ok, text), tuple(figures))


def render_campaign(campaign: dict, out_dir: Path, transition_figure=None) -> Path:
    """Write ``out_dir/campaign.html``; ``transition_figure``: a matplotlib figure of the postures
    at the switch to standing (Fig. 3.38), whose figures ``campaign["transition_postures"]`` holds."""
    import matplotlib

    matplotlib.use("Agg")
    out_dir = Path(out_dir)
    rows = campaign["trials"]
    head = "".join(f"<th>{html.escape(label)}</th>" for _, label in SUMMARY_COLUMNS)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_cell(k, s.get(k)))}</td>" for k, _ in SUMMARY_COLUMNS)
                   + "</tr>" for s in campaign["summary"])
    thesis = "".join(f"<li>{html.escape(k.replace('_', ' '))}: {html.escape(v)}</li>" for k, v in THESIS.items())
    failed = [r for r in rows if r["fell"] or not r["success"] or r["error"]]
    failures = "".join(f"<li>{html.escape(r['id'])}: {html.escape(r.get('cause') or '')}"
                       f"{' (error: ' + html.escape(r['error']) + ')' if r['error'] else ''}</li>" for r in failed)
    failures = failures or "<li>none</li>"
    figures = [("Peak ankle pitch torque and vertical GRF of every trial over their limits (thesis Fig. 3.47)",
                figure_png(_peaks_per_method(rows))),
               ("Step-length and hand errors (thesis Fig. 3.41, right)", figure_png(_histograms(rows))),
               ("Lateral ZMP error of every trial, measured − planned, RMS over single support (thesis Fig. 3.46; "
                "the naive method has no plan after its walk-in)", figure_png(_lateral_zmp(rows))),
               (f"Ankle pitch torque and vertical GRF of the trials with the largest peaks (at most {PEAK_TRIALS}), "
                "limits dashed (thesis Fig. 3.47)", figure_png(_peaks_over_time(rows, out_dir)))]
    if any(r.get("cabinet") for r in rows):
        figures.insert(0, ("Where each trial's cabinet stood, its front facing the arrow's way, in the start frame "
                           "(the robot at the origin facing +x): green met every criterion, red did not",
                           figure_png(_poses(rows))))
    images = "".join(f'<h2>{html.escape(t)}</h2><img alt="{html.escape(t)}" src="data:image/png;base64,{png}">'
                     for t, png in figures)
    if transition_figure is not None:
        images += _transitions_section(campaign.get("transition_postures", []), figure_png(transition_figure))
    summary = _summary(campaign)
    body = (first_screen(summary, campaign.get("command"))
            + f"""<h2>Falls per method, source count and speed class (thesis Table 3.1)</h2>
{_falls_table(campaign["summary"])}
<h2>Summary</h2>
<table><tr>{head}</tr>{body}</table>
<h2>The thesis's method, for comparison</h2><ul>{thesis}</ul>
<h2>Trials that fell, failed a criterion or ended in an error: {len(failed)}</h2>
<details><summary>the list</summary><ul>{failures}</ul></details>
{images}
<p>Each trial's report: <code>trials/ID/report.json</code> (<code>robot-ctrl report trials/ID</code> renders it).</p>""")
    text = page(summary.title, body)
    path = out_dir / "campaign.html"
    tmp = out_dir / ".campaign.html.partial"
    tmp.write_text(text)
    tmp.replace(path)
    return path
