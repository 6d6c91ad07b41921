"""``robot-ctrl`` command line: one subcommand per user-facing task."""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
import threading
from contextlib import contextmanager
from pathlib import Path

from robot_ctrl.modes import ArmMotion, BaseState, FilterMode, HardwareKind
from robot_ctrl.robot.config import ConfigError, available_robots

#: Settings' names in error messages, and the options that set them.
_COUPLING_OPTIONS = {"k": "--k", "alpha": "--alpha", "m_d": "--md", "m_z": "--mz", "m_psi": "--mpsi",
                     "k_sine": "--ksine", "lowpass": "--lowpass"}
_GROUP_OPTIONS = {**_COUPLING_OPTIONS, "n": "--robots", "seed": "--seed"}
_DRAWER_OPTIONS = {"slot": "--slot", "distance": "--distance", "goal jump distance": "--goal-jump distance",
                   "goal jump time": "--goal-jump time"}
_DISTURBANCE_OPTIONS = {"mass_scale": "--mass-scale", "friction_scale": "--friction-scale",
                        "latency": "--latency-ms: latency", "push time": "--push: push time",
                        "push angle": "--push: push angle", "push impulse": "--push: push impulse",
                        "reply_loss": "--reply-loss"}
#: Step timing a user may give [s]: below 0.3 s of single support the swing is too fast for the
#: servos (peak torque 0.9 of the limit at 0.3 s on the 3 m walk); up to a slow 1.5 s step.
SINGLE_SUPPORT_RANGE = (0.3, 1.5)
DOUBLE_SUPPORT_RANGE = (0.1, 1.0)


def _named(message: str, options: dict[str, str]) -> str:
    """``message`` with each setting's name (``m_d = ...``) replaced by its option (``--md = ...``)."""
    return re.sub(r"\b(" + "|".join(options) + r") = ", lambda m: f"{options[m.group(1)]} = ", message)


def _log(line: str) -> None:
    """Print a line without tearing the progress bar."""
    from tqdm import tqdm

    tqdm.write(line)


def _check_log_path(args: argparse.Namespace) -> None:
    """Refuse a ``--log`` that cannot be written, before anything runs."""
    path = getattr(args, "log", None)
    if path is None:
        return
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ConfigError(f"--log {path} is a folder: give a file name")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--log {path}: cannot create {folder} ({exc.strerror})") from exc
    if not os.access(folder, os.W_OK):
        raise ConfigError(f"--log {path}: {folder} is not writable")


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse a viewer without a display and a video without an offscreen renderer, before anything runs."""
    _check_log_path(args)
    if args.viewer and sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or
                                                                 os.environ.get("WAYLAND_DISPLAY")):
        raise ConfigError("--viewer needs a display, and neither DISPLAY nor WAYLAND_DISPLAY is set "
                          "(run without --viewer, or under a desktop or xvfb-run)")
    if args.video is not None:
        if args.video.suffix.lower() != ".mp4":
            raise ConfigError(f"--video {args.video}: the file must end in .mp4")
        from robot_ctrl.hw.mujoco_video import check_renderer

        try:
            check_renderer()
        except RuntimeError as exc:
            raise ConfigError(str(exc)) from exc


def _simulation(args: argparse.Namespace):
    """The robot and its hardware for a single-robot scenario: simulated, emulated or real servos."""
    from robot_ctrl.hw.hardware import open_hardware
    from robot_ctrl.robot.model import load_robot

    _check_outputs(args)
    disturbances = _disturbances(args)
    robot = load_robot(args.robot)
    if HardwareKind.parse(args.hw).real:
        _check_real_robot(args, disturbances, robot)
    try:
        return robot, disturbances, open_hardware(args.hw, robot, args.bus_config, viewer=args.viewer,
                                                  video=args.video, disturbances=disturbances,
                                                  drawer=getattr(args, "drawer", None))
    except (FileNotFoundError, ValueError) as exc:
        raise ConfigError(f"--hw {args.hw}: {exc}") from exc


def _check_real_robot(args: argparse.Namespace, disturbances, robot) -> None:
    """Refuse what a scenario on real servos cannot do, before anything moves."""
    from robot_ctrl.hw.bus_config import load_bus_config
    from robot_ctrl.hw.disturbances import Disturbances

    if disturbances != Disturbances():
        raise ConfigError(f"--hw {args.hw}: --push, --mass-scale, --friction-scale, --latency-ms, --sensor-noise and "
                          "--reply-loss act on a simulated robot, not on real servos")
    if args.viewer or args.video is not None:
        raise ConfigError(f"--hw {args.hw}: --viewer and --video show the simulation; real servos have none")
    if args.bus_config is None:
        raise ConfigError(f"--hw {args.hw} needs --bus-config: the YAML naming your buses, ids, directions, zero "
                          "offsets and body sensors (start from configs/hw/talos_mit_can.yaml or talos_dynamixel.yaml)")
    if not load_bus_config(args.bus_config, robot.joint_names).body_sensors:
        raise ConfigError(f"--hw {args.hw}: {args.command} needs the robot's IMU and foot force/torque sensors: name "
                          "their driver in the bus config (body_sensors: module:function, docs/hardware.md)")


def _base_state(args: argparse.Namespace) -> BaseState:
    """``--base-state``: the simulator's by default; on real servos, which have none, the estimate."""
    real = HardwareKind.parse(args.hw).real
    if args.base_state is None:
        return BaseState.ESTIMATED if real else BaseState.SIMULATED
    if real and args.base_state == BaseState.SIMULATED.value:
        raise ConfigError(f"--base-state simulated: --hw {args.hw} has no simulator; real servos walk on the "
                          "estimated base (--base-state estimated, the default there)")
    return BaseState(args.base_state)


@contextmanager
def _on_the_robot(args: argparse.Namespace, robot, hw, control_dt: float):
    """The run's recorders (the tick log) and, on real servos, its pacer (absolute deadlines; the
    scenario then starts with the start sequence, ``scenarios/robot_run.py``)."""
    pacer = _real_servo_pacer(HardwareKind.parse(args.hw), control_dt)
    with _tick_log(args, robot, hw, control_dt, pacer) as recorders:
        yield recorders, pacer


def _real_servo_pacer(kind: HardwareKind, control_dt: float):
    """The pacer of a loop on real servos (real-time scheduling asked for); None for a simulated
    robot, which waits for its controller."""
    from robot_ctrl.control.pacer import Pacer

    if not kind.real:
        return None
    if not Pacer.request_realtime():
        _log("robot-ctrl: no real-time scheduling (SCHED_FIFO not permitted); timing in the report")
    return Pacer(control_dt)


def _log_command(args: argparse.Namespace) -> int:
    import numpy as np

    from robot_ctrl.eval.html_report import render_report
    from robot_ctrl.eval.report_file import write_report
    from robot_ctrl.eval.tick_log import log_report, log_series, read_tick_log

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
    write_report(report, out, _log)
    np.savez_compressed(out / "timeseries.npz", **log_series(log))
    _log(f"wrote {out / 'timeseries.npz'}")
    _log(f"wrote {render_report(out)}")
    return 0


def _tick_log(args: argparse.Namespace, robot, hw, control_dt: float, pacer=None):
    """The run's tick log (``--log FILE``) as extra recorders, closed with the run."""
    from robot_ctrl.eval.tick_log import open_tick_log

    return open_tick_log(args.log, robot, hw, control_dt, pacer)


def _finish(args: argparse.Namespace, report: dict) -> int:
    if args.video is not None:
        _log(f"wrote {args.video}")
    return 1 if report["fell"] else 0


def _balance(args: argparse.Namespace) -> int:
    from robot_ctrl.control.balance_controller import BalanceParams
    from robot_ctrl.scenarios.balance import run_balance

    base_state = _base_state(args)
    robot, disturbances, hardware = _simulation(args)
    with hardware as hw, _on_the_robot(args, robot, hw, BalanceParams.control_dt) as (recorders, pacer):
        report = run_balance(robot, hw, out_dir=args.out, log=_log, progress=not args.quiet,
                             disturbances=disturbances, recorders=recorders, base_state=base_state, pacer=pacer)
    return _finish(args, report)


def _walk(args: argparse.Namespace) -> int:
    import math

    from robot_ctrl.control.path_follower import WalkGoal
    from robot_ctrl.scenarios.walk import WalkSettings, run_walk

    try:
        goal = WalkGoal(distance=args.distance, turn=math.radians(args.turn_deg), lateral=args.lateral,
                        speed=args.speed)
    except ValueError as exc:
        raise ConfigError(f"walk: {exc}".replace("turn = ", "--turn-deg (in rad) = ")) from exc
    if not 1 <= args.dynfilter_passes <= 10:
        raise ConfigError(f"walk: --dynfilter-passes {args.dynfilter_passes} is outside the allowed range [1, 10]")
    single, double = _step_timing(args, "walk")
    settings = WalkSettings(stabilize=not args.no_stabilizer, recover_pushes=not args.no_push_recovery,
                            arms=ArmMotion(args.arms),
                            dynfilter=FilterMode(args.dynfilter), dynfilter_passes=args.dynfilter_passes,
                            dynfilter_worker=not args.dynfilter_inline, base_state=_base_state(args),
                            single_support=single, double_support=double)
    robot, disturbances, hardware = _simulation(args)
    with hardware as hw, _on_the_robot(args, robot, hw, settings.control_dt) as (recorders, pacer):
        report = run_walk(robot, hw, goal, settings, out_dir=args.out, log=_log, progress=not args.quiet,
                          disturbances=disturbances, recorders=recorders, pacer=pacer)
    return _finish(args, report)


def _step_timing(args: argparse.Namespace, command: str) -> tuple[float, float]:
    """``--single-support`` and ``--double-support`` [s]: whole pattern-generator samples (0.1 s)."""
    from robot_ctrl.wpg.params import WalkParams

    sample = WalkParams.sample_time
    for option, value, (lo, hi) in (("--single-support", args.single_support, SINGLE_SUPPORT_RANGE),
                                    ("--double-support", args.double_support, DOUBLE_SUPPORT_RANGE)):
        if not lo <= value <= hi or abs(value / sample - round(value / sample)) > 1e-9:
            raise ConfigError(f"{command}: {option} {value} must be a multiple of {sample:g} s in [{lo:g}, {hi:g}] s")
    return args.single_support, args.double_support


def _drawer(args: argparse.Namespace) -> int:
    from robot_ctrl.hw.drawer_cabinet import DrawerPlacement
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios.drawer import run_drawer
    from robot_ctrl.scenarios.drawer_task import DrawerTask
    from robot_ctrl.scenarios.walk_reach_synthesis import load_demonstrations, load_primitives

    jumps = tuple(_goal_jump(j) for j in args.goal_jump)
    task = DrawerTask(args.distance, args.slot, jumps, FilterMode(args.dynfilter), base_state=_base_state(args))
    _disturbances(args)
    robot = load_robot(args.robot)
    try:  # before anything is learned or started
        demos = load_demonstrations(robot)
        task.check(demos.comfort_distance, min(t.lengths[1] for t in demos.trials))
    except (FileNotFoundError, ValueError) as exc:
        raise ConfigError(f"drawer: {_named(str(exc), _DRAWER_OPTIONS)}") from exc
    primitives = load_primitives(robot)
    args.drawer = DrawerPlacement(task.distance, task.slot, tuple((j.time, j.distance) for j in jumps))
    robot, disturbances, hardware = _simulation(args)
    with hardware as hw, _on_the_robot(args, robot, hw, task.control_dt) as (recorders, pacer):
        report = run_drawer(robot, hw, primitives, task, out_dir=args.out, log=_log, progress=not args.quiet,
                            disturbances=disturbances, recorders=recorders, pacer=pacer)
    if args.out is not None:
        from robot_ctrl.eval.html_report import render_report

        _log(f"wrote {render_report(args.out)}")
    return _finish(args, report)


def _goal_jump(text: str):
    from robot_ctrl.synthesis.synthesizer import GoalJump

    try:
        time, distance = (float(v) for v in text.split(":"))
    except ValueError:
        raise ConfigError(f"--goal-jump {text!r} must be TIME:DISTANCE, two numbers [s]:[m]") from None
    return GoalJump(time, distance)


def _robustness(args: argparse.Namespace) -> int:
    from robot_ctrl.scenarios import robustness

    if not 1 <= args.jobs <= 64:
        raise ConfigError(f"robustness: --jobs {args.jobs} is outside the allowed range [1, 64]")
    single, double = _step_timing(args, "robustness")
    grid = {}
    if args.quick:  # a smoke test of the campaign: two directions, one phase, two magnitudes
        grid = dict(directions=(0, -90), phases=("single_mid",), magnitudes=(0.1, 0.2),
                    mismatch={k: robustness.MISMATCH[k] for k in ("mass ×1.15", "latency 10 ms")})
    robustness.run_robustness(args.out, args.jobs, log=_log, progress=not args.quiet, single=single, double=double,
                              **grid)
    return 0


def _synth_primitives(args: argparse.Namespace):
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios.walk_reach_synthesis import load_primitives

    robot = load_robot(args.robot)
    try:
        return robot, load_primitives(robot, args.dataset)
    except (FileNotFoundError, ValueError) as exc:
        raise ConfigError(f"synth: {exc}") from exc


def _synth(args: argparse.Namespace) -> int:
    from robot_ctrl.scenarios.walk_reach_synthesis import GoalJump, plot_synthesis, run_synthesis, write_synthesis
    from robot_ctrl.synthesis.demonstrations import upper_body_joints
    from robot_ctrl.synthesis.step_planning import MAX_GOAL_DISTANCE
    from robot_ctrl.synthesis.synthesizer import WalkReachGoal

    if not (0 < args.distance <= MAX_GOAL_DISTANCE):  # before the primitives are learned (seconds)
        raise ConfigError(f"synth: --distance {args.distance} m is outside the allowed range (0, {MAX_GOAL_DISTANCE}]")
    robot, primitives = _synth_primitives(args)
    if args.slot not in primitives.slots:
        raise ConfigError(f"synth: --slot {args.slot!r} is not one of {', '.join(primitives.slots)}")
    jump = None
    if args.goal_jump:
        try:
            t, d = (float(v) for v in args.goal_jump.split(":"))
        except ValueError as exc:
            raise ConfigError(f"synth: --goal-jump {args.goal_jump!r} must be TIME:DISTANCE, e.g. 1.0:1.9") from exc
        jump = GoalJump(t, d)
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
    _, primitives = _synth_primitives(args)
    print("action  sources  Q anechoic  Q PCA (same count)  PCA components for the same Q")
    for row in primitives.quality:
        print(f"{row['action']:>6}  {row['sources']:>7}  {row['Q_anechoic']:>10.4f}  {row['Q_pca']:>18.4f}  "
              f"{row['pca_needed']:>29}")
    return 0


def _synth_demos(args: argparse.Namespace) -> int:
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.synthesis.demonstrations import default_dataset_path, generate_demonstrations

    robot = load_robot(args.robot)
    path = args.out or default_dataset_path(robot.name)
    demos = generate_demonstrations(robot)
    path.parent.mkdir(parents=True, exist_ok=True)
    demos.save(path)
    print(f"wrote {len(demos.trials)} demonstrations ({len(demos.channels)} channels, dt {demos.dt} s) to {path}")
    return 0


def _crowd_graph(args: argparse.Namespace):
    import numpy as np

    from robot_ctrl.crowd.coupling_graph import CouplingGraph

    try:
        if args.laplacian:
            return CouplingGraph.from_laplacian(np.loadtxt(args.laplacian, ndmin=2))
        if args.adjacency:
            return CouplingGraph.from_adjacency(np.loadtxt(args.adjacency, ndmin=2))
        return CouplingGraph.named(args.graph, args.n, args.weight)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"crowd: {exc}") from exc


def _crowd_certify(args: argparse.Namespace) -> int:
    import json

    import numpy as np

    from robot_ctrl.crowd.certificates import CouplingConfig, certify

    try:
        g = np.loadtxt(args.g_profile, ndmin=1) if args.g_profile else np.ones(1)
        cfg = CouplingConfig(_crowd_graph(args), k=args.k, alpha=args.alpha, m_d=args.md, m_z=args.mz,
                             m_psi=args.mpsi, k_sine=args.ksine, lowpass=args.lowpass, g=g,
                             heading_spread=np.radians(args.spread_deg))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"crowd certify: {_named(str(exc), _COUPLING_OPTIONS)}") from exc
    conditions = certify(cfg)
    if args.json:
        print(json.dumps([c.to_dict() for c in conditions], indent=2))
    else:
        graph = cfg.graph
        print(f"graph: {graph.topology or 'from file'}, N = {graph.n}, connected: {graph.connected}, "
              f"λ⁺ = {graph.lambda_plus:.6g}, λ_max = {graph.lambda_max:.6g}")
        for c in conditions:
            print(c.line())
    return 0 if all(c.holds for c in conditions) else 1


def _crowd_audit(args: argparse.Namespace) -> int:
    from robot_ctrl.crowd.audit import audit

    if not (1 <= args.graphs <= 100000) or not (2 <= args.min_n <= args.max_n <= 60) or args.seed < 0:
        raise ConfigError(f"crowd audit: --graphs {args.graphs} must be in [1, 100000], 2 <= --min-n "
                          f"{args.min_n} <= --max-n {args.max_n} <= 60 and --seed {args.seed} >= 0")
    print("certificate     holds  exact  certified/worst case: median    min    max  optimistic")
    for name, row in audit(args.graphs, (args.min_n, args.max_n), args.seed).items():
        stats = "  ".join(f"{row[k]:6.3f}" if row[k] is not None else "     -" for k in ("median", "min", "max"))
        print(f"{name:15s} {row['holds']:5d}  {row['exact']:5d}  {' ' * 22}{stats}  {row['optimistic']:10d}")
    return 0


def _crowd_run(args: argparse.Namespace) -> int:
    import numpy as np

    from robot_ctrl.crowd.certificates import refuse_violated
    from robot_ctrl.crowd.experiments import run_group
    from robot_ctrl.crowd.gait_coupling import GaitCoupling
    from robot_ctrl.crowd.gait_profile import GaitProfile
    from robot_ctrl.eval.report_file import write_report

    for option, value, (lo, hi) in (("--duration", args.duration, (1e-3, 3600.0)), ("--runs", args.runs, (1, 10000)),
                                    ("--frequency", args.frequency, (1e-3, 10.0)), ("--speed", args.speed, (1e-3, 10.0))):
        if not lo <= value <= hi:
            raise ConfigError(f"crowd run: {option} {value} is outside the allowed range [{lo:g}, {hi:g}]")
    graph = _crowd_graph(args)
    omega = 2 * np.pi * args.frequency
    try:
        coupling = GaitCoupling(graph, k=args.k, m_d=args.md or 0.0, m_z=args.mz or 0.0, m_psi=args.mpsi or 0.0)
        profile = GaitProfile.load_or_constant(args.profile, omega, args.speed) if args.profile else None
        if args.profile and profile.source.startswith("constant"):
            raise ValueError(f"no measured gait profile for {args.profile!r}: run robot-ctrl crowd gait-profile "
                             f"--robot {args.profile}")
        conditions = coupling.certify(np.ones(1) if profile is None else profile.g, omega, phases="hopf")
        refuse_violated(conditions, args.allow_unstable)
    except ValueError as exc:
        raise ConfigError(f"crowd run: {_named(str(exc), _COUPLING_OPTIONS)}") from exc
    try:
        result = run_group(coupling, duration=args.duration, runs=args.runs, profile=profile, omega=omega)
    except ValueError as exc:
        raise ConfigError(f"crowd run: {exc}") from exc
    for c in result.conditions:
        print(c.line())
    print(f"empirical phase rate {result.empirical_rate} 1/s, final phase spread {result.final_spread:.3g} rad")
    if result.position_error is not None:
        print(f"empirical position rate {result.position_rate} 1/s, final position error "
              f"{result.position_error[-1]:.3g} m")
    if result.heading_error is not None:
        print(f"empirical heading rate {result.heading_rate} 1/s, final heading error {result.heading_error[-1]:.3g} rad")
    report = result.report()
    report.update(graph=graph.topology or "from file", n=graph.n, k=args.k, m_d=args.md, m_z=args.mz, m_psi=args.mpsi,
                  gait_frequency_hz=args.frequency, gait_profile=None if profile is None else profile.source,
                  duration_s=args.duration, runs=args.runs)
    write_report(report, args.out)
    if args.out is not None:
        _plot_dispersion(result, args.out / "dispersion.png", f"{graph.topology or 'graph'} N={graph.n} k={args.k}")
    return 0


def _plot_dispersion(result, path: Path, title: str) -> None:
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogy(result.times, result.dispersion, label="mean angular dispersion R̂")
    if result.position_error is not None:
        ax.semilogy(result.times, result.position_error, label="position error ‖z − o − mean‖ [m]")
    if result.heading_error is not None:
        ax.semilogy(result.times, result.heading_error, label="heading error ‖ψ − mean‖ [rad]")
    rate = next((c.rate for c in result.conditions if c.name == "hopf_diffusive"), None)
    if rate is not None:
        ax.semilogy(result.times, result.dispersion[0] * np.exp(-rate * result.times), "--",
                    label=f"certified rate {rate:.3g} 1/s")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("R̂")
    ax.set_ylim(1e-8, 1.5)
    ax.set_title(title)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"wrote {path}")


def _crowd_figure(args: argparse.Namespace) -> int:
    import json

    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from robot_ctrl.crowd.experiments import rate_slopes

    if not 1 <= args.runs <= 1000:
        raise ConfigError(f"crowd figure: --runs {args.runs} is outside the allowed range [1, 1000]")
    data = rate_slopes(runs=args.runs)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "slopes.json").write_text(json.dumps(data, indent=2) + "\n")
    fig, (ax_a, ax_b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for topology, marker in (("all", "o"), ("ring", "s"), ("chain", "^"), ("star", "d")):
        rows = [v for v in data.values() if v["topology"] == topology]
        row = next(v for v in rows if v["n"] == 5)
        ax_a.plot(row["k"], row["rates"], marker, label=f"{topology}, N = 5 (simulated)")
        ax_a.plot(row["k"], [k * row["lambda_plus"] for k in row["k"]], "k:", lw=0.8)
        ns = [v["n"] for v in rows]
        ax_b.plot(ns, [v["slope"] for v in rows], marker, ms=9, mfc="none", label=f"{topology} (simulated)")
        ax_b.plot(ns, [v["theory_slope"] for v in rows], "--", label=f"{topology}: λ⁺ (theory)")
    ax_a.set_xlabel("coupling strength k")
    ax_a.set_ylabel("empirical rate λ [1/s]")
    ax_a.set_title("a) rate vs coupling (dotted: k λ⁺)")
    ax_a.legend(fontsize=8)
    ax_b.set_xscale("log")
    ax_b.set_yscale("log")
    ax_b.set_xticks(sorted({v["n"] for v in data.values()}))
    ax_b.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax_b.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax_b.set_xlabel("number of oscillators N")
    ax_b.set_ylabel("slope dλ/dk")
    ax_b.set_title("b) slope vs N (thesis Fig. 4.6)")
    ax_b.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(args.out / "fig_4_6.png", dpi=120)
    worst = max(abs(v["slope"] - v["theory_slope"]) / v["theory_slope"] for v in data.values())
    print(f"wrote {args.out / 'fig_4_6.png'} and slopes.json; largest slope deviation from λ⁺: {worst:.1%}")
    return 0


def _crowd_walk(args: argparse.Namespace) -> int:
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios.group_walk import GroupWalk, run_group_walk

    if HardwareKind.parse(args.hw).real:
        raise ConfigError(f"crowd walk: a group walks in one simulated world, not on real servos (--hw {args.hw})")
    _check_outputs(args)
    disturbances = _disturbances(args)
    robot = load_robot(args.robot)
    try:
        group = GroupWalk(n=args.robots, graph=args.graph, k=args.k, m_z=args.mz, m_psi=args.mpsi, speed=args.speed,
                          spacing=args.spacing, coupled_time=args.coupled_time, seed=args.seed,
                          allow_unstable=args.allow_unstable)
        report = run_group_walk(robot, group, args.hw, out_dir=args.out, viewer=args.viewer, video=args.video,
                                log=_log, progress=not args.quiet, disturbances=disturbances)
    except ValueError as exc:
        raise ConfigError(f"crowd walk: {_named(str(exc), _GROUP_OPTIONS)}") from exc
    return _finish(args, report)


def _crowd_gait_profile(args: argparse.Namespace) -> int:
    from robot_ctrl.crowd.gait_profile import MODELS
    from robot_ctrl.scenarios.gait_profile import measure_gait_profile

    if not (0.05 <= args.speed <= 0.3) or not (2 <= args.cycles <= 50):
        raise ConfigError(f"crowd gait-profile: --speed {args.speed} must be in [0.05, 0.3] m/s and --cycles "
                          f"{args.cycles} in [2, 50]")
    if HardwareKind.parse(args.hw).real:
        raise ConfigError(f"crowd gait-profile measures a simulated robot's gait, not real servos (--hw {args.hw})")
    robot, _, hardware = _simulation(args)
    out = args.out or MODELS / f"{robot.name}_gait_profile.json"
    with hardware as hw:
        measure_gait_profile(robot, hw, speed=args.speed, cycles=args.cycles, out=out, log=_log,
                             progress=not args.quiet)
    if args.video is not None:
        _log(f"wrote {args.video}")
    return 0


def _report(args: argparse.Namespace) -> int:
    from robot_ctrl.eval.html_report import render_report

    try:
        path = render_report(args.dir)
    except FileNotFoundError as exc:
        raise ConfigError(f"report: {exc}") from exc
    print(f"wrote {path}")
    return 0


def _robots(args: argparse.Namespace) -> int:
    from robot_ctrl.robot.model import load_robot

    for name in available_robots():
        robot = load_robot(name)
        print(f"{name}: {robot.nj} joints, {robot.mass:.2f} kg, URDF {robot.files.urdf}")
        if args.convert:
            print(f"  MJCF: {robot.mjcf_path}")
    return 0


def _robot_parent() -> argparse.ArgumentParser:
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument("--robot", default="talos", help=f"robot config name ({', '.join(available_robots())})")
    return parent


def _simulation_parent(robot: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Options of every MuJoCo scenario."""
    parent = argparse.ArgumentParser(add_help=False, parents=[robot])
    parent.add_argument("--hw", choices=[k.value for k in HardwareKind], default=HardwareKind.MUJOCO.value,
                        help="backend, always behind the safety layer: MuJoCo, MuJoCo behind an emulated MIT-CAN / "
                             "Dynamixel servo bus, or real servos (mit-can, dynamixel: the start sequence first, "
                             "then the scenario on the estimated base; docs/hardware.md)")
    parent.add_argument("--bus-config", help="bus mapping (configs/hw name or YAML path); required for real servos")
    parent.add_argument("--viewer", action="store_true", help="open the MuJoCo viewer (needs a display)")
    parent.add_argument("--video", type=Path, metavar="FILE.mp4",
                        help="record the run at 30 fps (MuJoCo offscreen renderer; MUJOCO_GL=egl when there is no display)")
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


def _disturbances(args: argparse.Namespace):
    from robot_ctrl.hw.disturbances import Disturbances, Push

    try:
        dist = Disturbances(tuple(Push.parse(p) for p in args.push), args.mass_scale, args.friction_scale,
                            args.latency_ms / 1e3, args.sensor_noise, reply_loss=args.reply_loss)
        dist.latency_ticks(0.005)
    except ValueError as exc:
        raise ConfigError(_named(str(exc), _DISTURBANCE_OPTIONS)) from exc
    if dist.reply_loss and args.hw != HardwareKind.MIT_CAN_EMULATED.value:
        raise ConfigError(f"--reply-loss acts on the emulated MIT-CAN bus (--hw mit-can-emulated), not on --hw {args.hw}")
    return dist


def _add_balance(sub, sim) -> None:
    p = sub.add_parser("balance", parents=[sim], help="stand, shift weight, lift a foot, reach with the right hand",
                       description="Balance demo at 200 Hz control: half-sitting, CoM over the left foot, right foot "
                                   "up 5 cm and back, CoM back, right-hand reach to (0.4, -0.2, 0.8) m in the start "
                                   "floor frame and back. Exit status 1 if the robot fell.")
    _base_state_arg(p)
    p.add_argument("--out", type=Path, help="write DIR/report.json")
    _log_arg(p)
    p.set_defaults(run=_balance)


def _add_walk(sub, sim) -> None:
    p = sub.add_parser("walk", parents=[sim], help="walk a path with the MPC walking controller",
                       description="Walk straight (--distance), along an arc (--distance with --turn-deg) or "
                                   "sideways (--lateral), stop in double support and stand 2 s. Exit status 1 if "
                                   "the robot fell.")
    p.add_argument("--distance", type=float, default=0.0, help="path length forward [m] (arc length when turning)")
    p.add_argument("--turn-deg", type=float, default=0.0, help="heading change over the path [deg], + left")
    p.add_argument("--lateral", type=float, default=0.0, help="side-step distance [m], + left, - right")
    p.add_argument("--speed", type=float, default=0.25, help="walking speed [m/s], 0.02..0.5")
    p.add_argument("--no-stabilizer", action="store_true", help="open loop: no DCM/ZMP balance feedback")
    p.add_argument("--no-push-recovery", action="store_true",
                   help="the plan does not take up a pushed DCM (its footsteps do not follow a push)")
    p.add_argument("--arms", choices=[m.value for m in ArmMotion], default=ArmMotion.NONE.value,
                   help="upper body: half-sitting, or both elbows swinging ±0.5 rad at 1 Hz")
    p.add_argument("--dynfilter", choices=[m.value for m in FilterMode], default=FilterMode.OFF.value,
                   help="dynamic filter: off, legs only (upper body frozen in its preview) or full body")
    p.add_argument("--dynfilter-passes", type=int, default=2, help="filter passes per WPG sample (1..10)")
    p.add_argument("--dynfilter-inline", action="store_true",
                   help="run the filter in the control loop, its correction applied in the sample it was "
                        "computed for (default: in a worker process on another core, one 0.1 s sample behind)")
    _step_timing_args(p)
    _base_state_arg(p)
    p.add_argument("--out", type=Path, help="write DIR/report.json and DIR/timeseries.npz")
    _log_arg(p)
    p.set_defaults(run=_walk)


def _step_timing_args(p) -> None:
    from robot_ctrl.wpg.params import WalkParams

    p.add_argument("--single-support", type=float, default=WalkParams.single_support,
                   help="single-support time of each step [s], a multiple of 0.1 in "
                        f"[{SINGLE_SUPPORT_RANGE[0]:g}, {SINGLE_SUPPORT_RANGE[1]:g}]: shorter steps catch pushes sooner")
    p.add_argument("--double-support", type=float, default=WalkParams.double_support,
                   help="double-support time between steps [s], a multiple of 0.1 in "
                        f"[{DOUBLE_SUPPORT_RANGE[0]:g}, {DOUBLE_SUPPORT_RANGE[1]:g}]")


def _add_drawer(sub, sim) -> None:
    p = sub.add_parser("drawer", parents=[sim], help="walk to a drawer, pull it open, reach the object (headline task)",
                       description="The walk-and-reach task in MuJoCo: the learned synthesis drives the MPC walking "
                                   "controller to a chest of drawers at --distance, the left hand pulls the drawer "
                                   "open and the right hand reaches the object in --slot; report.json says whether "
                                   "every criterion was met (success). Exit status 1 if the robot fell.")
    p.add_argument("--distance", type=float, default=2.0, help="drawer front panel from the start pelvis [m]")
    p.add_argument("--slot", default="front_left", help="object slot: front_left, front_right, back_left, back_right")
    p.add_argument("--goal-jump", action="append", default=[], metavar="TIME:DISTANCE",
                   help="at TIME [s] the cabinet moves to DISTANCE [m]; the synthesis replans (repeatable)")
    p.add_argument("--dynfilter", choices=[m.value for m in FilterMode], default=FilterMode.FULL.value,
                   help="dynamic filter: off, legs only, or full body (default)")
    _base_state_arg(p)
    p.add_argument("--out", type=Path, help="write DIR/report.json, DIR/timeseries.npz and DIR/report.html")
    _log_arg(p)
    p.set_defaults(run=_drawer)


def _log_arg(p) -> None:
    p.add_argument("--log", type=Path, metavar="FILE",
                   help="write a per-tick binary log (state, command, safety, bus, timing); robot-ctrl log FILE "
                        "turns it into a report")


def _base_state_arg(p) -> None:
    p.add_argument("--base-state", choices=[m.value for m in BaseState],
                   help="the controller's base pose and velocity: the simulator's (default in simulation), or "
                        "estimated from the IMU, the encoders and the foot force sensors (control/base_estimator.py; "
                        "the only one on real servos)")


def _graph_args(p) -> None:
    p.add_argument("--graph", choices=("all", "ring", "chain", "star"), default="all", help="named topology")
    p.add_argument("--n", type=int, default=8, help="number of agents (named topologies)")
    p.add_argument("--weight", type=float, default=1.0, help="link weight of the named topology (> 0)")
    p.add_argument("--laplacian", type=Path, help="Laplacian matrix as a text file (any graph)")
    p.add_argument("--adjacency", type=Path, help="adjacency (link weight) matrix as a text file")


def _add_crowd_certify(sub) -> None:
    p = sub.add_parser("certify", help="check the contraction conditions of a coupling configuration",
                       description="Prints each applicable sufficient condition with holds/violated, its margin "
                                   "and the guaranteed convergence rate. Exit status 1 if any is violated.")
    _graph_args(p)
    p.add_argument("--k", type=float, help="phase / state coupling strength")
    p.add_argument("--alpha", type=float, help="leader coupling strength")
    p.add_argument("--md", type=float, help="step-frequency (distance) coupling m_d")
    p.add_argument("--mz", type=float, help="step-length coupling m_z")
    p.add_argument("--mpsi", type=float, help="heading coupling m_psi")
    p.add_argument("--ksine", type=float, help="sine (Schoener-Dose) coupling of headings or phases, eq. 4.45")
    p.add_argument("--spread-deg", type=float, default=45.0,
                   help="largest angle difference the heading / sine certificates cover [deg], < 90")
    p.add_argument("--lowpass", type=float, help="position low-pass filter constant (with --md)")
    p.add_argument("--g-profile", type=Path, help="speed profile g(phi) samples over a cycle (text file)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(run=_crowd_certify)


def _add_crowd_audit(sub) -> None:
    p = sub.add_parser("audit", help="compare the certificates with brute-force worst cases on random graphs",
                             description="Random connected weighted graphs (symmetric and not): each certified rate "
                                         "against the exhaustive worst case (step frequency and length, N <= 12) or "
                                         "sampled worst cases; prints certified/worst-case ratios (1 = exact).")
    p.add_argument("--graphs", type=int, default=1000, help="random graphs")
    p.add_argument("--min-n", type=int, default=2, help="smallest group")
    p.add_argument("--max-n", type=int, default=12, help="largest group")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.set_defaults(run=_crowd_audit)


def _add_crowd_run(sub) -> None:
    p = sub.add_parser("run", help="simulate coupled Andronov-Hopf gait oscillators (kinematic)",
                       description="Simulates the group from random initial states, writes DIR/report.json "
                                   "(certificate, empirical rate, final phase spread) and DIR/dispersion.png.")
    _graph_args(p)
    p.add_argument("--k", type=float, required=True, help="phase (oscillator state) coupling strength [1/s]")
    p.add_argument("--md", type=float, help="step-frequency coupling m_d [rad/(s m)]")
    p.add_argument("--mz", type=float, help="step-length coupling m_z [1/m]")
    p.add_argument("--mpsi", type=float, help="heading consensus m_psi [1/s]")
    p.add_argument("--frequency", type=float, default=1.0, help="gait frequency [Hz] (one cycle = two steps)")
    p.add_argument("--profile", help="use the measured gait profile g(phi) of this robot (e.g. talos)")
    p.add_argument("--speed", type=float, default=1.0, help="mean walking speed with --profile [m/s]")
    p.add_argument("--duration", type=float, default=30.0, help="simulated time [s]")
    p.add_argument("--runs", type=int, default=100, help="random initial conditions averaged")
    p.add_argument("--allow-unstable", action="store_true", help="simulate even if the certificate is violated")
    p.add_argument("--out", type=Path, help="output folder")
    p.set_defaults(run=_crowd_run)


def _add_crowd_walk(sub, sim) -> None:
    p = sub.add_parser("walk", parents=[sim], help="robots walking side by side with coupled gaits (MuJoCo)",
                       description="N robots in one MuJoCo world, each with its own walking controller, start at "
                                   "random step phases and walk abreast along +x; step phase (k), step length "
                                   "(m_z) and heading (m_psi) are coupled through the gait bridge. Writes "
                                   "DIR/report.json and DIR/phases.png. Exit status 1 if a robot fell.")
    p.add_argument("--robots", type=int, default=3, help="number of robots, 2..8")
    p.add_argument("--graph", choices=("all", "ring", "chain", "star"), default="all", help="coupling topology")
    p.add_argument("--k", type=float, default=1.0, help="step-phase coupling k [1/s]")
    p.add_argument("--mz", type=float, default=1.0, help="step-length coupling m_z [1/m]")
    p.add_argument("--mpsi", type=float, default=0.5, help="heading consensus m_psi [1/s]")
    p.add_argument("--speed", type=float, default=0.2, help="nominal walking speed [m/s], 0.05..0.3")
    p.add_argument("--spacing", type=float, default=1.2, help="lateral distance between robots [m]")
    p.add_argument("--coupled-time", type=float, default=10.0, help="walking time with the coupling on [s]")
    p.add_argument("--seed", type=int, default=0, help="seed of the random start phases")
    p.add_argument("--allow-unstable", action="store_true", help="run even if the certificate is violated")
    p.add_argument("--out", type=Path, help="output folder")
    p.set_defaults(run=_crowd_walk)


def _add_crowd_gait_profile(sub, sim) -> None:
    p = sub.add_parser("gait-profile", parents=[sim], help="measure the gait's speed profile g(phi) in MuJoCo",
                       description="Walks straight and bins the measured CoM forward speed over the gait phase; "
                                   "the crowd certificates and simulations use it.")
    p.add_argument("--speed", type=float, default=0.2, help="walking speed [m/s], 0.05..0.3")
    p.add_argument("--cycles", type=int, default=6, help="gait cycles averaged, 2..50")
    p.add_argument("--out", type=Path, help="output JSON (default models/<robot>_gait_profile.json)")
    p.set_defaults(run=_crowd_gait_profile)


def _add_crowd(sub, sim) -> None:
    crowd = sub.add_parser("crowd", help="coupled gaits: contraction certificates and crowd simulation")
    crowd_sub = crowd.add_subparsers(dest="crowd_command", required=True)
    _add_crowd_certify(crowd_sub)
    _add_crowd_audit(crowd_sub)
    _add_crowd_run(crowd_sub)
    p = crowd_sub.add_parser("figure", help="reproduce thesis Fig. 4.6 (rate vs k, slope vs N)")
    p.add_argument("--runs", type=int, default=30, help="random initial conditions per point")
    p.add_argument("--out", type=Path, default=Path("runs/fig_4_6"), help="output folder")
    p.set_defaults(run=_crowd_figure)
    _add_crowd_walk(crowd_sub, sim)
    _add_crowd_gait_profile(crowd_sub, sim)


def _add_synth(sub, robot) -> None:
    data = argparse.ArgumentParser(add_help=False, parents=[robot])
    data.add_argument("--dataset", type=Path, default=None,
                      help="demonstration set (default: models/<robot>_walk_reach_demos.npz)")
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
                       description="Learns the stepwise anechoic model (s0 + 3 periodic sources for action 1, 2 more "
                                   "for actions 2 and 3) and prints Q = 1 - |X - X^|^2/|X|^2 per action next to PCA "
                                   "with the same number of sources.")
    p.set_defaults(run=_synth_quality)
    p = sub.add_parser("synth-demos", parents=[robot], help="generate the walk-and-reach demonstration set (IK)")
    p.add_argument("--out", type=Path, default=None, help="output .npz (default: models/<robot>_walk_reach_demos.npz)")
    p.set_defaults(run=_synth_demos)


def _add_robustness(sub) -> None:
    p = sub.add_parser("robustness", help="campaign of pushed and mismatched walks (MuJoCo, in parallel)",
                       description="The 3 m walk at 0.25 m/s pushed in 8 directions at 4 gait phases with growing "
                                   "impulses (0.1..0.5 N·s/kg) until it falls, and under mass, friction and latency "
                                   "mismatch; writes DIR/robustness.json and DIR/robustness.html, and each walk's "
                                   "report under DIR.")
    p.add_argument("--out", type=Path, default=Path("runs/robustness"), help="output folder")
    p.add_argument("--jobs", type=int, default=2, help="walks run at a time, 1..64")
    p.add_argument("--quick", action="store_true", help="a small grid (2 directions, 1 phase, 2 magnitudes)")
    _step_timing_args(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=_robustness)


def _add_tools(sub) -> None:
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


def _add_hw(sub, robot) -> None:
    p = sub.add_parser("hw", parents=[robot], help="bring up real or emulated servos: scan, read, check, stand, jog, zero",
                       description="One bring-up step at a time (docs/hardware.md): scan (every motor answers), read "
                                   "(joints against limits, motors off), check (scan + a posture stand may start "
                                   "from), stand (minimum-jerk move to half-sitting at reduced gains, faulting on "
                                   "tracking error), jog JOINT DELTA (one joint by DELTA rad), zero JOINT (a drive's "
                                   "encoder zero). Exit status 3 on a hardware fault; the servos end in damping, "
                                   "disabled.")
    p.add_argument("action", choices=["scan", "read", "check", "stand", "jog", "zero"])
    p.add_argument("joint", nargs="?", help="jog, zero: the joint")
    p.add_argument("delta", nargs="?", type=float, help="jog: the angle to move by [rad]")
    p.add_argument("--hw", choices=[k.value for k in HardwareKind], default=HardwareKind.MIT_CAN_EMULATED.value,
                   help="servos: real (mit-can, dynamixel: the interfaces in --bus-config) or emulated")
    p.add_argument("--bus-config", help="bus mapping (configs/hw name or YAML path); required for real servos")
    p.add_argument("--duration", type=float, default=4.0, help="stand, jog: the move's duration [s], 0.5..60")
    p.add_argument("--gain-scale", type=float, default=0.3, help="stand, jog: share of the servo stiffness, 0.01..1")
    _log_arg(p)
    p.set_defaults(run=_hw)


def _hw(args: argparse.Namespace) -> int:
    from robot_ctrl.control.start_sequence import StartParams
    from robot_ctrl.hw.hardware import open_hardware
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
        raise ConfigError(_named(str(exc).replace("StartParams.", ""), {"duration": "--duration",
                                                                        "gain_scale": "--gain-scale"})) from exc
    _check_log_path(args)
    kind = HardwareKind.parse(args.hw)
    if args.action == "zero" and kind not in (HardwareKind.MIT_CAN, HardwareKind.MIT_CAN_EMULATED):
        raise ConfigError(f"hw zero sets an MIT drive's encoder zero; with --hw {kind.value} put the joint's "
                          "zero_offset in the bus config instead (docs/hardware.md, Bring-up)")
    with open_hardware(kind, robot, args.bus_config) as hw:
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
            pacer = _real_servo_pacer(kind, params.control_dt)
            with _tick_log(args, robot, hw, params.control_dt, pacer) as recorders:
                result = bringup.move(robot, hw, target, params, pacer, recorders)
    for key, value in result.items():
        print(f"{key}: {value}")
    return 0 if result.get("reached", True) else 3


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="robot-ctrl", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    robot = _robot_parent()
    sim = _simulation_parent(robot)
    _add_balance(sub, sim)
    _add_walk(sub, sim)
    _add_drawer(sub, sim)
    _add_crowd(sub, sim)
    _add_robustness(sub)
    _add_synth(sub, robot)
    _add_hw(sub, robot)
    _add_tools(sub)
    return parser


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def main(argv: list[str] | None = None) -> int:
    """Exit status: 0 done, 1 the robot fell, 2 bad input, 3 a hardware fault, 130 interrupted
    (Ctrl-C or SIGTERM: the hardware is closed on the way out, damping then disable)."""
    from robot_ctrl.hw.adapter import HardwareFault

    args = build_parser().parse_args(argv)
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
        print(f"robot-ctrl: interrupted{f' ({exc})' if str(exc) else ''}", file=sys.stderr)
        return 130
    finally:
        if in_main_thread:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
