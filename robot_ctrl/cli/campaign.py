"""``robot-ctrl campaign``: many drawer trials, locally or on a Ray cluster, resumable."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from robot_ctrl.cli.options import (
    backend_args,
    backend_of,
    check_out_folder,
    check_ranges,
    command_line,
    dataset_arg,
    log_line,
    parse_sources,
    sources_arg,
)
from robot_ctrl.cli.robot_runs import check_drawer_tasks
from robot_ctrl.modes import FilterMode
from robot_ctrl.robot.config import ConfigError


def _campaign(args: argparse.Namespace) -> int:
    from robot_ctrl.eval.campaigns import drawer_campaign as campaign
    from robot_ctrl.robot.model import load_robot

    check_ranges("campaign", args)
    if args.poses == "random" and args.n is None:
        raise ConfigError("campaign: --poses random draws --n trials (a --trials file gives each pose itself)")
    robot = load_robot(args.robot)
    try:
        methods = campaign.parse_methods(args.method)
        speeds = campaign.parse_speeds(args.speeds)
        dynfilter = FilterMode.parse(args.dynfilter or robot.config.drawer_dynfilter)
        if args.trials is not None:
            trials = campaign.read_trials(args.trials, methods, dynfilter)
        elif args.poses == "random":
            trials = campaign.draw_poses(args.n, args.seed, speeds, methods, dynfilter, _reachable(robot, args.dataset))
        else:
            trials = campaign.draw_trials(args.n, args.seed, speeds, methods, dynfilter)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"campaign: {exc}".replace("speed ", "--speeds ").replace("method ", "--method ")) from exc
    sources = parse_sources(args.sources, "campaign: --sources")
    dataset = str(args.dataset.resolve()) if args.dataset is not None else None
    trials = [replace(t, index=k, sources=f"{first}+{extra}", robot=robot.name,
                      dataset=campaign.method_dataset(t.method, dataset, robot.name))
              for k, (t, (first, extra)) in enumerate((t, s) for t in trials for s in sources)]
    for demos, naive in sorted({(t.dataset, t.method == "naive") for t in trials}, key=str):  # each set, checked once
        tasks = {f"campaign: trial {t.id}": _task(t) for t in trials
                 if (t.dataset, t.method == "naive") == (demos, naive)}
        check_drawer_tasks(tasks, robot, dataset=None if demos is None else Path(demos), whole_body=naive)
    check_out_folder(args)
    backend = backend_of(args, "campaign")
    args.out.mkdir(parents=True, exist_ok=True)
    result = campaign.run_drawer_campaign(trials, args.out, backend, robot, timeout=args.timeout,
                                          progress=not args.quiet, log=log_line, command=command_line(args))
    if result is None:
        raise KeyboardInterrupt("the campaign stopped; run the same command again to finish it")
    for s in result["summary"]:
        log_line(f"{s['method']} {s['sources']} {s['speed']:>7}: trials {s['trials']}, falls {s['falls']}, "
                 f"successes {s['successes']}, errors {s['errors']}; step error median "
                 f"{_mm(s['step_length_error_median_m'])}, max {_mm(s['step_length_error_max_m'])}; hand error max "
                 f"{_mm(s['hand_error_max_m'])}")
    bad = sum(s["falls"] + s["errors"] for s in result["summary"])
    return 1 if bad else 0


def _task(trial):
    """The drawer task a campaign's trial runs (checked as the drawer command checks it)."""
    import math

    from robot_ctrl.geometry.room import CabinetPose, Room
    from robot_ctrl.scenarios.drawer_task import DrawerTask
    from robot_ctrl.synthesis.synthesizer import GoalJump

    jumps = (GoalJump(*trial.jump),) if trial.jump else ()
    task = DrawerTask(trial.distance, trial.slot, jumps, trial.dynfilter, speed=trial.speed)
    if trial.cabinet is None:
        return task
    x, y, yaw = trial.cabinet
    return replace(task, cabinet=CabinetPose(x, y, math.radians(yaw)),
                   room=Room(*trial.room, against_wall=not trial.free_standing))


def _reachable(robot, dataset: Path | None):
    """Whether a drawn trial's cabinet can be walked to in its room (``DrawerTask.approach``, at the
    comfort distance of the demonstrations in ``dataset``, None: the robot's)."""
    from robot_ctrl.synthesis.learned import load_demonstrations

    comfort = load_demonstrations(robot, dataset).comfort_distance

    def reachable(trial) -> bool:
        try:
            _task(trial).approach(comfort, robot.config.drawer)
        except ValueError:
            return False
        return True

    return reachable


def _mm(value: float | None) -> str:
    return "–" if value is None else f"{value * 1e3:.1f} mm"


def add_parsers(sub, robot) -> None:
    p = sub.add_parser("campaign", parents=[robot],
                       help="many drawer trials in parallel, locally or on a Ray cluster (resumable)",
                       description="Runs drawer trials (from --trials FILE, or --n drawn at random with --seed at new "
                                   "distances or, with --poses random, anywhere in random rooms), each in its own "
                                   "processes, --jobs at a time, and writes "
                                   "DIR/campaign.json (a row per trial, a summary per method and speed class), "
                                   "DIR/campaign.html and each trial's report under DIR/trials/. Rerunning the same "
                                   "command finishes the trials a kill left undone. Exit status 1 if a trial fell or "
                                   "ended in an error, 130 when interrupted.")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--trials", type=Path, metavar="FILE",
                       help="one trial a line: 'distance slot speed [jump_time jump_distance]', or in a room "
                            "'X,Y,YAW_DEG [slot] [speed] [room=W,D] [free-standing]'; # comments")
    which.add_argument("--n", type=int, help="trials drawn at random per method, 1..10000")
    p.add_argument("--seed", type=int, default=0, help="seed of the random draw (with --n)")
    p.add_argument("--poses", choices=("straight", "random"), default="straight",
                   help="with --n: the cabinet straight ahead at a random distance (straight), or anywhere in a "
                        "random room (random: sides 5-8 m, its back against a wall or free-standing, its front "
                        "1.2-6 m from the start in any direction, facing any way, drawn again until reachable)")
    p.add_argument("--speeds", default="slow,middle,fast",
                   help="speed classes of the drawn trials, in turn (slow 0.8, middle 0.92, nominal 1.0, fast 1.2)")
    p.add_argument("--method", default="ours",
                   help="comma-separated methods: ours, ours-no-feedback (the commander's position loops off), naive "
                        "(every joint learned and played on the servos, thesis 3.8.4), wpg-direct (the generator of "
                        "the feasible training runs: the pipeline on the kinematic set's primitives)")
    p.add_argument("--dynfilter", choices=[m.value for m in FilterMode], default=None,
                   help="dynamic filter of every trial (default: full, or the robot config's drawer.dynfilter)")
    dataset_arg(p)
    sources_arg(p, many=True)
    p.add_argument("--jobs", type=int, default=2, help="trials at a time, 1..256")
    backend_args(p)
    p.add_argument("--timeout", type=float, default=600.0, help="wall-clock limit of one trial [s], 10..86400")
    p.add_argument("--out", type=Path, default=Path("runs/campaign"), help="output folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_campaign)
