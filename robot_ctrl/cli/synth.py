"""``robot-ctrl synth | synth-quality | synth-demos``: the walk-and-reach synthesis, kinematic."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_ctrl.cli.options import (
    backend_args,
    backend_of,
    check_ranges,
    dataset_arg,
    log_line,
    parse_sources,
    sources_arg,
    time_distance,
)
from robot_ctrl.robot.config import ConfigError


def _synth_primitives(args: argparse.Namespace, sources: tuple[int, int] | None = None):
    """The robot and its primitives learned from ``--dataset`` with ``sources`` (default: the default
    count); a missing or unusable dataset is one line."""
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.synthesis.learned import DEFAULT_SOURCES, load_primitives

    robot = load_robot(args.robot)
    robot.config.require_reach(args.command)
    try:
        return robot, load_primitives(robot, args.dataset, sources or DEFAULT_SOURCES)
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
    from robot_ctrl.synthesis.learned import load_demonstrations

    splits = parse_sources(args.sources, "synth-quality: --sources")
    learned = [_synth_primitives(args, split) for split in splits]  # each learned once, then cached
    demos = load_demonstrations(learned[0][0], args.dataset)
    print(f"{demos.provenance.get('source', 'unknown')} demonstrations: {len(demos.trials)} trials")
    print("sources  action  sources (s0 + periodic)  Q anechoic  Q PCA (same count)  PCA components for the same Q")
    for (first, extra), (_, primitives) in zip(splits, learned):
        for row in primitives.quality:
            print(f"{f'{first}+{extra}':>7}  {row['action']:>6}  {row['sources']:>23}  {row['Q_anechoic']:>10.4f}  "
                  f"{row['Q_pca']:>18.4f}  {row['pca_needed']:>29}")
    return 0


def _synth_transition(args: argparse.Namespace) -> int:
    from robot_ctrl.eval.reports.transition_postures import (
        plot_transition_postures,
        transition_postures,
        transition_summary,
    )
    from robot_ctrl.synthesis.step_planning import MAX_GOAL_DISTANCE

    try:
        distances = tuple(float(v) for v in args.distances.split(","))
    except ValueError:
        distances = ()
    if len(distances) != 2 or not all(0 < d <= MAX_GOAL_DISTANCE for d in distances):
        raise ConfigError(f"synth-transition: --distances {args.distances!r} must be two distances in "
                          f"(0, {MAX_GOAL_DISTANCE}] m, e.g. 1.15,1.35")
    robot, primitives = _synth_primitives(args)
    if args.slot not in primitives.slots:
        raise ConfigError(f"synth-transition: --slot {args.slot!r} is not one of {', '.join(primitives.slots)}")
    try:
        postures = transition_postures(robot, primitives, distances, args.slot)
    except ValueError as exc:
        raise ConfigError(f"synth-transition: --distances: {exc}") from exc
    s = transition_summary(postures)
    print(f"short cycles {s['short_cycles_m'][0]:.3f} and {s['short_cycles_m'][1]:.3f} m before standing: at the "
          f"transition the upper body differs by up to {s['transition_max_joint_difference_rad']:.3f} rad, the left "
          f"hand by {s['transition_left_hand_distance_m'] * 1e3:.1f} mm; at the end by "
          f"{s['final_max_joint_difference_rad']:.3f} rad and {s['final_left_hand_distance_m'] * 1e3:.1f} mm")
    if args.plot is not None:
        print(f"wrote {plot_transition_postures(robot, postures, args.plot)}")
    return 0


def _synth_demos(args: argparse.Namespace) -> int:
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.synthesis.demonstrations import (
        feasible_dataset_path,
        generate_demonstrations,
        kinematic_dataset_path,
    )

    robot = load_robot(args.robot)
    robot.config.require_reach("synth-demos")
    if args.from_physics:
        from robot_ctrl.eval.campaigns.feasible_demonstrations import record_feasible_set

        check_ranges("synth-demos", args)
        source = args.source or kinematic_dataset_path(robot.name)
        if not source.is_file():
            raise ConfigError(f"synth-demos: --source {source} does not exist")
        path = args.out or feasible_dataset_path(robot.name)
        try:
            demos = record_feasible_set(robot, source, args.runs, backend_of(args, "synth-demos"), path,
                                        progress=not args.quiet, log=log_line)
        except ValueError as exc:
            raise ConfigError(f"synth-demos: {exc}") from exc
        if demos is None:
            raise KeyboardInterrupt("the runs stopped; run the same command again to finish them")
    else:
        path = args.out or kinematic_dataset_path(robot.name)
        demos = generate_demonstrations(robot)
        path.parent.mkdir(parents=True, exist_ok=True)
        demos.save(path)
    print(f"wrote {len(demos.trials)} demonstrations ({len(demos.channels)} channels, dt {demos.dt} s, "
          f"{demos.provenance['source']}) to {path}")
    return 0


def add_parsers(sub, robot) -> None:
    data = argparse.ArgumentParser(add_help=False, parents=[robot])
    dataset_arg(data)
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
                       description="Learns the stepwise anechoic model (s0 + FIRST periodic sources for action 1, "
                                   "EXTRA more for actions 2 and 3) and prints Q = 1 - |X - X^|^2/|X|^2 per action next "
                                   "to PCA with the same number of sources.")
    sources_arg(p, many=True)
    p.set_defaults(run=_synth_quality)
    p = sub.add_parser("synth-transition", parents=[data], help="posture at the switch to standing vs the step before",
                       description="Synthesizes two goals whose short cycles differ in length (the same comfort "
                                   "distance at the end) and compares the upper body at the switch to standing and at "
                                   "the end (thesis Fig. 3.38; kinematic).")
    p.add_argument("--distances", default="1.15,1.35", help="two goal distances from the synthesis's start [m]")
    p.add_argument("--slot", default="back_right", help="object slot")
    p.add_argument("--plot", type=Path, default=None, help="PNG of both postures, side view")
    p.set_defaults(run=_synth_transition)
    p = sub.add_parser("synth-demos", parents=[robot], help="make a walk-and-reach demonstration set (IK, or physics)",
                       description="Without --from-physics: generates the kinematic set (IK, no dynamics) into "
                                   "models/<robot>_walk_reach_demos.npz. With --from-physics: plays 30 walk-and-reach "
                                   "sequences (10 cabinets x the speed scalings 0.8, 0.92, 1.2) through the whole "
                                   "pipeline in MuJoCo as a campaign (resumable, --jobs at a time) and records the "
                                   "realized motion, cut at the measured touch-downs, into "
                                   "models/<robot>_walk_reach_feasible.npz (thesis 3.8.3, docs/synthesis.md).")
    p.add_argument("--from-physics", action="store_true", help="record the set from physics runs")
    p.add_argument("--source", type=Path, default=None,
                   help="with --from-physics: the set the runs' primitives are learned from (default: the kinematic set)")
    p.add_argument("--runs", type=Path, default=Path("runs/feasible-demos"),
                   help="with --from-physics: folder of the runs (rerun to finish an interrupted set)")
    p.add_argument("--jobs", type=int, default=2, help="with --from-physics: runs at a time, 1..256")
    backend_args(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--out", type=Path, default=None,
                   help="output .npz (default: models/<robot>_walk_reach_demos.npz, with --from-physics "
                        "models/<robot>_walk_reach_feasible.npz)")
    p.set_defaults(run=_synth_demos)
