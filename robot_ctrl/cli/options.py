"""What every subcommand shares: its options' names in error messages, the range check and the
value parsers, the parents of the parsers, and the log line that does not tear a progress bar."""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from pathlib import Path

from robot_ctrl.modes import BaseState
from robot_ctrl.robot.config import ConfigError
from robot_ctrl.robot.config_file import available_robots

#: Settings' names in error messages (from the library's checks), and the options that set them.
COUPLING_OPTIONS = {"k": "--k", "alpha": "--alpha", "m_d": "--md", "m_z": "--mz", "m_psi": "--mpsi",
                    "k_sine": "--ksine", "lowpass": "--lowpass"}
GROUP_OPTIONS = {**COUPLING_OPTIONS, "n": "--robots", "seed": "--seed"}
DRAWER_OPTIONS = {"slot": "--slot", "distance": "--distance", "goal jump distance": "--goal-jump distance",
                  "goal jump time": "--goal-jump time", "goal jump pose": "--goal-jump pose", "cabinet": "--cabinet",
                  "method": "--method"}
ROOM_SIDE = (2.0, 20.0)  # [m] of --room's width and depth
DISTURBANCE_OPTIONS = {"mass_scale": "--mass-scale", "friction_scale": "--friction-scale",
                       "latency": "--latency-ms: latency", "push time": "--push: push time",
                       "push angle": "--push: push angle", "push impulse": "--push: push impulse",
                       "reply_loss": "--reply-loss"}

#: Step timing a user may give [s]: below 0.3 s of single support the swing is too fast for the
#: servos (peak torque 0.9 of the limit at 0.3 s on the 3 m walk); up to a slow 1.5 s step.
SINGLE_SUPPORT_RANGE = (0.3, 1.5)
DOUBLE_SUPPORT_RANGE = (0.1, 1.0)

#: (command, option) → the closed range [lo, hi] its value must lie in, checked by :func:`check_ranges`
#: before anything runs. Options whose check needs more than a range (step timing, drawer
#: distances, disturbances) are checked where their values are parsed.
RANGES: dict[tuple[str, str], tuple[float, float]] = {
    ("walk", "--dynfilter-passes"): (1, 10),
    ("robustness", "--jobs"): (1, 64),
    ("crowd run", "--duration"): (1e-3, 3600.0),
    ("crowd run", "--runs"): (1, 10000),
    ("crowd run", "--frequency"): (1e-3, 10.0),
    ("crowd run", "--speed"): (1e-3, 10.0),
    ("crowd audit", "--graphs"): (1, 100000),
    ("crowd audit", "--min-n"): (2, 60),
    ("crowd audit", "--max-n"): (2, 60),
    ("crowd audit", "--seed"): (0, 2**32 - 1),
    ("crowd figure", "--runs"): (1, 1000),
    ("crowd gait-profile", "--speed"): (0.05, 0.3),
    ("crowd gait-profile", "--cycles"): (2, 50),
    ("campaign", "--n"): (1, 10000),
    ("campaign", "--seed"): (0, 2**32 - 1),
    ("campaign", "--jobs"): (1, 256),
    ("synth-demos", "--jobs"): (1, 256),
    ("campaign", "--timeout"): (10.0, 86400.0),
}


def check_ranges(command: str, args: argparse.Namespace) -> None:
    """Refuse, with one line, the first option of ``command`` outside its range in :data:`RANGES`
    (NaN is outside every range; an option not given is not checked)."""
    for (cmd, option), (lo, hi) in RANGES.items():
        value = getattr(args, option.lstrip("-").replace("-", "_")) if cmd == command else lo
        if value is not None and not lo <= value <= hi:
            raise ConfigError(f"{command}: {option} {value} is outside the allowed range [{lo:g}, {hi:g}]")


def backend_args(p) -> None:
    """``--backend`` and ``--address`` of a campaign (``eval/campaigns/campaign_backends.py``)."""
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local: this machine's processes; ray: a Ray cluster (--address) or a Ray instance "
                        "started here (docs/campaigns.md)")
    p.add_argument("--address", help="with --backend ray: the cluster's head (ray://HOST:10001 or HOST:6379)")


def backend_of(args: argparse.Namespace, command: str):
    """The campaign backend ``--backend``, ``--jobs`` and ``--address`` ask for."""
    from robot_ctrl.eval.campaigns.campaign_backends import open_backend

    try:
        return open_backend(args.backend, args.jobs, args.address)
    except ValueError as exc:
        raise ConfigError(f"{command}: {exc}") from exc


def time_distance(text: str, option: str):
    """``TIME:DISTANCE`` ([s]:[m], e.g. ``3:2.4``) as a :class:`~robot_ctrl.synthesis.synthesizer.GoalJump`;
    the values' own ranges are the task's to check."""
    from robot_ctrl.synthesis.synthesizer import GoalJump

    try:
        time, distance = (float(v) for v in text.split(":"))
    except ValueError:
        raise ConfigError(f"{option} {text!r} must be TIME:DISTANCE, two numbers [s]:[m], e.g. 3:2.4") from None
    return GoalJump(time, distance)


def numbers(text: str, option: str, form: str, example: str) -> tuple[float, ...]:
    """``text``'s comma-separated finite numbers, as many as ``form`` names (``X,Y,YAW_DEG``)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != len(form.split(",")) or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"{option} {text!r} must be {form}, {len(form.split(','))} finite numbers, e.g. {example}")
    return values


def named(message: str, options: dict[str, str]) -> str:
    """``message`` with each setting's name (``m_d = ...``) replaced by its option (``--md = ...``)."""
    return re.sub(r"\b(" + "|".join(options) + r") = ", lambda m: f"{options[m.group(1)]} = ", message)


def command_line(args: argparse.Namespace) -> str:
    """The command that reproduces this run, as a shell would take it."""
    import shlex

    return shlex.join(["robot-ctrl", *args.argv])


def log_line(line: str) -> None:
    """Print a line without tearing the progress bar."""
    from tqdm import tqdm

    tqdm.write(line)


def check_log_path(args: argparse.Namespace) -> None:
    """Refuse a ``--log`` that cannot be written, before anything runs."""
    if getattr(args, "log", None) is not None:
        check_out_file(args.log, "--log")


def check_out_file(path: Path, option: str) -> None:
    """Refuse an output file ``path`` (given as ``option``) that cannot be written, before anything runs."""
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ConfigError(f"{option} {path} is a folder: give a file name")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"{option} {path}: cannot create {folder} ({exc.strerror})") from exc
    if not os.access(folder, os.W_OK):
        raise ConfigError(f"{option} {path}: {folder} is not writable")


def check_out_folder(args: argparse.Namespace) -> None:
    """Refuse an ``--out`` that is not a folder this process can write, before anything runs (not
    after a whole run, when its report is to be written)."""
    out = getattr(args, "out", None)
    if out is None:
        return
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} is a file, not a folder")
    existing = next(p for p in (out, *out.absolute().parents) if p.exists())
    if not existing.is_dir():
        raise ConfigError(f"--out {out}: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK):
        raise ConfigError(f"--out {out}: {existing} is not writable")


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse an output folder or log that cannot be written, a viewer without a display and a
    video without an offscreen renderer, before anything runs."""
    check_out_folder(args)
    check_log_path(args)
    if args.viewer and sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or
                                                                 os.environ.get("WAYLAND_DISPLAY")):
        raise ConfigError("--viewer needs a display, and neither DISPLAY nor WAYLAND_DISPLAY is set "
                          "(run without --viewer, or under a desktop or xvfb-run)")
    if args.video is not None:
        if args.video.suffix.lower() != ".mp4":
            raise ConfigError(f"--video {args.video}: the file must end in .mp4")
        from robot_ctrl.sim.mujoco_video import check_renderer

        try:
            check_renderer()
        except RuntimeError as exc:
            raise ConfigError(str(exc)) from exc


def step_timing(args: argparse.Namespace, command: str) -> dict[str, float]:
    """``--single-support`` and ``--double-support`` [s] where given (whole pattern-generator samples,
    0.1 s), as WalkParams fields; those not given are the robot's."""
    from robot_ctrl.wpg.params import WalkParams

    sample = WalkParams.sample_time
    given = {}
    for option, field, (lo, hi) in (("--single-support", "single_support", SINGLE_SUPPORT_RANGE),
                                    ("--double-support", "double_support", DOUBLE_SUPPORT_RANGE)):
        value = getattr(args, field)
        if value is None:
            continue
        if not lo <= value <= hi or abs(value / sample - round(value / sample)) > 1e-9:
            raise ConfigError(f"{command}: {option} {value} must be a multiple of {sample:g} s in [{lo:g}, {hi:g}] s")
        given[field] = value
    return given


def robot_parent() -> argparse.ArgumentParser:
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument("--robot", default="talos", help=f"robot config name ({', '.join(available_robots())})")
    return parent


def step_timing_args(p) -> None:
    from robot_ctrl.wpg.params import WalkParams

    p.add_argument("--single-support", type=float,
                   help="single-support time of each step [s], a multiple of 0.1 in "
                        f"[{SINGLE_SUPPORT_RANGE[0]:g}, {SINGLE_SUPPORT_RANGE[1]:g}] (default: the robot's, "
                        f"{WalkParams.single_support:g} for Talos): shorter steps catch pushes sooner")
    p.add_argument("--double-support", type=float,
                   help="double-support time between steps [s], a multiple of 0.1 in "
                        f"[{DOUBLE_SUPPORT_RANGE[0]:g}, {DOUBLE_SUPPORT_RANGE[1]:g}] (default: the robot's, "
                        f"{WalkParams.double_support:g} for Talos)")


def log_arg(p) -> None:
    p.add_argument("--log", type=Path, metavar="FILE",
                   help="write a per-tick binary log (state, command, safety, bus, timing); robot-ctrl log FILE "
                        "turns it into a report")


def base_state_arg(p) -> None:
    p.add_argument("--base-state", choices=[m.value for m in BaseState],
                   help="the controller's base pose and velocity: the simulator's (default in simulation), or "
                        "estimated from the IMU, the encoders and the foot force sensors (control/estimation/base_estimator.py; "
                        "the only one on real servos)")


def dataset_arg(p) -> None:
    p.add_argument("--dataset", type=Path, default=None,
                   help="demonstration set the walk-and-reach primitives are learned from (default: the robot's, "
                        "models/<robot>_walk_reach_*.npz; docs/synthesis.md)")


MAX_SOURCES = 8  # periodic sources per group of the mixture model


def parse_sources(text: str, option: str) -> tuple[tuple[int, int], ...]:
    """``FIRST+EXTRA[,FIRST+EXTRA...]`` (e.g. ``4+3``: periodic sources for action 1, more for actions
    2 and 3) as pairs; one line naming ``option`` and the ranges otherwise."""
    pairs = []
    for item in text.split(","):
        try:
            first, extra = (int(v) for v in item.split("+"))
        except ValueError:
            raise ConfigError(f"{option} {item!r} is not FIRST+EXTRA (e.g. 4+3)") from None
        if not (1 <= first <= MAX_SOURCES and 0 <= extra <= MAX_SOURCES):
            raise ConfigError(f"{option} {item}: FIRST must be in [1, {MAX_SOURCES}] and EXTRA in [0, {MAX_SOURCES}]")
        pairs.append((first, extra))
    return tuple(pairs)


def sources_arg(p, many: bool = False) -> None:
    p.add_argument("--sources", default="3+2", metavar="FIRST+EXTRA" + ("[,...]" if many else ""),
                   help="periodic sources of the learned mixture model: FIRST for action 1, EXTRA more for actions 2 "
                        "and 3" + (", comma-separated to compare (e.g. 3+2,4+3,5+4; thesis Fig. 3.41)" if many else
                                   " (default 3+2; the thesis's robot used 4+3)"))
