"""Figures of a tick log for ``robot-ctrl report`` (``robot-ctrl log`` writes the series): the
joints tracked worst, command against measurement; the torque of every joint relative to its limit
over time, damping shaded; and, on real hardware, the loop's lateness behind its deadlines."""

from __future__ import annotations

import numpy as np

from robot_ctrl.eval.reports.figures import figure_png, shade_spans

WORST_JOINTS = 4


def log_figures(series: dict) -> list[tuple[str, str]]:
    """(title, PNG as base64) of each figure; empty for a run that is not a log."""
    if "log_t" not in series:
        return []
    figures = [("Command and measurement of the joints tracked worst", _tracking(series)),
               ("Joint torques relative to their limits (damping shaded)", _torques(series))]
    if np.isfinite(series["log_lateness"]).any():
        figures.append(("Loop lateness behind its deadlines", _lateness(series)))
    return figures


def _tracking(s) -> str:
    import matplotlib.pyplot as plt

    t, q, cmd = s["log_t"], s["log_q"], s["log_cmd_q"]
    with np.errstate(invalid="ignore"):
        worst = np.argsort(np.nanmax(np.abs(cmd - q), axis=0))[::-1][:WORST_JOINTS]
    fig, axes = plt.subplots(len(worst), 1, figsize=(9, 1.8 * len(worst) + 0.6), sharex=True, squeeze=False)
    for ax, j in zip(axes[:, 0], worst):
        ax.plot(t, cmd[:, j], lw=0.9, label="command")
        ax.plot(t, q[:, j], lw=0.9, label="measured")
        ax.set_ylabel(f"{s['log_joint_names'][j]}\n[rad]", fontsize=8)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("t [s]")
    return figure_png(fig)


def _torques(s) -> str:
    import matplotlib.pyplot as plt

    from robot_ctrl.eval.recording.tick_log import MODES
    from robot_ctrl.hw.safety import SafetyMode

    t, ratio = s["log_t"], np.abs(s["log_tau"]) / s["log_effort"]
    fig, ax = plt.subplots(figsize=(9, 3.2))
    shade_spans(ax, t, s["log_mode"] == MODES.index(SafetyMode.DAMPING), color="C3", alpha=0.15)
    ax.plot(t, ratio.max(axis=1), lw=0.9, label="largest over the joints")
    ax.plot(t, np.median(ratio, axis=1), lw=0.9, label="median")
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_ylabel("|τ| / limit")
    ax.set_xlabel("t [s]")
    ax.legend(fontsize=8)
    return figure_png(fig)


def _lateness(s) -> str:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 2.8))
    ax.plot(s["log_t"], s["log_lateness"] * 1e3, lw=0.8)
    ax.set_ylabel("lateness [ms]")
    ax.set_xlabel("t [s]")
    return figure_png(fig)
