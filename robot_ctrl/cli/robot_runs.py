"""``robot-ctrl balance | walk | drawer | robustness``: the single-robot scenarios and their campaign."""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path

from robot_ctrl.cli.options import (
    DRAWER_OPTIONS,
    ROOM_SIDE,
    backend_args,
    backend_of,
    base_state_arg,
    check_out_folder,
    check_ranges,
    command_line,
    dataset_arg,
    log_arg,
    log_line,
    named,
    numbers,
    parse_sources,
    sources_arg,
    step_timing,
    step_timing_args,
    time_distance,
)
from robot_ctrl.cli.simulation import base_state_of, finish, on_the_robot, parse_disturbances, simulation
from robot_ctrl.modes import ArmMotion, CameraView, DrawerMethod, FilterMode, SpeedClass
from robot_ctrl.robot.config import ConfigError


def _balance(args: argparse.Namespace) -> int:
    from robot_ctrl.control.controllers.balance_controller import BalanceParams
    from robot_ctrl.scenarios.balance import run_balance

    base_state = base_state_of(args)
    robot, disturbances, hardware = simulation(args)
    with hardware as hw, on_the_robot(args, robot, hw, BalanceParams.control_dt) as (recorders, pacer):
        report = run_balance(robot, hw, out_dir=args.out, log=log_line, progress=not args.quiet,
                             disturbances=disturbances, recorders=recorders, base_state=base_state, pacer=pacer)
    return finish(args, report)


def _walk(args: argparse.Namespace) -> int:
    import math

    from robot_ctrl.control.commanders.path_follower import WalkGoal
    from robot_ctrl.control.controllers.walking_controller import WalkingOptions
    from robot_ctrl.robot.config_file import load_robot_config
    from robot_ctrl.scenarios.walk import WalkSettings, run_walk
    from robot_ctrl.wpg.params import WalkParams

    speed = load_robot_config(args.robot).walking_speed if args.speed is None else args.speed
    try:
        goal = WalkGoal(distance=args.distance, turn=math.radians(args.turn_deg), lateral=args.lateral, speed=speed)
    except ValueError as exc:
        raise ConfigError(f"walk: {exc}".replace("turn = ", "--turn-deg (in rad) = ")) from exc
    check_ranges("walk", args)
    timing = step_timing(args, "walk")
    robot, disturbances, hardware = simulation(args)
    try:
        params = WalkParams.of_robot(robot.config.walking, **timing)
    except ValueError as exc:
        raise ConfigError(f"walk: {exc}") from exc
    options = WalkingOptions(params=params,
                             stabilize=not args.no_stabilizer, recover_pushes=not args.no_push_recovery,
                             dynfilter=FilterMode(args.dynfilter), dynfilter_passes=args.dynfilter_passes,
                             dynfilter_worker=not args.dynfilter_inline)
    settings = WalkSettings(options, arms=ArmMotion(args.arms), base_state=base_state_of(args))
    with hardware as hw, on_the_robot(args, robot, hw, options.control_dt) as (recorders, pacer):
        report = run_walk(robot, hw, goal, settings, out_dir=args.out, log=log_line, progress=not args.quiet,
                          disturbances=disturbances, recorders=recorders, pacer=pacer)
    return finish(args, report)


def _drawer(args: argparse.Namespace) -> int:
    from robot_ctrl.geometry.room import handover_pose
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios.drawer import run_drawer
    from robot_ctrl.scenarios.drawer_task import DrawerTask
    from robot_ctrl.sim.drawer_cabinet import DrawerPlacement
    from robot_ctrl.synthesis.learned import load_primitives
    from robot_ctrl.synthesis.synthesizer import SynthesisError

    cabinet, room = cabinet_and_room(args)
    jumps = tuple(time_distance(j, "--goal-jump") for j in args.goal_jump if "," not in j)
    moves = tuple(cabinet_move(j) for j in args.goal_jump if "," in j)
    robot = load_robot(args.robot)
    distance = (args.distance if cabinet is None else cabinet.x if cabinet.straight_ahead
                else math.hypot(cabinet.x, cabinet.y))
    task = DrawerTask(distance, args.slot, jumps, FilterMode(args.dynfilter or robot.config.drawer_dynfilter),
                      base_state=base_state_of(args), speed=SpeedClass(args.speed),
                      position_feedback=not args.no_position_feedback,
                      method=DrawerMethod(args.method), cabinet=cabinet, room=room, moves=moves)
    parse_disturbances(args)
    sources = parse_sources(args.sources, "drawer: --sources")
    if len(sources) != 1:
        raise ConfigError(f"drawer: --sources {args.sources!r}: one FIRST+EXTRA (a campaign compares several)")
    naive = task.method is DrawerMethod.NAIVE
    check_drawer_tasks({"drawer": task}, robot, DRAWER_OPTIONS, args.dataset, whole_body=naive)
    try:
        primitives = load_primitives(robot, args.dataset, sources[0], whole_body=naive)
    except ValueError as exc:
        raise ConfigError(f"drawer: --dataset: {exc}") from exc
    approach = task.approach(primitives.comfort_distance, robot.config.drawer)
    placement = DrawerPlacement(task.distance, task.slot, tuple((j.time, j.distance) for j in jumps))
    if approach is not None:  # in a room: the cabinet stands ahead of the hand-over pose
        placement = replace(placement, distance=approach.handover_distance, frame=tuple(approach.handover),
                            walls=approach.walls,
                            moves=tuple((m.time, tuple(handover_pose(m.pose, approach.handover_distance)))
                                        for m in moves))
    robot, disturbances, hardware = simulation(args, robot, prop=placement)
    with hardware as hw, on_the_robot(args, robot, hw, task.control_dt) as (recorders, pacer):
        try:
            report = run_drawer(robot, hw, primitives, task, out_dir=args.out, log=log_line,
                                progress=not args.quiet, disturbances=disturbances, recorders=recorders, pacer=pacer)
        except SynthesisError as exc:
            raise ConfigError(f"drawer: --distance {task.distance} with these primitives (--dataset, --sources): "
                              f"{exc}") from exc
    return finish(args, report, html=not args.no_html)


def cabinet_and_room(args: argparse.Namespace):
    """``--cabinet X,Y,YAW_DEG`` and ``--room W,D`` (with ``--free-standing``) as the task's
    :class:`CabinetPose` and :class:`Room` (None, default room without ``--cabinet``)."""
    from robot_ctrl.geometry.room import CabinetPose, Room

    if args.cabinet is None:
        if args.room is not None or args.free_standing:
            raise ConfigError("drawer: --room and --free-standing need --cabinet (--distance has no room)")
        return None, Room()
    x, y, yaw = numbers(args.cabinet, "drawer: --cabinet", "X,Y,YAW_DEG", "3.0,1.5,200")
    width, depth = numbers(args.room or "6,6", "drawer: --room", "W,D", "6,6")
    lo, hi = ROOM_SIDE
    for name, v in (("width", width), ("depth", depth)):
        if not lo <= v <= hi:
            raise ConfigError(f"drawer: --room {name} = {v:g} m is outside the allowed range [{lo:g}, {hi:g}] m")
    return CabinetPose(x, y, math.radians(yaw)), Room(width, depth, against_wall=not args.free_standing)


def cabinet_move(text: str):
    """``TIME:X,Y,YAW_DEG`` (a goal jump in a room) as a :class:`~robot_ctrl.geometry.room.CabinetMove`;
    the values' own ranges are the task's to check."""
    from robot_ctrl.geometry.room import CabinetMove, CabinetPose

    time, _, pose = text.partition(":")
    try:
        values = (float(time), *(float(v) for v in pose.split(",")))
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"drawer: --goal-jump {text!r} must be TIME:X,Y,YAW_DEG in a room, four finite numbers "
                          "[s]:[m],[m],[deg], e.g. 3:2.5,1.0,200")
    t, x, y, yaw = values
    return CabinetMove(t, CabinetPose(x, y, math.radians(yaw)))


def check_drawer_tasks(tasks: dict, robot, options: dict[str, str] | None = None, dataset: Path | None = None,
                       whole_body: bool = False) -> None:
    """Refuse, with one line, a drawer task the learned primitives cannot do (``DrawerTask.check``),
    before anything is learned or started. ``tasks``: what to call each in the message → the task;
    ``options``: the command-line options that set the task's settings, named in the message;
    ``dataset``: the demonstrations the primitives are learned from (default: the robot's)."""
    from robot_ctrl.synthesis.learned import load_demonstrations

    label = next(iter(tasks), "drawer").split(":")[0]  # the command, until a task is named
    robot.config.require_reach(label)
    try:
        demos = load_demonstrations(robot, dataset, whole_body)
        if whole_body:
            try:
                demos.whole_body()  # refuses a set without the legs, before anything runs
            except ValueError as exc:
                raise ValueError(f"--dataset: {exc}") from exc
        shortest = min(t.lengths[1] for t in demos.trials)
        for label, task in tasks.items():
            task.check(demos.comfort_distance, shortest, robot.config.drawer)
    except (FileNotFoundError, ValueError) as exc:
        raise ConfigError(f"{label}: {named(str(exc), options) if options else exc}") from exc


def _robustness(args: argparse.Namespace) -> int:
    from robot_ctrl.eval.campaigns import robustness_campaign as robustness
    from robot_ctrl.wpg.params import WalkParams

    check_ranges("robustness", args)
    check_out_folder(args)
    timing = step_timing(args, "robustness")
    grid = {}
    if args.quick:  # a smoke test of the campaign: two directions, one phase, two magnitudes
        grid = dict(directions=(0, -90), phases=("single_mid",), magnitudes=(0.1, 0.2),
                    mismatch={k: robustness.MISMATCH[k] for k in ("mass ×1.15", "latency 10 ms")})
    robustness.run_robustness(args.out, backend_of(args, "robustness"), log=log_line, progress=not args.quiet,
                              single=timing.get("single_support", WalkParams.single_support),
                              double=timing.get("double_support", WalkParams.double_support),
                              command=command_line(args), **grid)
    return 0


def add_scenario_parsers(sub, sim) -> None:
    _add_balance(sub, sim)
    _add_walk(sub, sim)
    _add_drawer(sub, sim)


def _add_balance(sub, sim) -> None:
    p = sub.add_parser("balance", parents=[sim], help="stand, shift weight, lift a foot, reach with the right hand",
                       description="Balance demo at 200 Hz control: half-sitting, CoM over the left foot, right foot "
                                   "up 5 cm and back, CoM back, right-hand reach to (0.4, -0.2, 0.8) m in the start "
                                   "floor frame and back. Exit status 1 if the robot fell.")
    base_state_arg(p)
    p.add_argument("--out", type=Path, help="write DIR/report.json")
    log_arg(p)
    p.set_defaults(run=_balance)


def _add_walk(sub, sim) -> None:
    p = sub.add_parser("walk", parents=[sim], help="walk a path with the MPC walking controller",
                       description="Walk straight (--distance), along an arc (--distance with --turn-deg) or "
                                   "sideways (--lateral), stop in double support and stand 2 s. Exit status 1 if "
                                   "the robot fell.")
    p.add_argument("--distance", type=float, default=0.0, help="path length forward [m] (arc length when turning)")
    p.add_argument("--turn-deg", type=float, default=0.0, help="heading change over the path [deg], + left")
    p.add_argument("--lateral", type=float, default=0.0, help="side-step distance [m], + left, - right")
    p.add_argument("--speed", type=float,
                   help="walking speed [m/s], 0.02..0.5 (default: the robot config's walking.speed, 0.25 for Talos)")
    p.add_argument("--no-stabilizer", action="store_true", help="open loop: no DCM/ZMP balance feedback")
    p.add_argument("--no-push-recovery", action="store_true",
                   help="the plan does not take up a pushed DCM (its footsteps do not follow a push)")
    p.add_argument("--arms", choices=[m.value for m in ArmMotion], default=ArmMotion.NONE.value,
                   help="upper body: half-sitting, or both elbows swinging ±0.35 rad at 1 Hz")
    p.add_argument("--dynfilter", choices=[m.value for m in FilterMode], default=FilterMode.OFF.value,
                   help="dynamic filter: off, legs only (upper body frozen in its preview) or full body")
    p.add_argument("--dynfilter-passes", type=int, default=2, help="filter passes per WPG sample (1..10)")
    p.add_argument("--dynfilter-inline", action="store_true",
                   help="run the filter in the control loop, its correction applied in the sample it was "
                        "computed for (default: in a worker process on another core, one 0.1 s sample behind)")
    step_timing_args(p)
    base_state_arg(p)
    p.add_argument("--out", type=Path, help="write DIR/report.json and DIR/timeseries.npz")
    log_arg(p)
    p.set_defaults(run=_walk)


def _add_drawer(sub, sim) -> None:
    p = sub.add_parser("drawer", parents=[sim], help="walk to a drawer, pull it open, reach the object (headline task)",
                       description="The walk-and-reach task in MuJoCo: the learned synthesis drives the MPC walking "
                                   "controller to a chest of drawers at --distance, the left hand pulls the drawer "
                                   "open and the right hand reaches the object in --slot; report.json says whether "
                                   "every criterion was met (success). Exit status 1 if the robot fell.")
    p.add_argument("--distance", type=float, default=2.0, help="drawer front panel from the start pelvis [m]")
    p.add_argument("--slot", default="front_left", help="object slot: front_left, front_right, back_left, back_right")
    p.add_argument("--cabinet", metavar="X,Y,YAW_DEG",
                   help="the cabinet anywhere in a room instead of --distance ahead: the closed front panel's point "
                        "ahead of the standing pelvis at (X, Y) [m] in the start frame (x forward, y left) and the "
                        "direction its front faces [deg] (180: facing the robot; --distance D is --cabinet D,0,180 "
                        "without the room); the robot walks round to its front, then the synthesis takes over")
    p.add_argument("--room", metavar="W,D",
                   help="with --cabinet: the room's width along the cabinet's front and depth along the way it "
                        "faces [m] (default 6,6), its walls square to the cabinet, the cabinet's back against one")
    p.add_argument("--free-standing", action="store_true",
                   help="with --cabinet: the cabinet stands free, the room centred on the start, the cabinet and "
                        "the walk in to it")
    p.add_argument("--goal-jump", action="append", default=[], metavar="TIME:DISTANCE",
                   help="at TIME [s] the cabinet moves to DISTANCE [m]; the synthesis replans (repeatable); with "
                        "--cabinet, TIME:X,Y,YAW_DEG moves it to that pose while the robot walks its approach, "
                        "which is planned again (once)")
    p.add_argument("--dynfilter", choices=[m.value for m in FilterMode], default=None,
                   help="dynamic filter: off, legs only, or full body (default: full, or the robot config's "
                        "drawer.dynfilter)")
    p.add_argument("--speed", choices=[m.value for m in SpeedClass], default=SpeedClass.NOMINAL.value,
                   help="speed class: the synthesized sequence played at 0.8 (slow), 0.92 (middle), 1.0 (nominal) "
                        "or 1.2 (fast) times its learned timing (thesis 3.3.2, Table 3.1)")
    p.add_argument("--no-position-feedback", action="store_true",
                   help="the synthesis alone steers the walk: no feedback of the pelvis's lag, no stop at the final "
                        "footsteps, no waiting for the pelvis, no standing lean (docs/drawer.md)")
    p.add_argument("--method", choices=[m.value for m in DrawerMethod], default=DrawerMethod.OURS.value,
                   help="ours (synthesis, WPG, dynamic filter, stack of tasks) or naive: every joint learned from the "
                        "feasible demonstrations and played on the servos (thesis 3.8.4, docs/evaluation.md)")
    dataset_arg(p)
    sources_arg(p)
    base_state_arg(p)
    p.add_argument("--out", type=Path, help="write DIR/report.json, DIR/timeseries.npz and DIR/report.html")
    p.add_argument("--no-html", action="store_true",
                   help="with --out, no DIR/report.html (campaign trials: their campaign has its own page; "
                        "`robot-ctrl report DIR` renders it later)")
    log_arg(p)
    p.set_defaults(run=_drawer, default_camera=CameraView.SIDE.value)


def add_robustness_parser(sub) -> None:
    p = sub.add_parser("robustness", help="campaign of pushed and mismatched walks (MuJoCo, in parallel)",
                       description="The 3 m walk at 0.25 m/s pushed in 8 directions at 4 gait phases with growing "
                                   "impulses (0.1..0.5 N·s/kg) until it falls, and under mass, friction and latency "
                                   "mismatch; writes DIR/robustness.json and DIR/robustness.html, and each walk's "
                                   "report under DIR.")
    p.add_argument("--out", type=Path, default=Path("runs/robustness"), help="output folder")
    p.add_argument("--jobs", type=int, default=2, help="walks run at a time, 1..64")
    backend_args(p)
    p.add_argument("--quick", action="store_true", help="a small grid (2 directions, 1 phase, 2 magnitudes)")
    step_timing_args(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_robustness)
