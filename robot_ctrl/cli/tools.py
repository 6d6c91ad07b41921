"""``robot-ctrl report | log | robots``: reports from a run's folder or tick log, and the robot configs."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_ctrl.cli.options import log_line
from robot_ctrl.robot.config import ConfigError
from robot_ctrl.robot.config_file import available_robots


def _report(args: argparse.Namespace) -> int:
    from robot_ctrl.eval.reports.html_report import render_report

    try:
        path = render_report(args.dir)
    except FileNotFoundError as exc:
        raise ConfigError(f"report: {exc}") from exc
    print(f"wrote {path}")
    return 0


def _log_command(args: argparse.Namespace) -> int:
    import numpy as np

    from robot_ctrl.eval.recording.report_file import write_report
    from robot_ctrl.eval.recording.tick_log import log_report, log_series, read_tick_log
    from robot_ctrl.eval.reports.html_report import render_report

    if not args.file.is_file():
        raise ConfigError(f"log: {args.file} does not exist")
    try:
        log = read_tick_log(args.file)
        report = log_report(log)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"log: {exc}") from exc
    out = args.out if args.out is not None else args.file.with_suffix("")
    if out.exists() and not out.is_dir():
        raise ConfigError(f"log: --out {out} is a file, not a folder")
    write_report(report, out, log_line)
    np.savez_compressed(out / "timeseries.npz", **log_series(log))
    log_line(f"wrote {out / 'timeseries.npz'}")
    log_line(f"wrote {render_report(out)}")
    return 0


def _robots(args: argparse.Namespace) -> int:
    from robot_ctrl.robot.model import load_robot

    for name in available_robots():
        robot = load_robot(name)
        print(f"{name}: {robot.nj} joints, {robot.mass:.2f} kg, URDF {robot.files.urdf}")
        if args.convert:
            print(f"  MJCF: {robot.mjcf_path}")
    return 0


def add_parsers(sub) -> None:
    p = sub.add_parser("report", help="render DIR/report.json (+ timeseries) as DIR/report.html",
                       description="Self-contained HTML: metrics table, ZMP reference vs measured, top view of CoM "
                                   "and footprints, joint torque peaks against limits, GRF against time.")
    p.add_argument("dir", type=Path, help="a run's output folder (--out of balance or walk)")
    p.set_defaults(run=_report)
    p = sub.add_parser("log", help="turn a tick log (--log FILE of a run) into report.json and report.html",
                       description="Reads a per-tick binary log written with --log by walk, drawer, balance or hw "
                                   "stand/jog (simulated, emulated or real servos) and writes DIR/report.json (falls "
                                   "where the base was measured, peak torques, command tracking, safety "
                                   "interventions, bus statistics, loop timing), DIR/timeseries.npz and "
                                   "DIR/report.html.")
    p.add_argument("file", type=Path, help="the log")
    p.add_argument("--out", type=Path, help="output folder (default: the log's name without suffix, beside it)")
    p.set_defaults(run=_log_command)
    p = sub.add_parser("robots", help="list the robot configs (and convert their MJCF with --convert)")
    p.add_argument("--convert", action="store_true", help="convert each robot to its cached MJCF and print the path")
    p.set_defaults(run=_robots)
