"""``robot-ctrl synth | synth-quality | synth-demos``: the walk-and-reach synthesis, kinematic."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_ctrl.cli.options import time_distance
from robot_ctrl.robot.config import ConfigError


def _synth_primitives(args: argparse.Namespace):
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.synthesis.learned import load_primitives

    robot = load_robot(args.robot)
    try:
        return robot, load_primitives(robot, args.dataset)
    except (FileNotFoundError, ValueError) as exc:
        raise ConfigError(f"synth: {exc}") from exc


def _synth(args: argparse.Namespace) -> int:
    from robot_ctrl.scenarios.walk_reach_synthesis import plot_synthesis, run_synthesis, write_synthesis
    from robot_ctrl.synthesis.demonstrations import upper_body_joints
    from robot_ctrl.synthesis.step_planning import MAX_GOAL_DISTANCE
    from robot_ctrl.synthesis.synthesizer import WalkReachGoal

    if not (0 < args.distance <= MAX_GOAL_DISTANCE):  # before the primitives are learned (seconds)
        raise ConfigError(f"synth: --distance {args.distance} m is outside the allowed range (0, {MAX_GOAL_DISTANCE}]")
    robot, primitives = _synth_primitives(args)
    if args.slot not in primitives.slots:
        raise ConfigError(f"synth: --slot {args.slot!r} is not one of {', '.join(primitives.slots)}")
    jump = time_distance(args.goal_jump, "synth: --goal-jump") if args.goal_jump else None
    try:
        run = run_synthesis(primitives, WalkReachGoal(args.distance, args.slot), jump=jump)
    except ValueError as exc:
        raise ConfigError(f"synth: {exc}") from exc
    r = run.report
    print(f"actions {r['actions']}  (comfort distance {r['comfort_distance_m']:.3f} m, replans {r['replans']})")
    print("planned  lengths [m] " + " ".join(f"{v:.4f}" for v in r["planned_step_lengths_m"]))
    print("realized lengths [m] " + " ".join(f"{v:.4f}" for v in r["realized_step_lengths_m"]))
    print(f"final pelvis to drawer {r['final_pelvis_to_goal_m']:.4f} m after {r['duration_s']:.2f} s")
    if args.out is not None:
        print(f"wrote {write_synthesis(run, args.out)}")
    if args.plot is not None:
        plot_synthesis(run, upper_body_joints(robot), args.plot)
        print(f"wrote {args.plot}")
    return 0


def _synth_quality(args: argparse.Namespace) -> int:
    _, primitives = _synth_primitives(args)
    print("action  sources  Q anechoic  Q PCA (same count)  PCA components for the same Q")
    for row in primitives.quality:
        print(f"{row['action']:>6}  {row['sources']:>7}  {row['Q_anechoic']:>10.4f}  {row['Q_pca']:>18.4f}  "
              f"{row['pca_needed']:>29}")
    return 0


def _synth_demos(args: argparse.Namespace) -> int:
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.synthesis.demonstrations import default_dataset_path, generate_demonstrations

    robot = load_robot(args.robot)
    path = args.out or default_dataset_path(robot.name)
    demos = generate_demonstrations(robot)
    path.parent.mkdir(parents=True, exist_ok=True)
    demos.save(path)
    print(f"wrote {len(demos.trials)} demonstrations ({len(demos.channels)} channels, dt {demos.dt} s) to {path}")
    return 0


def add_parsers(sub, robot) -> None:
    data = argparse.ArgumentParser(add_help=False, parents=[robot])
    data.add_argument("--dataset", type=Path, default=None,
                      help="demonstration set (default: models/<robot>_walk_reach_demos.npz)")
    p = sub.add_parser("synth", parents=[data], help="walk-and-reach synthesis from learned primitives (kinematic)",
                       description="Plans the actions for a drawer at --distance (end-state comfort), synthesizes "
                                   "pelvis velocity and upper-body joint angles at 200 Hz until the sequence ends, "
                                   "and prints planned vs realized action lengths (pelvis advance per gait cycle) and "
                                   "the final pelvis-to-drawer distance.")
    p.add_argument("--distance", type=float, required=True, help="drawer front panel from the start pelvis [m]")
    p.add_argument("--slot", default="front_left", help="object slot in the drawer: front_left, front_right, "
                                                          "back_left or back_right")
    p.add_argument("--goal-jump", default=None, metavar="TIME:DISTANCE",
                   help="move the drawer to DISTANCE [m] at TIME [s] (online replanning)")
    p.add_argument("--plot", type=Path, default=None, help="PNG of joint angles, pelvis velocity, action boundaries")
    p.add_argument("--out", type=Path, default=None, help="folder for synth.json")
    p.set_defaults(run=_synth)
    p = sub.add_parser("synth-quality", parents=[data], help="approximation quality of the learned model vs PCA",
                       description="Learns the stepwise anechoic model (s0 + 3 periodic sources for action 1, 2 more "
                                   "for actions 2 and 3) and prints Q = 1 - |X - X^|^2/|X|^2 per action next to PCA "
                                   "with the same number of sources.")
    p.set_defaults(run=_synth_quality)
    p = sub.add_parser("synth-demos", parents=[robot], help="generate the walk-and-reach demonstration set (IK)")
    p.add_argument("--out", type=Path, default=None, help="output .npz (default: models/<robot>_walk_reach_demos.npz)")
    p.set_defaults(run=_synth_demos)
