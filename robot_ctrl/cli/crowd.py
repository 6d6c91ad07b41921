"""``robot-ctrl crowd ...``: contraction certificates, their audit, kinematic crowds, the thesis's
Fig. 4.6, coupled walks in MuJoCo and the gait profile."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from robot_ctrl.cli.options import COUPLING_OPTIONS, GROUP_OPTIONS, check_outputs, check_ranges, log_line, named
from robot_ctrl.cli.simulation import finish, parse_disturbances, simulation, video_request
from robot_ctrl.modes import HardwareKind
from robot_ctrl.robot.config import ConfigError


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

    gains = {"--k": args.k, "--alpha": args.alpha, "--md": args.md, "--mz": args.mz, "--mpsi": args.mpsi,
             "--ksine": args.ksine}
    if all(v is None for v in gains.values()):
        raise ConfigError(f"crowd certify: give at least one coupling gain ({', '.join(gains)})")
    if args.lowpass is not None and args.md is None:
        raise ConfigError("crowd certify: --lowpass is the step-frequency coupling's position filter: it needs --md")
    try:
        g = np.loadtxt(args.g_profile, ndmin=1) if args.g_profile else np.ones(1)
        cfg = CouplingConfig(_crowd_graph(args), k=args.k, alpha=args.alpha, m_d=args.md, m_z=args.mz,
                             m_psi=args.mpsi, k_sine=args.ksine, lowpass=args.lowpass, g=g,
                             heading_spread=np.radians(args.spread_deg))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"crowd certify: {named(str(exc), COUPLING_OPTIONS)}") from exc
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

    check_ranges("crowd audit", args)
    if args.min_n > args.max_n:
        raise ConfigError(f"crowd audit: --min-n {args.min_n} must not exceed --max-n {args.max_n}")
    print("certificate     holds  contracting  exact  certified/worst case: median    min    max  optimistic")
    for name, row in audit(args.graphs, (args.min_n, args.max_n), args.seed).items():
        stats = "  ".join(f"{row[k]:6.3f}" if row[k] is not None else "     -" for k in ("median", "min", "max"))
        print(f"{name:15s} {row['holds']:5d}  {row['contracting']:11d}  {row['exact']:5d}  {' ' * 22}{stats}  "
              f"{row['optimistic']:10d}")
    return 0


def _crowd_run(args: argparse.Namespace) -> int:
    import numpy as np

    from robot_ctrl.crowd.certificates import refuse_violated
    from robot_ctrl.crowd.experiments import CrowdDiverged, run_group
    from robot_ctrl.crowd.gait_coupling import GaitCoupling
    from robot_ctrl.crowd.gait_profile import GaitProfile
    from robot_ctrl.eval.recording.report_file import write_report
    from robot_ctrl.eval.reports.crowd_figures import plot_dispersion

    check_ranges("crowd run", args)
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
        raise ConfigError(f"crowd run: {named(str(exc), COUPLING_OPTIONS)}") from exc
    try:
        result = run_group(coupling, duration=args.duration, runs=args.runs, profile=profile, omega=omega)
    except CrowdDiverged as exc:
        print(f"crowd run: {exc}", file=sys.stderr)
        return 1
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
        title = f"{graph.topology or 'graph'} N={graph.n} k={args.k}"
        path = plot_dispersion(result, args.out / "dispersion.png", title)
        print(f"wrote {path}")
    return 0


def _crowd_figure(args: argparse.Namespace) -> int:
    import json

    from robot_ctrl.crowd.experiments import rate_slopes
    from robot_ctrl.eval.reports.crowd_figures import plot_rate_slopes

    check_ranges("crowd figure", args)
    data = rate_slopes(runs=args.runs)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "slopes.json").write_text(json.dumps(data, indent=2) + "\n")
    path = plot_rate_slopes(data, args.out / "fig_4_6.png")
    worst = max(abs(v["slope"] - v["theory_slope"]) / v["theory_slope"] for v in data.values())
    print(f"wrote {path} and slopes.json; largest slope deviation from λ⁺: {worst:.1%}")
    return 0


def _crowd_walk(args: argparse.Namespace) -> int:
    from robot_ctrl.robot.model import load_robot
    from robot_ctrl.scenarios.group_walk import GroupWalk, run_group_walk

    if HardwareKind.parse(args.hw).real:
        raise ConfigError(f"crowd walk: a group walks in one simulated world, not on real servos (--hw {args.hw})")
    check_outputs(args)
    disturbances = parse_disturbances(args)
    robot = load_robot(args.robot)
    try:
        group = GroupWalk(n=args.robots, graph=args.graph, k=args.k, m_z=args.mz, m_psi=args.mpsi, speed=args.speed,
                          spacing=args.spacing, coupled_time=args.coupled_time, seed=args.seed,
                          allow_unstable=args.allow_unstable)
        report = run_group_walk(robot, group, args.hw, out_dir=args.out, viewer=args.viewer, video=video_request(args),
                                log=log_line, progress=not args.quiet, disturbances=disturbances)
    except ValueError as exc:
        raise ConfigError(f"crowd walk: {named(str(exc), GROUP_OPTIONS)}") from exc
    return finish(args, report)


def _crowd_gait_profile(args: argparse.Namespace) -> int:
    from robot_ctrl.crowd.gait_profile import MODELS
    from robot_ctrl.scenarios.gait_profile_walk import measure_gait_profile

    check_ranges("crowd gait-profile", args)
    if HardwareKind.parse(args.hw).real:
        raise ConfigError(f"crowd gait-profile measures a simulated robot's gait, not real servos (--hw {args.hw})")
    robot, _, hardware = simulation(args)
    out = args.out or MODELS / f"{robot.name}_gait_profile.json"
    with hardware as hw:
        measure_gait_profile(robot, hw, speed=args.speed, cycles=args.cycles, out=out, log=log_line,
                             progress=not args.quiet)
    if args.video is not None:
        log_line(f"wrote {args.video}")
    return 0


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


def add_parsers(sub, sim) -> None:
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
