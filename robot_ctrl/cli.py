"""``robot-ctrl`` command line: one subcommand per user-facing task."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from robot_ctrl.robot.config import ConfigError, available_robots


def _balance(args: argparse.Namespace) -> int:
    from robot_ctrl.hw.mujoco_backend import MujocoBackend
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios.balance import run_balance

    robot = load_robot(args.robot)
    report = run_balance(robot, MujocoBackend(robot, viewer=args.viewer), out_dir=args.out)
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
