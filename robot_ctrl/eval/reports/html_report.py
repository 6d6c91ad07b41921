"""``robot-ctrl report DIR``: render ``DIR/report.json`` (and ``DIR/timeseries.npz`` when the run
wrote one) into a self-contained ``DIR/report.html``: a metrics table and matplotlib figures
embedded as PNG data, no network resources.

Figures: the tick log's (``log_figures``) for ``robot-ctrl log``; ZMP reference vs measured (x and y, world frame, against time, single-support phases
shaded); top view of the planned and measured CoM paths with the planned and realized footprints
(start frame); peak |torque| per joint against its limit; vertical ground reaction force per foot
against time with the limit line; for the drawer task, ``drawer_figures``.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from robot_ctrl.eval.reports.drawer_figures import drawer_figures
from robot_ctrl.eval.reports.figures import figure_png, shade_spans
from robot_ctrl.eval.reports.log_figures import log_figures

SUMMARY_KEYS = ("fell", "fall_time_s", "fall_reason", "time_s", "final_position_error_m", "final_yaw_error_deg",
                "hand_error_m", "zmp_in_support_ratio", "zmp_error_rms_m", "zmp_error_max_m", "zmp_lateral_std_m",
                "com_error_rms_m", "com_error_max_m", "step_length_error_m", "peak_torque_ratio", "peak_torque_joint",
                "peak_grf_n", "grf_limit_n", "grf_over_limit", "dynfilter", "arms", "base_state",
                "base_estimate_error", "rtf",
                # the drawer task
                "success", "distance_m", "slot", "goal_jumps", "actions", "planned_step_lengths_m",
                "realized_step_lengths_m", "step_length_error_max_m", "comfort_distance_m", "final_pelvis_to_drawer_m",
                "drawer_opening_m", "drawer_opening_required_m", "drawer_pull_force_peak_n", "grasp", "hand_to_handle_m",
                "hand_to_object_m", "hand_to_object_synth_only_m", "peak_ankle_pitch_torque_ratio",
                # a tick log (robot-ctrl log)
                "ticks", "tracking_error_rms_rad", "tracking_error_max_rad", "tracking_error_max_joint", "safety",
                "bus", "timing")


def render_report(run_dir: Path) -> Path:
    """Render ``run_dir/report.json`` (and ``timeseries.npz`` when the run wrote one) into a
    self-contained ``run_dir/report.html``; return its path (``robot-ctrl report DIR``)."""

    run_dir = Path(run_dir)
    path = run_dir / "report.json"
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist: run a scenario with --out {run_dir} first")
    report = json.loads(path.read_text())
    import matplotlib

    matplotlib.use("Agg")
    figures = []
    series_path = run_dir / "timeseries.npz"
    series = dict(np.load(series_path)) if series_path.is_file() else None
    walked = series is not None and "zmp" in series
    if walked:
        figures.append(("ZMP: reference vs measured", _zmp_figure(series)))
        figures.append(("Top view: CoM and footprints (start frame)", _top_view(series, report)))
    if "peak_torque_nm" in report and "torque_limit_nm" in report:
        figures.append(("Peak joint torques against their limits", _torque_figure(report)))
    if walked:
        figures.append(("Vertical ground reaction forces", _grf_figure(series)))
        figures.extend(drawer_figures(series, report))
    if series is not None:
        figures.extend(log_figures(series))
    rows = "".join(f"<tr><th>{html.escape(k)}</th><td>{_cell(report[k])}</td></tr>"
                   for k in SUMMARY_KEYS if k in report)
    body = "".join(f'<h2>{html.escape(title)}</h2><img alt="{html.escape(title)}" src="data:image/png;base64,{png}">'
                   for title, png in figures)
    title = f"robot_ctrl run: {report.get('robot', '')} {run_dir.name}"
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:2em auto;}} table{{border-collapse:collapse;}}
th,td{{border:1px solid #ccc;padding:3px 8px;text-align:left;font-size:90%;}} img{{max-width:100%;}}</style>
</head><body><h1>{html.escape(title)}</h1><table>{rows}</table>{body}</body></html>
"""
    out = run_dir / "report.html"
    out.write_text(page)
    return out


def _cell(value) -> str:
    """A summary value as HTML: a dict holding dicts or more than 8 entries (the safety layer's
    report) as a table of its own, a per-joint figure listed largest first; anything else as text."""
    nested = isinstance(value, dict) and (len(value) > 8 or any(isinstance(v, dict) for v in value.values()))
    if not nested:
        return html.escape(_fmt(value))
    if all(isinstance(v, (int, float)) for v in value.values()):
        ranked = sorted(value.items(), key=lambda item: -item[1])
        return html.escape(", ".join(f"{k} {_fmt(v)}" for k, v in ranked) + " (largest first)")
    rows = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{_cell(v)}</td></tr>" for k, v in value.items())
    return f"<table>{rows}</table>"


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list) and len(value) > 8:
        arr = np.asarray(value, dtype=float)
        return f"{len(value)} values, mean {arr.mean():+.4f}, max |·| {np.abs(arr).max():.4f}"
    return json.dumps(value) if isinstance(value, (dict, list)) else str(value)


def _zmp_figure(s) -> str:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for i, (ax, name) in enumerate(zip(axes, "xy")):
        shade_spans(ax, s["t"], s["stance"] >= 0, color="0.9")
        ax.plot(s["t"], s["zmp_ref"][:, i], label="reference (plan)")
        ax.plot(s["t"], s["zmp"][:, i], lw=0.8, label="measured (foot F/T)")
        ax.set_ylabel(f"ZMP {name} [m]")
    axes[0].legend(fontsize=8, loc="upper left")
    axes[1].set_xlabel("time [s] (grey: single support)")
    return figure_png(fig)


def _top_view(s, report) -> str:
    import matplotlib.patches as patches
    import matplotlib.pyplot as plt

    x0, y0, yaw0 = s["start_pose"]
    c, sn = np.cos(yaw0), np.sin(yaw0)

    def local(xy):
        d = xy - [x0, y0]
        return np.stack([c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1]], axis=1)

    com = local(s["com_ref"])
    span = np.ptp(com, axis=0) + 0.4
    fig, ax = plt.subplots(figsize=(10, float(np.clip(10 * span[1] / span[0] + 1.6, 3.4, 8.0))))
    length, width = s["foot_size"]
    for step in report.get("footsteps", []):
        for key, style in (("planned", dict(fill=False, ec="C0", lw=1.2)), ("realized", dict(fill=False, ec="C3", lw=0.8, ls="--"))):
            x, y, yaw = step[key]
            corner = np.array([x, y]) + _rot(yaw) @ [-length / 2, -width / 2]
            ax.add_patch(patches.Rectangle(corner, length, width, angle=np.degrees(yaw), **style))
    ax.plot(*com.T, "C0", label="CoM planned")
    ax.plot(*local(s["com"]).T, "C3", lw=0.8, label="CoM measured")
    ax.plot([], [], "C0", lw=1.2, label="footprints planned")
    ax.plot([], [], "C3--", lw=0.8, label="footprints realized")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.4), ncol=4)
    return figure_png(fig)


def _rot(yaw: float) -> np.ndarray:
    return np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])


def _torque_figure(report) -> str:
    import matplotlib.pyplot as plt

    names = list(report["peak_torque_nm"])
    peak = np.array([report["peak_torque_nm"][n] for n in names])
    limit = np.array([report["torque_limit_nm"][n] for n in names])
    fig, ax = plt.subplots(figsize=(9, 4.5))
    x = np.arange(len(names))
    ax.bar(x, limit, color="0.85", label="limit")
    ax.bar(x, peak, color=np.where(peak > limit, "C3", "C0"), label="peak |τ|")
    ax.set_xticks(x, [n.replace("_joint", "") for n in names], rotation=90, fontsize=7)
    ax.set_ylabel("torque [N·m]")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    return figure_png(fig)


def _grf_figure(s) -> str:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 3.8))
    ax.plot(s["t"], s["grf"][:, 0], label="left foot")
    ax.plot(s["t"], s["grf"][:, 1], label="right foot")
    ax.axhline(float(s["grf_limit_n"]), color="C3", ls="--", label=f"limit {float(s['grf_limit_n']):.0f} N")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("vertical GRF [N]")
    ax.legend(fontsize=8)
    return figure_png(fig)
