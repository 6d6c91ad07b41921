"""Kinematic run of the walk-and-reach synthesis (no physics): ``robot-ctrl synth``.

Steps the :class:`Synthesizer` at a fixed rate until the sequence ends, optionally moving the goal
at a given time (the drawer jump of thesis Fig. 3.39), and reports planned against realized
action lengths (pelvis advance per action) and the final pelvis-to-drawer distance.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from robot_ctrl.synthesis.primitives import WalkReachPrimitives
from robot_ctrl.synthesis.synthesizer import GoalJump, Synthesizer, WalkReachGoal


@dataclass
class SynthesisRun:
    time: np.ndarray  # (n,) [s]
    pelvis_velocity: np.ndarray  # (n, 3)
    upper_body_q: np.ndarray  # (n, J)
    phase: np.ndarray  # (n,)
    action: np.ndarray  # (n,)
    progress: np.ndarray  # (n,) pelvis advance [m]
    goal: np.ndarray  # (n,) drawer distance in force at each sample [m]
    report: dict


def run_synthesis(primitives: WalkReachPrimitives, goal: WalkReachGoal, dt: float = 0.005,
                  jump: GoalJump | None = None, max_time: float = 60.0) -> SynthesisRun:
    synth = Synthesizer(primitives, goal, dt)
    rows, t = [], 0.0
    while not synth.finished:
        if t > max_time:
            raise RuntimeError(f"the sequence did not end within {max_time} s")
        if jump is not None and t >= jump.time:
            goal = WalkReachGoal(jump.distance, goal.slot)
        out = synth.step(dt, goal)
        t += dt
        rows.append((t, out, synth.progress, goal.distance))
    planned = [h.planned_length for h in synth.history]
    realized = [h.end_progress - h.start_progress for h in synth.history]
    report = {
        "goal_distance_m": goal.distance, "slot": goal.slot, "dt_s": dt,
        "goal_jump": None if jump is None else {"time_s": jump.time, "distance_m": jump.distance},
        "actions": [h.action for h in synth.history],
        "planned_step_lengths_m": planned, "realized_step_lengths_m": realized,
        "step_length_errors_mm": [1000 * (r - p) for r, p in zip(realized, planned)],
        "comfort_distance_m": primitives.comfort_distance,
        "final_pelvis_to_goal_m": goal.distance - synth.progress,
        "replans": synth.replans, "duration_s": t,
        "approximation_quality": list(primitives.quality),
    }
    outs = [r[1] for r in rows]
    return SynthesisRun(np.array([r[0] for r in rows]), np.array([o.pelvis_velocity for o in outs]),
                        np.array([o.upper_body_q for o in outs]), np.array([o.phase for o in outs]),
                        np.array([o.action for o in outs]), np.array([r[2] for r in rows]),
                        np.array([r[3] for r in rows]), report)


def write_synthesis(run: SynthesisRun, out_dir: Path) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "synth.json"
    path.write_text(json.dumps(run.report, indent=2, default=float))
    return path


def plot_synthesis(run: SynthesisRun, joint_names: tuple[str, ...], path: Path) -> None:
    """Pelvis velocity, upper-body joint angles and pelvis advance, with the action boundaries."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(10, 10), sharex=True)
    for i, name in enumerate(("vx [m/s]", "vy [m/s]", "ωz [rad/s]")):
        axes[0].plot(run.time, run.pelvis_velocity[:, i], label=name)
    axes[0].set_ylabel("pelvis velocity")
    for j, name in enumerate(joint_names):
        if np.ptp(run.upper_body_q[:, j]) > 0.02:
            axes[1].plot(run.time, run.upper_body_q[:, j], label=name.removesuffix("_joint"))
    axes[1].set_ylabel("joint angle [rad]")
    axes[2].plot(run.time, run.progress, label="pelvis advance")
    axes[2].plot(run.time, run.goal - run.report["comfort_distance_m"], "--", label="drawer − comfort distance")
    axes[2].set_ylabel("[m]")
    axes[2].set_xlabel("time [s]")
    wraps = np.diff(run.phase, prepend=np.inf) < -np.pi  # each action is one period of the leader
    starts = np.flatnonzero((wraps | (np.arange(len(run.time)) == 0)) & (run.action > 0))
    for ax in axes:
        for k in starts:
            ax.axvline(run.time[k], color="grey", lw=0.8, ls=":")
        ax.legend(fontsize=7, ncol=4, loc="upper left")
    for k in starts:
        axes[0].annotate(f"action {run.action[k]}", (run.time[k], 1.0), xycoords=("data", "axes fraction"),
                         fontsize=8, va="bottom")
    fig.suptitle(f"walk-and-reach synthesis, drawer at {run.report['goal_distance_m']:.2f} m")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
