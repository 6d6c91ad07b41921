"""The ``robot-ctrl`` parser and entry point: exit statuses, signals, errors as one line."""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from robot_ctrl.cli import campaign, crowd, hw, robot_runs, synth, tools
from robot_ctrl.cli.options import robot_parent
from robot_ctrl.cli.simulation import simulation_parent
from robot_ctrl.robot.config import ConfigError



def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="robot-ctrl", description="``robot-ctrl`` command line: one subcommand per "
                                                                      "user-facing task.")
    sub = parser.add_subparsers(dest="command", required=True)
    robot = robot_parent()
    sim = simulation_parent(robot)
    robot_runs.add_scenario_parsers(sub, sim)
    crowd.add_parsers(sub, sim)
    robot_runs.add_robustness_parser(sub)
    campaign.add_parsers(sub, robot)
    synth.add_parsers(sub, robot)
    hw.add_parsers(sub, robot)
    tools.add_parsers(sub)
    return parser


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def _interrupted(exc: KeyboardInterrupt) -> int:
    print(f"robot-ctrl: interrupted{f' ({exc})' if str(exc) else ''}", file=sys.stderr)
    return 130


def main(argv: list[str] | None = None) -> int:
    """Exit status: 0 done, 1 the robot fell, 2 bad input, 3 a hardware fault, 130 interrupted
    (Ctrl-C or SIGTERM: the hardware is closed on the way out, damping then disable)."""
    from robot_ctrl.hw.adapter import HardwareFault

    args = build_parser().parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # what a report gives to reproduce the run
    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _interrupt) if in_main_thread else None
    try:
        return args.run(args)
    except ConfigError as exc:
        print(f"robot-ctrl: error: {exc}", file=sys.stderr)
        return 2
    except HardwareFault as exc:
        print(f"robot-ctrl: hardware fault: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt as exc:
        return _interrupted(exc)
    except SystemError as exc:
        # A signal that lands while compiled code (numba) calls back into Python (to raise an
        # exception it caught, say) comes out as a SystemError caused by the KeyboardInterrupt.
        cause = exc.__cause__
        while cause is not None and not isinstance(cause, KeyboardInterrupt):
            cause = cause.__cause__
        if cause is None:
            raise
        return _interrupted(cause)
    finally:
        if in_main_thread:
            signal.signal(signal.SIGTERM, previous)
