"""``robot-ctrl`` command line: one subcommand per user-facing task."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from robot_ctrl.robot.config import ConfigError, available_robots


def _check_viewer(args: argparse.Namespace) -> None:
    if args.viewer and sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or
                                                                 os.environ.get("WAYLAND_DISPLAY")):
        raise ConfigError("--viewer needs a display, and neither DISPLAY nor WAYLAND_DISPLAY is set "
                          "(run without --viewer, or under a desktop or xvfb-run)")


def _balance(args: argparse.Namespace) -> int:
    from robot_ctrl.hw.mujoco_backend import MujocoBackend
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios.balance import run_balance

    _check_viewer(args)
    robot = load_robot(args.robot)
    report = run_balance(robot, MujocoBackend(robot, viewer=args.viewer), out_dir=args.out)
    return 1 if report["fell"] else 0


def _walk(args: argparse.Namespace) -> int:
    import math

    from robot_ctrl.control.path_follower import WalkGoal
    from robot_ctrl.hw.mujoco_backend import MujocoBackend
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios.walk import run_walk

    try:
        goal = WalkGoal(distance=args.distance, turn=math.radians(args.turn_deg), lateral=args.lateral,
                        speed=args.speed)
    except ValueError as exc:
        raise ConfigError(f"walk: {exc}".replace("turn = ", "--turn-deg (in rad) = ")) from exc
    _check_viewer(args)
    robot = load_robot(args.robot)
    report = run_walk(robot, MujocoBackend(robot, viewer=args.viewer), goal, stabilize=not args.no_stabilizer,
                      out_dir=args.out)
    return 1 if report["fell"] else 0


def _robots(args: argparse.Namespace) -> int:
    from robot_ctrl.robot.model import load_robot

    for name in available_robots():
        robot = load_robot(name)
        print(f"{name}: {robot.nj} joints, {robot.mass:.2f} kg, URDF {robot.files.urdf}")
        if args.convert:
            print(f"  MJCF: {robot.mjcf_path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="robot-ctrl", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("balance", help="stand, shift weight, lift a foot, reach with the right hand (MuJoCo)",
                       description="Balance demo in MuJoCo at 200 Hz control: half-sitting, CoM over the left foot, "
                                   "right foot up 5 cm and back, CoM back, right-hand reach to (0.4, -0.2, 0.8) m in "
                                   "the start floor frame and back. Exit status 1 if the robot fell.")
    p.add_argument("--robot", default="talos", help=f"robot config name ({', '.join(available_robots())})")
    p.add_argument("--viewer", action="store_true", help="open the MuJoCo viewer (needs a display)")
    p.add_argument("--out", type=Path, help="write DIR/report.json")
    p.set_defaults(run=_balance)

    p = sub.add_parser("walk", help="walk a path with the MPC walking controller (MuJoCo)",
                       description="Walk straight (--distance), along an arc (--distance with --turn-deg) or "
                                   "sideways (--lateral), stop in double support and stand 2 s. Exit status 1 if "
                                   "the robot fell.")
    p.add_argument("--robot", default="talos", help=f"robot config name ({', '.join(available_robots())})")
    p.add_argument("--distance", type=float, default=0.0, help="path length forward [m] (arc length when turning)")
    p.add_argument("--turn-deg", type=float, default=0.0, help="heading change over the path [deg], + left")
    p.add_argument("--lateral", type=float, default=0.0, help="side-step distance [m], + left, - right")
    p.add_argument("--speed", type=float, default=0.25, help="walking speed [m/s], 0.02..0.5")
    p.add_argument("--no-stabilizer", action="store_true", help="open loop: no DCM/ZMP balance feedback")
    p.add_argument("--viewer", action="store_true", help="open the MuJoCo viewer (needs a display)")
    p.add_argument("--out", type=Path, help="write DIR/report.json")
    p.set_defaults(run=_walk)

    p = sub.add_parser("robots", help="list the robot configs (and convert their MJCF with --convert)")
    p.add_argument("--convert", action="store_true", help="convert each robot to its cached MJCF and print the path")
    p.set_defaults(run=_robots)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except ConfigError as exc:
        print(f"robot-ctrl: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
