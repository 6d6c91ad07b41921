"""The options and the set-up shared by every MuJoCo (or real-servo) scenario: the robot, its
hardware, the disturbances, how the controller sees the base, the tick log and the pacer."""

from __future__ import annotations

import argparse
from contextlib import contextmanager
from pathlib import Path

from robot_ctrl.cli.options import DISTURBANCE_OPTIONS, check_outputs, command_line, log_line, named
from robot_ctrl.modes import BaseState, CameraView, HardwareKind
from robot_ctrl.robot.config import ConfigError


def simulation_parent(robot: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Options of every MuJoCo scenario."""
    parent = argparse.ArgumentParser(add_help=False, parents=[robot])
    parent.add_argument("--hw", choices=[k.value for k in HardwareKind], default=HardwareKind.MUJOCO.value,
                        help="backend, always behind the safety layer: MuJoCo, MuJoCo behind an emulated MIT-CAN / "
                             "Dynamixel servo bus, or real servos (mit-can, dynamixel: the start sequence first, "
                             "then the scenario on the estimated base; docs/hardware.md)")
    parent.add_argument("--bus-config", help="bus mapping (configs/hw name or YAML path); required for real servos")
    parent.add_argument("--allow-drives-without-timeout", action="store_true",
                        help="real servos: enable drives that have no command timeout of their own (they hold their "
                             "last command if this process dies; the run says which)")
    parent.add_argument("--viewer", action="store_true", help="open the MuJoCo viewer (needs a display)")
    parent.add_argument("--video", type=Path, metavar="FILE.mp4",
                        help="record the run at 30 fps (MuJoCo offscreen renderer; MUJOCO_GL=egl when there is no display)")
    parent.add_argument("--camera", choices=[v.value for v in CameraView],
                        help="the video's camera: behind the robots (follow, the default), from the robot's left side "
                             "where its hands work (side, the drawer task's default), from above (top), or close on "
                             "its left hand (hand)")
    parent.add_argument("--quiet", action="store_true", help="no progress bar")
    disturb = parent.add_argument_group("disturbances of the simulated robot (docs/robustness.md)")
    disturb.add_argument("--push", action="append", default=[], metavar="TIME:ANGLE_DEG:IMPULSE",
                         help="a 0.1 s horizontal push on the base from TIME [s], direction ANGLE_DEG in the start "
                              "frame (0 forward, 90 left), IMPULSE N·s per kg of robot mass, 0..2; repeatable")
    disturb.add_argument("--mass-scale", type=float, default=1.0, help="every body's mass and inertia, 0.5..2")
    disturb.add_argument("--friction-scale", type=float, default=1.0, help="sliding friction of floor and feet, 0.05..3")
    disturb.add_argument("--latency-ms", type=float, default=0.0,
                         help="command delay [ms], a multiple of the 5 ms control period, 0..100")
    disturb.add_argument("--sensor-noise", action="store_true",
                         help="noisy encoders (1 mrad), IMU attitude (0.5°) and foot F/T (5 N, 0.5 N·m)")
    disturb.add_argument("--reply-loss", type=float, default=0.0, metavar="P",
                         help="with --hw mit-can-emulated: each servo reply lost with probability P, 0..0.5")
    return parent


def parse_disturbances(args: argparse.Namespace):
    """``--push``, ``--mass-scale``, ... as :class:`~robot_ctrl.sim.disturbances.Disturbances`."""
    from robot_ctrl.sim.disturbances import Disturbances, Push

    try:
        dist = Disturbances(tuple(Push.parse(p) for p in args.push), args.mass_scale, args.friction_scale,
                            args.latency_ms / 1e3, args.sensor_noise, reply_loss=args.reply_loss)
        dist.latency_ticks(0.005)
    except ValueError as exc:
        raise ConfigError(named(str(exc), DISTURBANCE_OPTIONS)) from exc
    if dist.reply_loss and args.hw != HardwareKind.MIT_CAN_EMULATED.value:
        raise ConfigError(f"--reply-loss acts on the emulated MIT-CAN bus (--hw mit-can-emulated), not on --hw {args.hw}")
    return dist


def simulation(args: argparse.Namespace, robot=None, prop=None):
    """The robot (``--robot``, unless the command loaded it already), its disturbances and its
    hardware for a single-robot scenario: simulated, emulated or real servos; ``prop``: a scene prop
    placed in the robot's world (the drawer cabinet)."""
    from robot_ctrl.backends import open_hardware
    from robot_ctrl.robot.model import load_robot

    check_outputs(args)
    disturbances = parse_disturbances(args)
    robot = robot or load_robot(args.robot)
    check_controller_config(robot)
    if HardwareKind.parse(args.hw).real:
        check_real_robot(args, disturbances, robot)
    try:
        return robot, disturbances, open_hardware(args.hw, robot, args.bus_config, viewer=args.viewer,
                                                  video=video_request(args, robot), disturbances=disturbances,
                                                  prop=prop,
                                                  allow_drives_without_timeout=args.allow_drives_without_timeout)
    except (FileNotFoundError, ValueError) as exc:
        raise ConfigError(f"--hw {args.hw}: {exc}") from exc


def video_request(args: argparse.Namespace, robot=None):
    """``--video`` and ``--camera`` as a :class:`~robot_ctrl.sim.mujoco_video.Video` (None: no video); the
    command's default camera is its ``default_camera``."""
    from robot_ctrl.sim.mujoco_video import Video

    if args.video is None:
        return None
    view = CameraView(args.camera or getattr(args, "default_camera", CameraView.FOLLOW.value))
    hand = None if robot is None else f"{robot.name}/{robot.config.hands['left']}"
    return Video(Path(args.video), view, hand)


def check_controller_config(robot) -> None:
    """The robot config's walking parameters and balance gains, checked before anything moves."""
    from robot_ctrl.control.controllers.stabilizer import StabilizerGains
    from robot_ctrl.wpg.params import WalkParams

    try:
        WalkParams.of_robot(robot.config.walking)
        StabilizerGains.of_robot(robot.config.stabilizer)
    except ValueError as exc:
        raise ConfigError(f"--robot {robot.name}: {exc}") from exc


def check_real_robot(args: argparse.Namespace, disturbances, robot) -> None:
    """Refuse what a scenario on real servos cannot do, before anything moves."""
    from robot_ctrl.buses.bus_config import load_bus_config, shipped_bus_configs
    from robot_ctrl.sim.disturbances import Disturbances

    if disturbances != Disturbances():
        raise ConfigError(f"--hw {args.hw}: --push, --mass-scale, --friction-scale, --latency-ms, --sensor-noise and "
                          "--reply-loss act on a simulated robot, not on real servos")
    if args.viewer or args.video is not None:
        raise ConfigError(f"--hw {args.hw}: --viewer and --video show the simulation; real servos have none")
    if args.bus_config is None:
        raise ConfigError(f"--hw {args.hw} needs --bus-config: the YAML naming your buses, ids, directions, zero "
                          f"offsets and body sensors (start from {shipped_bus_configs()})")
    if not load_bus_config(args.bus_config, robot.joint_names).body_sensors:
        raise ConfigError(f"--hw {args.hw}: {args.command} needs the robot's IMU and foot force/torque sensors: name "
                          "their driver in the bus config (body_sensors: module:function, docs/hardware.md)")


def base_state_of(args: argparse.Namespace) -> BaseState:
    """``--base-state``: the simulator's by default; on real servos, which have none, the estimate."""
    real = HardwareKind.parse(args.hw).real
    if args.base_state is None:
        return BaseState.ESTIMATED if real else BaseState.SIMULATED
    if real and args.base_state == BaseState.SIMULATED.value:
        raise ConfigError(f"--base-state simulated: --hw {args.hw} has no simulator; real servos walk on the "
                          "estimated base (--base-state estimated, the default there)")
    return BaseState(args.base_state)


@contextmanager
def on_the_robot(args: argparse.Namespace, robot, hw, control_dt: float):
    """The run's recorders (the tick log) and, on real servos, its pacer (absolute deadlines; the
    scenario then starts with the start sequence, ``scenarios/robot_run.py``)."""
    pacer = real_servo_pacer(HardwareKind.parse(args.hw), control_dt)
    with tick_log_recorders(args, robot, hw, control_dt, pacer) as recorders:
        yield recorders, pacer


def real_servo_pacer(kind: HardwareKind, control_dt: float):
    """The pacer of a loop on real servos (real-time scheduling asked for); None for a simulated
    robot, which waits for its controller."""
    from robot_ctrl.control.loop.pacer import Pacer

    if not kind.real:
        return None
    if not Pacer.request_realtime():
        log_line("robot-ctrl: no real-time scheduling (SCHED_FIFO not permitted); timing in the report")
    return Pacer(control_dt)


def tick_log_recorders(args: argparse.Namespace, robot, hw, control_dt: float, pacer=None):
    """The run's tick log (``--log FILE``) as extra recorders, closed with the run."""
    from robot_ctrl.eval.recording.tick_log import open_tick_log

    return open_tick_log(args.log, robot, hw, control_dt, pacer)


def finish(args: argparse.Namespace, report: dict, html: bool = False) -> int:
    """After a run: its report.json gains the command that reproduces it (and the video it
    recorded), ``html`` renders its report.html; the exit status (1: the robot fell)."""
    if args.video is not None:
        log_line(f"wrote {args.video}")
    if args.out is not None:
        from robot_ctrl.eval.recording.report_file import write_report

        report["command"] = command_line(args)
        if args.video is not None:
            report["video"] = str(Path(args.video).resolve())
        write_report(report, args.out, log=lambda line: None)
        if html:
            from robot_ctrl.eval.reports.html_report import render_report

            log_line(f"wrote {render_report(args.out)}")
    return 1 if report["fell"] else 0
