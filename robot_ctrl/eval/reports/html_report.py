"""``robot-ctrl report DIR``: render ``DIR/report.json`` (and ``DIR/timeseries.npz`` when the run
wrote one) into a self-contained ``DIR/report.html`` in the shared look (``page.py``).

The first screen answers "did it work, and how well": the task and its parameters, the verdict,
the key figures against their goals (``run_summary.py``), the command that reproduces the run and a
picture (the top view of the CoM and footprints; a frame of the run's video when it recorded one;
a group walk's phase figure). Below it the figures: the tick log's (``log_figures``) for
``robot-ctrl log``; ZMP reference vs measured (x and y, world frame, against time, single-support
phases shaded); peak |torque| per joint against its limit; vertical ground reaction force per foot
against time with the limit line; for the drawer task, ``drawer_figures``. Then every other field of
report.json by a human name, its unit and its key, nested values as small tables.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path

import numpy as np

from robot_ctrl.eval.reports.drawer_figures import drawer_figures
from robot_ctrl.eval.reports.figures import figure_png, shade_spans
from robot_ctrl.eval.reports.log_figures import log_figures
from robot_ctrl.eval.reports.page import figure_section, first_screen, page
from robot_ctrl.eval.reports.run_summary import quantity, summarize, unit_of

#: Human names of the report.json keys whose own name would not say what they are.
NAMES = {
    "hand_to_object_synth_only_m": "Right hand to the object, by the synthesized arm angles alone",
    "synthesis_step_length_errors_m": "Step-length errors of the synthesis against its own plan",
    "actions": "Synthesized actions (1 normal cycle, 2 short cycle, 3 standing)",
    "rtf": "Real-time factor (simulated s per wall-clock s)",
    "replans": "Synthesis replans",
    "dynfilter": "Dynamic filter",
    "sources": "Primitive sources (periodic + extra)",
    "base_ground_truth": "Reports from the simulator's base (ground truth)",
    "grf_over_limit": "Vertical ground force over its limit",
    "demanded_peak_torque_ratio": "Demanded torque / limit at the measured state",
}
ACRONYMS = {"zmp": "ZMP", "com": "CoM", "grf": "GRF", "wpg": "WPG", "dcm": "DCM", "ik": "IK"}
VIDEO_FRAME_AT = 0.95  # share of the video's length where the report's frame is taken


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
    series_path = run_dir / "timeseries.npz"
    series = dict(np.load(series_path)) if series_path.is_file() else None
    walked = series is not None and "zmp" in series
    summary = summarize(report)
    pictures = []
    if walked:
        pictures.append(("Top view: CoM and footprints, planned and realized (start frame)",
                         _top_view(series, report)))
    frame = _video_frame(run_dir, report.get("video"))
    if frame is not None:
        pictures.append((f"The video ({Path(report['video']).name}) near its end", frame))
    if (run_dir / "phases.png").is_file():
        pictures.append(("Gait phase differences", base64.b64encode((run_dir / "phases.png").read_bytes()).decode()))
    figures = []
    if walked:
        figures.append(("ZMP: reference vs measured", _zmp_figure(series)))
    if "peak_torque_nm" in report and "torque_limit_nm" in report:
        figures.append(("Peak joint torques against their limits", _torque_figure(report)))
    if walked:
        figures.append(("Vertical ground reaction forces", _grf_figure(series)))
        figures.extend(drawer_figures(series, report))
    if series is not None:
        figures.extend(log_figures(series))
    shown = {f.key for f in summary.figures} | {"command", "video", "peak_torque_nm", "torque_limit_nm"}
    details = "".join(f"<tr><td>{_name(k)} <span class=\"key\">{html.escape(k)}</span></td><td>{_value(k, v)}"
                      "</td></tr>" for k, v in report.items() if k not in shown and v not in (None, [], {}))
    body = (first_screen(summary, report.get("command"), pictures)
            + "".join(figure_section(title, png) for title, png in figures)
            + f'<h2>Every other field</h2><p>The raw report: <a href="report.json">report.json</a>.</p>'
            + f'<div style="overflow-x:auto"><table>{details}</table></div>')
    out = run_dir / "report.html"
    out.write_text(page(summary.title, body))
    return out


def _name(key: str) -> str:
    if key in NAMES:
        return html.escape(NAMES[key])
    bare, _ = unit_of(key)
    words = " ".join(ACRONYMS.get(w, w) for w in bare.split("_"))
    return html.escape(words[:1].upper() + words[1:])


def _value(key: str, value) -> str:
    """A report value as HTML: numbers with the unit their key names, nested values as small
    tables, long ones folded."""
    _, unit = unit_of(key)
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        return html.escape(quantity(value, unit) if isinstance(value, float) or unit else str(value))
    if isinstance(value, str):
        return html.escape(value)
    if value in ({}, []):
        return "none"
    if isinstance(value, dict):
        items = [(k, v) for k, v in value.items() if v is not None]
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for _, v in items) and len(items) > 8:
            items.sort(key=lambda kv: -abs(kv[1]))  # per joint: largest first
        rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{_value(k if unit == '' else key, v)}"
                       f"</td></tr>" for k, v in items)
        table = f"<table>{rows}</table>"
        return table if len(items) <= 8 else f"<details><summary>{len(items)} entries</summary>{table}</details>"
    if isinstance(value, list):
        if all(isinstance(v, dict) for v in value):
            columns = list(dict.fromkeys(c for v in value for c in v))
            if len(columns) > 8:  # a report per item (a group's robots): one folded table each
                return "".join(f"<details><summary>{k}</summary>{_value(key, v)}</details>"
                               for k, v in enumerate(value))
            head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
            rows = "".join("<tr>" + "".join(f"<td>{_value(c, v.get(c)) if v.get(c) is not None else ''}"
                                            f"</td>" for c in columns) + "</tr>" for v in value)
            table = f"<table><tr>{head}</tr>{rows}</table>"
            return table if len(value) <= 6 else f"<details><summary>{len(value)} rows</summary>{table}</details>"
        cells = "".join(f"<td class=\"num\">{_value(key, v)}</td>" for v in value)
        table = f"<table><tr>{cells}</tr></table>"
        return table if len(value) <= 12 else f"<details><summary>{len(value)} values</summary>{table}</details>"
    return html.escape(json.dumps(value))


def _video_frame(run_dir: Path, video: str | None) -> str | None:
    """A frame of the run's video near its end, as PNG data (None: no video, or it cannot be read)."""
    if not video:
        return None
    path = Path(video) if Path(video).is_file() else run_dir / Path(video).name
    if not path.is_file():
        return None
    import io

    import imageio_ffmpeg
    import matplotlib.pyplot as plt

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    wanted = int(VIDEO_FRAME_AT * meta["duration"] * meta["fps"])
    frame = None
    for k, frame in enumerate(reader):  # decoded one at a time: a whole video would not fit in memory
        if k >= wanted:
            break
    reader.close()
    if frame is None:
        return None
    width, height = meta["size"]
    buffer = io.BytesIO()
    plt.imsave(buffer, np.frombuffer(frame, np.uint8).reshape(height, width, 3), format="png")
    return base64.b64encode(buffer.getvalue()).decode()


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
    room, cabinet, approach = report.get("room"), report.get("cabinet"), report.get("approach")
    outline = np.array(room["corners_m"]) if room else com
    span = np.ptp(np.vstack([com, outline]), axis=0) + 0.4
    fig, ax = plt.subplots(figsize=(10, float(np.clip(10 * span[1] / span[0] + 1.6, 3.4, 8.0))))
    length, width = s["foot_size"]
    for step in report.get("footsteps", []):
        for key, style in (("planned", dict(fill=False, ec="C0", lw=1.2)), ("realized", dict(fill=False, ec="C3", lw=0.8, ls="--"))):
            x, y, yaw = step[key]
            corner = np.array([x, y]) + _rot(yaw) @ [-length / 2, -width / 2]
            ax.add_patch(patches.Rectangle(corner, length, width, angle=np.degrees(yaw), **style))
    if room:  # the drawer in a room: the walls' inside, the cabinet (where it stood before a goal jump), the path
        ax.add_patch(patches.Polygon(outline, fill=False, ec="0.3", lw=2.5, label="walls"))
        moves = report.get("cabinet_moves") or []
        for k, pose in enumerate([cabinet] + moves):
            last = k == len(moves)
            ax.add_patch(patches.Polygon(np.array(pose["footprint_m"]), fc="burlywood" if last else "none",
                                         ec="saddlebrown", ls="-" if last else "--",
                                         label="cabinet" if last else "cabinet before its jump"))
    if approach:
        ax.plot(*np.array(approach["planned_path_m"]).T, "k:", marker="o", ms=3, lw=1.2, label="path planned")
        for again in approach.get("replanned") or []:
            ax.plot(*np.array(again["planned_path_m"]).T, "m:", marker="o", ms=3, lw=1.2,
                    label=f"path planned again at {again['time_s']:g} s")
        ax.plot(*np.array(approach["realized_path_m"]).T, "C2", lw=1.0, label="pelvis walked")
    ax.plot(*com.T, "C0", label="CoM planned")
    ax.plot(*local(s["com"]).T, "C3", lw=0.8, label="CoM measured")
    ax.plot([], [], "C0", lw=1.2, label="footprints planned")
    ax.plot([], [], "C3--", lw=0.8, label="footprints realized")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if room:  # a tall room: the legend beside it
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    else:
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
