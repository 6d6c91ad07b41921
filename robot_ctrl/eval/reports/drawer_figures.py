"""Figures of the drawer task for ``robot-ctrl report``: the thesis's Fig. 3.47 analog (ankle pitch
torque and vertical ground reaction force of each foot against time, with their limits, the
synthesized actions shaded) and the drawer itself (opening against the required clearance; the
contact forces: the hand's pull on the drawer, the fingers' on the handle and on the object, the
robot's other contacts with the furniture; both hands' distances to their targets)."""

from __future__ import annotations

from robot_ctrl.eval.reports.figures import figure_png
from robot_ctrl.geometry import SIDES

ACTION_NAMES = {1: "normal cycle", 2: "short cycle", 3: "standing"}


def drawer_figures(series: dict, report: dict) -> list[tuple[str, str]]:
    """(title, PNG as base64) of each figure; empty for a run that is not a drawer task."""
    if "action_starts" not in series:
        return []
    return [("Ankle pitch torque and vertical GRF per foot, actions shaded (thesis Fig. 3.47)",
             _ankle_and_grf(series)), ("The drawer, the contact forces and the hands", _drawer(series, report))]


def _shade_actions(ax, series) -> None:
    starts = series["action_starts"]
    end = float(series["drawer_t"][-1])
    for (t0, action), t1 in zip(starts, list(starts[1:, 0]) + [end]):
        if int(action) in ACTION_NAMES:
            ax.axvspan(t0, t1, color=f"C{int(action) + 3}", alpha=0.12, lw=0)
            ax.text(t0, 1.0, f" {int(action)}", transform=ax.get_xaxis_transform(), fontsize=7, va="top")


def _ankle_and_grf(series) -> str:
    import matplotlib.pyplot as plt

    t = series["drawer_t"]
    fig, axes = plt.subplots(2, 2, figsize=(10, 5.5), sharex=True)
    for col, side in enumerate(SIDES):
        limit = float(series["ankle_pitch_limit_nm"][col])
        ax = axes[0, col]
        ax.plot(t, series["ankle_pitch_torque"][:, col], lw=0.8)
        ax.axhline(limit, color="C3", ls="--", lw=0.8)
        ax.axhline(-limit, color="C3", ls="--", lw=0.8)
        ax.set_title(f"{side} foot", fontsize=9)
        ax.set_ylabel("ankle pitch τ [N·m]")
        ax = axes[1, col]
        ax.plot(t, series["drawer_grf"][:, col], lw=0.8)
        ax.axhline(float(series["grf_limit_n"]), color="C3", ls="--", lw=0.8)
        ax.set_ylabel("vertical GRF [N]")
        ax.set_xlabel("time [s]")
        for a in axes[:, col]:
            _shade_actions(a, series)
    fig.tight_layout()
    return figure_png(fig)


def _drawer(series, report) -> str:
    import matplotlib.pyplot as plt

    t = series["drawer_t"]
    fig, (top, middle, bottom) = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    top.plot(t, series["drawer_opening_m"], label="drawer opening")
    top.axhline(float(report["drawer_opening_required_m"]), color="C3", ls="--", label="required clearance")
    top.set_ylabel("[m]")
    top.legend(fontsize=8, loc="upper left")
    middle.plot(t, series["drawer_pull_force_n"], lw=0.8, label="pull on the drawer (along its opening)")
    middle.plot(t, series["grip_force_n"], lw=0.8, label="left fingers on the handle")
    middle.plot(t, series["object_grip_force_n"], lw=0.8, label="right fingers on the object")
    middle.plot(t, series["unintended_force_n"], lw=0.8, color="C3", label="other robot–furniture contact")
    middle.set_ylabel("contact force [N]")
    middle.legend(fontsize=8, loc="upper left")
    bottom.plot(t, series["left_hand_to_handle_m"], label="left hand to handle")
    bottom.plot(t, series["right_hand_to_object_m"], label="right hand to object")
    bottom.set_yscale("log")
    bottom.set_ylabel("[m]")
    bottom.set_xlabel("time [s]")
    bottom.legend(fontsize=8, loc="lower left")
    for ax in (top, middle, bottom):
        _shade_actions(ax, series)
    fig.tight_layout()
    return figure_png(fig)
