"""Walking MPC solve time for Talos, and placo's WalkPatternGenerator on the same robot and walk.

Ours: the walking pattern generator re-solves its MPC (16 samples of 0.1 s, two free footsteps)
every 0.1 s over a 3 m walk at 0.25 m/s started from standing; we time ``WalkingMPC.solve``
(QP assembly + daqp solve) and the whole ``update`` (horizon construction included).

placo (optional ``bench`` extra): same timing (0.7 s single support, 0.1 s double support,
0.1 s planning step, 1.6 s planned ahead, CoM height, sole size, feet spacing), 15 steps of
0.2 m; we time one ``plan`` of the whole walk and the ``replan`` every 0.1 s during it (the
call placo's own walking loop makes). The two take turns (:func:`in_turns`: our walk five times,
placo's replans between them), so that the machine's swings fall on both. placo needs frames
named ``left_foot``, ``right_foot`` and ``trunk``: a temporary copy of the Talos URDF with those
fixed frames added is written to a temporary folder at run time (nothing is committed).

``--solvers`` also times the CasADi QP plugins on the same walk (how daqp was chosen, and what
CasADi's interface to it costs over calling it directly).
Run: ``python benchmarks/bench_wpg.py [--solvers]``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from robot_ctrl.robot import load_robot
from robot_ctrl.robot.description import resolve_package_uris
from robot_ctrl.wpg.footstep import Footstep
from robot_ctrl.wpg.generator import WalkingPatternGenerator
from robot_ctrl.wpg.mpc import MpcInfeasible
from robot_ctrl.wpg.params import WalkParams


def stats_ms(samples) -> tuple[float, float]:
    ms = np.asarray(samples) * 1e3
    return float(np.median(ms)), float(np.percentile(ms, 99))


def our_walk(params: WalkParams, distance: float = 3.0, speed: float = 0.25):
    """Our generator started from standing, and its next update's wall time [s] (None once it has
    walked ``distance``)."""
    gen = WalkingPatternGenerator(params, Footstep("left", 0.0, params.step_width / 2, 0.0),
                                  Footstep("right", 0.0, -params.step_width / 2, 0.0), np.zeros(2))
    gen.set_velocity(speed, 0.0, 0.0)

    def update() -> float | None:
        if gen.com_x[0] >= distance:
            return None
        t0 = time.perf_counter()
        gen.update()
        return time.perf_counter() - t0

    return gen, update


def run_ours(params: WalkParams, distance: float = 3.0):
    """A whole walk: the MPC's solve times and the updates' wall times [s]."""
    gen, update = our_walk(params, distance)
    updates = list(iter(update, None))
    return gen.solve_times, updates


def placo_urdf(robot, folder: Path) -> Path:
    """Talos URDF with placo's frame names (left_foot, right_foot, trunk) as extra fixed links."""
    text = resolve_package_uris(robot.files.urdf.read_text())
    extra = ""
    for name, parent in (("left_foot", robot.config.feet["left"]), ("right_foot", robot.config.feet["right"]),
                         ("trunk", robot.config.waist)):
        extra += (f'<link name="{name}"/><joint name="{name}_frame" type="fixed"><parent link="{parent}"/>'
                  f'<child link="{name}"/><origin xyz="0 0 0" rpy="0 0 0"/></joint>')
    path = folder / "talos_placo.urdf"
    path.write_text(text.replace("</robot>", extra + "</robot>"))
    return path


def placo_walk(robot, params: WalkParams, distance: float = 3.0, step: float = 0.2):
    """placo's generator with the whole walk planned (each of 5 plans timed), and its next replan's
    wall time [s] (None at the planned end)."""
    import placo

    with tempfile.TemporaryDirectory() as folder:
        humanoid = placo.HumanoidRobot(str(placo_urdf(robot, Path(folder))))
    p = placo.HumanoidParameters()
    p.single_support_duration = params.single_support
    p.single_support_timesteps = round(params.single_support / params.sample_time)
    p.double_support_ratio = params.double_support / params.single_support
    p.startend_double_support_ratio = params.start_transfer / params.single_support
    p.planned_timesteps = params.horizon
    p.walk_com_height = params.com_height
    p.walk_foot_height = params.swing_apex
    p.foot_length, p.foot_width = params.foot_length, params.foot_width
    p.feet_spacing = params.step_width
    p.zmp_margin = params.zmp_margin
    p.walk_max_dx_forward = params.reach_x[1]
    wpg = placo.WalkPatternGenerator(humanoid, p)
    planner = placo.FootstepsPlannerRepetitive(p)
    planner.configure(step, 0.0, 0.0, round(distance / step))
    left, right = np.eye(4), np.eye(4)
    left[1, 3], right[1, 3] = params.step_width / 2, -params.step_width / 2
    footsteps = planner.plan(placo.HumanoidRobot_Side.left, left, right)
    supports = placo.FootstepsPlanner.make_supports(footsteps, 0.0, True, p.has_double_support(), True)
    com = np.array([0.0, 0.0, params.com_height])
    plans = []
    for _ in range(5):
        t0 = time.perf_counter()
        trajectory = wpg.plan(supports, com, 0.0)
        plans.append(time.perf_counter() - t0)
    # A replan with the repetitive planner extends the walk: stop at the planned end.
    state = {"t": params.sample_time, "last": 0.0, "trajectory": trajectory, "end": trajectory.t_end}

    def replan() -> float | None:
        while state["t"] < state["end"] - params.sample_time:
            t = state["t"]
            state["t"] += params.sample_time
            if wpg.can_replan_supports(state["trajectory"], t):
                t0 = time.perf_counter()
                supports = wpg.replan_supports(planner, state["trajectory"], t, state["last"])
                state["trajectory"] = wpg.replan(supports, state["trajectory"], t)
                state["last"] = t
                return time.perf_counter() - t0
        return None

    return plans, replan


WALKS = 5


def in_turns(robot, params: WalkParams) -> tuple[list[float], list[float], list[float], list[float]]:
    """``WALKS`` of our 3 m walks, each followed by its share of placo's replans over its one walk:
    a burst of the machine's load then falls on both, and each runs long enough to keep its own
    caches (one call of each in turn left our update cold after placo's much larger replan). Our
    solve and update times, placo's plan and replan times [s]."""
    solves, updates, replans = [], [], []
    plans, replan = placo_walk(robot, params)
    share = None
    for _ in range(WALKS):
        gen, update = our_walk(params)
        updates += list(iter(update, None))
        solves += gen.solve_times
        share = share or -(-len(gen.solve_times) // WALKS)  # placo's replans are about as many as our updates
        replans += [r for r in (replan() for _ in range(share)) if r is not None]
    return solves, updates, plans, replans + list(iter(replan, None))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--solvers", action="store_true", help="also time the CasADi QP plugins")
    parser.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    args = parser.parse_args()
    robot = load_robot("talos")
    params = WalkParams(com_height=0.88, step_width=0.17, foot_length=robot.config.foot.length,
                        foot_width=robot.config.foot.width)
    run_ours(params, 0.5)  # warm-up
    try:
        import placo  # noqa: F401
    except ImportError as exc:
        placo_missing = f"placo does not import ({exc}; make bench, or pip install -e '.[bench]'): no comparison"
        (solves, updates), plans, replans = run_ours(params), None, None
    else:
        placo_missing = None
        solves, updates, plans, replans = in_turns(robot, params)
    med, p99 = stats_ms(solves)
    umed, up99 = stats_ms(updates)
    results = {"ours_update_ms_median": round(umed, 4), "ours_solve_ms_median": round(med, 4),
               "placo_replan_ms_median": None, "ratio_placo_update": None}
    walks = f"{WALKS} walks" if plans is not None else "a walk"
    print(f"robot_ctrl walking MPC ({params.solver}), {walks} of 3 m at 0.25 m/s, {len(solves)} solves: "
          f"median {med:.3f} ms, p99 {p99:.3f} ms  (whole update incl. horizon: median {umed:.3f} ms, p99 {up99:.3f} ms)")
    if args.solvers:
        for plugin in ("casadi-daqp", "qpoases", "osqp", "hpipm"):
            try:
                s, _ = run_ours(WalkParams(**{**params.__dict__, "solver": plugin}))
                m, q = stats_ms(s)
                print(f"  plugin {plugin:8s}: median {m:.3f} ms, p99 {q:.3f} ms")
            except (MpcInfeasible, RuntimeError) as exc:
                print(f"  plugin {plugin:8s}: failed ({str(exc).splitlines()[0][:100]})")
    if placo_missing:
        print(placo_missing)
        return finish(results, args.json)
    pmed, _ = stats_ms(plans)
    rmed, rp99 = stats_ms(replans)
    print(f"placo WalkPatternGenerator, same robot and timing, 15 steps of 0.2 m: plan {pmed:.2f} ms (median of "
          f"{len(plans)}), replan median {rmed:.3f} ms, p99 {rp99:.3f} ms ({len(replans)} replans)")
    print(f"ratio placo replan / robot_ctrl MPC solve (median): {rmed / med:.2f}; "
          f"/ robot_ctrl whole update: {rmed / umed:.2f}")
    results.update(placo_replan_ms_median=round(rmed, 4), ratio_placo_update=round(rmed / umed, 3))
    finish(results, args.json)


def finish(results: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(results))


if __name__ == "__main__":
    main()
