"""Postures at the transition from the short cycle to standing (thesis Fig. 3.38).

Like a person's, the learned posture at the start of the last action depends on the step that led
to it: action 3's weights and means are regressed on the preceding short cycle's length
(``synthesis/primitives.py``). Two goals whose short cycles differ in length end at the same
comfort distance from the drawer; the synthesized upper body at the switch to standing differs.
Kinematic (the synthesis alone); the legs are drawn at the start posture.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from robot_ctrl.control.commanders.synthesized_body import SynthesizedBody
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.synthesis.primitives import WalkReachPrimitives
from robot_ctrl.synthesis.step_planning import Action
from robot_ctrl.synthesis.synthesizer import Synthesizer, WalkReachGoal

#: The two goals compared (distances from the synthesis's start [m]) and their object slot: short
#: cycles of about 17 and 25 cm before the same comfort distance.
TRANSITION_DISTANCES = (1.15, 1.35)
TRANSITION_SLOT = "back_right"


def transition_postures(robot: RobotModel, primitives: WalkReachPrimitives, distances: tuple[float, ...], slot: str,
                        dt: float = 0.005) -> list[dict]:
    """Per goal distance [m, from the pelvis where the synthesis starts]: the short cycle's length
    [m], the upper-body angles [rad] at the first sample of standing and at the end, and the hands'
    offsets from the pelvis [m] (pelvis frame: x forward, z up) at both."""
    body = SynthesizedBody(robot)
    out = []
    for distance in distances:
        synth = Synthesizer(primitives, WalkReachGoal(distance, slot), dt)
        transition = None
        while not synth.finished:
            output = synth.step(dt)
            if transition is None and output.action is Action.STAND:
                transition = output.upper_body_q
            if not synth.finished:
                final = output.upper_body_q
        short = [p.length for p in synth.plan if p.action is Action.SHORT][-1]
        hands = {name: body.hands_from_pelvis(q, robot.q_half_sitting, 0.0) for name, q in
                 (("transition", transition), ("final", final))}
        out.append({"distance_m": distance, "short_cycle_m": round(short, 4), "transition_q": transition,
                    "final_q": final, "hands_m": hands})
    return out


def transition_summary(postures: list[dict]) -> dict:
    """How the two postures differ: the largest joint-angle difference [rad] and the left hand's
    distance [m], at the transition and at the end of standing."""
    a, b = postures[:2]
    return {"short_cycles_m": [a["short_cycle_m"], b["short_cycle_m"]],
            **{f"{when}_max_joint_difference_rad": round(float(np.abs(a[f"{when}_q"] - b[f"{when}_q"]).max()), 4)
               for when in ("transition", "final")},
            **{f"{when}_left_hand_distance_m": round(float(np.linalg.norm(a["hands_m"][when]["left"] -
                                                                          b["hands_m"][when]["left"])), 4)
               for when in ("transition", "final")}}


def plot_transition_postures(robot: RobotModel, postures: list[dict], path: Path) -> Path:
    """:func:`draw_transition_postures` into a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 6.5))
    draw_transition_postures(robot, postures, ax)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def draw_transition_postures(robot: RobotModel, postures: list[dict], ax, title: str = "") -> None:
    """Side view (x forward, z up) of the robot's skeleton at each transition posture, overlaid
    (red, green: the thesis's colours), on the matplotlib axes ``ax``."""
    body = SynthesizedBody(robot)
    data = robot.pin.createData()
    for p, colour in zip(postures, ("tab:red", "tab:green")):
        q = body.configuration(p["transition_q"], robot.q_half_sitting)
        pin.forwardKinematics(robot.pin, data, q)
        for j in range(2, robot.pin.njoints):  # every joint to its parent: the skeleton of any robot
            a, b = data.oMi[robot.pin.parents[j]].translation, data.oMi[j].translation
            ax.plot([a[0], b[0]], [a[2], b[2]], color=colour, lw=2, alpha=0.8)
        hand = body.hands(p["transition_q"], q)["left"]
        ax.plot(hand[0], hand[2], "o", color=colour,
                label=f"short cycle {p['short_cycle_m'] * 100:.1f} cm before (goal {p['distance_m']:.2f} m)")
    ax.set_aspect("equal")
    ax.set_xlabel("x forward [m] (pelvis frame)")
    ax.set_ylabel("z up [m]")
    ax.set_title(title or "Posture at the switch to standing (Fig. 3.38)", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), fontsize=8)
