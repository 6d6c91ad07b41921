"""``robustness.html``: the robustness campaign as a self-contained page: the largest survived push
per direction (polar, one curve per gait phase, start frame: 0° forward, 90° left) beside the
largest the linear inverted pendulum could capture from the state each push met (dashed), the grid
as a table, and a pass/fail table per model mismatch."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from robot_ctrl.eval.reports.figures import figure_png
from robot_ctrl.eval.reports.page import KeyFigure, Summary, Verdict, first_screen, page
from robot_ctrl.eval.reports.run_summary import GOAL_TOLERANCE


def render_robustness(result: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cells = result["largest_survived_push"]
    phases = list(dict.fromkeys(c["phase"] for c in cells))
    directions = sorted({c["direction_deg"] for c in cells})
    fig = plt.figure(figsize=(6.5, 6.5))
    ax = fig.add_subplot(projection="polar")
    angles = np.radians(directions + directions[:1])
    for phase in phases:
        values = {c["direction_deg"]: c["impulse_ns_per_kg"] for c in cells if c["phase"] == phase}
        line, = ax.plot(angles, [values[d] for d in directions + directions[:1]], marker="o",
                        label=phase.replace("_", " "))
        bound = {c["direction_deg"]: c.get("lip_capturable_ns_per_kg") for c in cells if c["phase"] == phase}
        if None not in bound.values():
            ax.plot(angles, [min(bound[d], max(result["magnitudes_ns_per_kg"])) for d in directions + directions[:1]],
                    linestyle="--", linewidth=1, color=line.get_color())
    ax.set_rmax(max(result["magnitudes_ns_per_kg"]))
    ax.set_rticks(result["magnitudes_ns_per_kg"])
    ax.set_title("largest survived push [N·s/kg] by direction (0° forward, 90° left);\n"
                 "dashed: largest the LIP could capture (clipped at the largest tested)", fontsize=10)
    ax.legend(fontsize=8, loc="lower left", bbox_to_anchor=(-0.1, -0.12))
    figure = figure_png(fig)
    rows = "".join(_mismatch_row(m) for m in result["mismatch"])
    cell = {(c["direction_deg"], c["phase"]): c for c in cells}
    grid = "".join(f"<tr><th>{d}°</th>" + "".join(_grid_cell(cell[d, p]) for p in phases) + "</tr>" for d in directions)
    weakest = min(cells, key=lambda c: c["impulse_ns_per_kg"])
    walked = sum(bool(m["walked"]) for m in result["mismatch"])
    summary = Summary(
        f"Robustness — {result['walk']}",
        Verdict(walked == len(result["mismatch"]) if result["mismatch"] else None,
                f"Every push direction and gait phase survived at least {weakest['impulse_ns_per_kg']:g} N·s/kg; "
                f"{walked} of {len(result['mismatch'])} model mismatches walked"),
        (KeyFigure("Smallest largest-survived push", f"{weakest['impulse_ns_per_kg']:g} N·s/kg at "
                   f"{weakest['direction_deg']}°, {weakest['phase'].replace('_', ' ')}"),
         KeyFigure("Largest push tested", f"{max(result['magnitudes_ns_per_kg']):g} N·s/kg"),
         KeyFigure("Model mismatches walked", f"{walked} of {len(result['mismatch'])}", "all",
                   walked == len(result["mismatch"]))))
    body = (first_screen(summary, result.get("command"), [("largest survived push by direction", figure)])
            + f"""<p>Pushes of {result['push_duration_s']} s on the base, growing until the robot falls; 0: not even the smallest; {max(result['magnitudes_ns_per_kg']):g}: the largest tested, and it did not fall.
A walk that survived its push but ended more than {GOAL_TOLERANCE * 100:g} cm from its goal says so.
In brackets, the largest push the linear inverted pendulum could capture by stepping within the controller's reach, from the state the push met (measured): first with a swing foot that may land as early as 0.3 s after lift-off, a push above it cannot be caught without a hip strategy or a crossing step; then with the walk's own step timing, a push above that needs the step timing to change (docs/robustness.md).</p>
<table><tr><th>direction</th>{''.join(f'<th>{html.escape(p)}</th>' for p in phases)}</tr>{grid}</table>
<h2>Model mismatch</h2><table><tr><th>run</th><th>result</th><th>final error</th><th>error</th></tr>{rows}</table>""")
    page_text = page(summary.title, body)
    path = Path(path)
    path.write_text(page_text)
    return path


def _grid_cell(c: dict) -> str:
    bound, own = c.get("lip_capturable_ns_per_kg"), c.get("lip_capturable_own_timing_ns_per_kg")
    error = c.get("final_position_error_m")
    off = "" if error is None or error <= GOAL_TOLERANCE else f", ended {error * 1000:.0f} mm from the goal"
    bounds = "" if bound is None else f" ({bound:.2f}" + ("" if own is None else f" | {own:.2f}") + ")"
    return f"<td>{c['impulse_ns_per_kg']:g}" + bounds + off + "</td>"


def _mismatch_row(m: dict) -> str:
    error = "" if m["final_position_error_m"] is None else f"{m['final_position_error_m'] * 1000:.1f} mm"
    return (f"<tr><td>{html.escape(m['name'])}</td><td>{'walked' if m['walked'] else 'FELL'}</td><td>{error}</td>"
            f"<td>{html.escape(str(m['error'] or ''))}</td></tr>")
