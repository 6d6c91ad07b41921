"""``robot-ctrl hw scan | read | check | stand | jog | zero``: servo bring-up, one step at a time."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_ctrl.cli.options import check_log_path, check_out_file, log_arg, named
from robot_ctrl.cli.simulation import real_servo_pacer, tick_log_recorders
from robot_ctrl.modes import HardwareKind
from robot_ctrl.robot.config import ConfigError


def add_parsers(sub, robot) -> None:
    p = sub.add_parser("hw", parents=[robot], help="bring up real or emulated servos: scan, read, check, stand, jog, "
                                                    "zero; emulate drives for another process",
                       description="One bring-up step at a time (docs/hardware.md): scan (every motor answers), read "
                                   "(joints against limits, motors off), check (scan + a posture stand may start "
                                   "from), stand (minimum-jerk move to half-sitting at reduced gains, faulting on "
                                   "tracking error), jog JOINT DELTA (one joint by DELTA rad), zero JOINT (a drive's "
                                   "encoder zero). emulate: emulated drives in this process, serving the buses "
                                   "the bus config names to other processes until Ctrl-C (--hw mit-can or dynamixel; "
                                   "--status FILE). Exit status 3 on a hardware fault; the servos end in damping, "
                                   "disabled.")
    p.add_argument("action", choices=["scan", "read", "check", "stand", "jog", "zero", "emulate"])
    p.add_argument("joint", nargs="?", help="jog, zero: the joint")
    p.add_argument("delta", nargs="?", type=float, help="jog: the angle to move by [rad]")
    p.add_argument("--hw", choices=[k.value for k in HardwareKind], default=HardwareKind.MIT_CAN_EMULATED.value,
                   help="servos: real (mit-can, dynamixel: the interfaces in --bus-config) or emulated")
    p.add_argument("--bus-config", help="bus mapping (configs/hw name or YAML path); required for real servos")
    p.add_argument("--allow-drives-without-timeout", action="store_true",
                   help="real servos: enable drives that have no command timeout of their own (they hold their "
                        "last command if this process dies; the run says which)")
    p.add_argument("--duration", type=float, default=4.0, help="stand, jog: the move's duration [s], 0.5..60")
    p.add_argument("--gain-scale", type=float, default=0.3, help="stand, jog: share of the servo stiffness, 0.01..1")
    p.add_argument("--status", type=Path, metavar="FILE",
                   help="emulate: a JSON file rewritten every 10 ms with each drive's state (enabled, kp, kd, "
                        "command_age_s, stopped)")
    log_arg(p)
    p.set_defaults(run=_hw)


def _hw(args: argparse.Namespace) -> int:
    from robot_ctrl.backends import open_hardware
    from robot_ctrl.control.loop.start_sequence import StartParams
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios import bringup

    if args.action in ("jog", "zero") and args.joint is None or args.action == "jog" and args.delta is None:
        raise ConfigError(f"hw {args.action} needs {'JOINT DELTA' if args.action == 'jog' else 'JOINT'}")
    try:
        params = StartParams(duration=args.duration, gain_scale=args.gain_scale)
        robot = load_robot(args.robot)
        target = bringup.jog_target(robot, args.joint, args.delta) if args.action == "jog" else None
        if args.action == "zero" and args.joint not in robot.joint_names:
            raise ValueError(f"zero: {args.joint!r} is not a joint of {robot.name}")
    except ValueError as exc:
        raise ConfigError(named(str(exc).replace("StartParams.", ""), {"duration": "--duration",
                                                                        "gain_scale": "--gain-scale"})) from exc
    check_log_path(args)
    kind = HardwareKind.parse(args.hw)
    if args.action == "emulate":
        return _emulate(args, kind, robot)
    if args.status is not None:
        raise ConfigError("--status is for hw emulate (the emulated drives' status file)")
    if args.action == "zero" and kind not in (HardwareKind.MIT_CAN, HardwareKind.MIT_CAN_EMULATED):
        raise ConfigError(f"hw zero sets an MIT drive's encoder zero; with --hw {kind.value} put the joint's "
                          "zero_offset in the bus config instead (docs/hardware.md, Bring-up)")
    with open_hardware(kind, robot, args.bus_config,
                       allow_drives_without_timeout=args.allow_drives_without_timeout) as hw:
        if args.action == "read":
            for row in bringup.read(robot, hw):
                print("  ".join(f"{k} {v}" for k, v in row.items()))
            return 0
        if args.action == "zero":
            bringup.zero(hw, args.joint)
            print(f"{args.joint}: its drive's zero is now its present position")
            return 0
        if args.action in ("scan", "check"):
            result = bringup.scan(robot, hw) if args.action == "scan" else bringup.check(robot, hw, params)
        else:
            pacer = real_servo_pacer(kind, params.control_dt)
            with tick_log_recorders(args, robot, hw, params.control_dt, pacer) as recorders:
                result = bringup.move(robot, hw, target, params, pacer, recorders)
    for key, value in result.items():
        print(f"{key}: {value}")
    return 0 if result.get("reached", True) else 3


def _emulate(args: argparse.Namespace, kind: HardwareKind, robot) -> int:
    from robot_ctrl.scenarios.emulated_servos import serve_emulated_drives

    if not kind.real:
        raise ConfigError(f"hw emulate --hw {kind.value}: name the drives to emulate, mit-can or dynamixel (the "
                          "other process then runs --hw mit-can or dynamixel against them)")
    if args.bus_config is None:
        raise ConfigError(f"hw emulate needs --bus-config: the buses to serve (e.g. configs/hw/"
                          f"{robot.name}_{kind.value.replace('-', '_')}_emulated.yaml)")
    if args.status is not None:
        check_out_file(args.status, "--status")
    serve_emulated_drives(kind, robot, args.bus_config, args.status, print)
    return 0
