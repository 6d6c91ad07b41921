"""Walking MPC for Talos: robot_ctrl's update against placo's replan, doing the same work at the
same look-ahead.

Ours: the walking pattern generator re-plans every 0.1 s over a 3 m walk at 0.25 m/s started from
standing. One ``update`` builds the horizon and solves the MPC: CoM jerks over 16 samples of 0.1 s
(1.6 s ahead) with the next two footsteps as decision variables (Herdt et al. 2010), ZMP in the
support polygon as hard constraints; it produces the CoM plan and those footsteps, which the plan
is queried for by time. We time the whole update; the QP solve alone is printed beside it, not
compared with anything.

placo (optional ``bench`` extra): its ``WalkPatternGenerator`` with the same timing (0.7 s single,
0.1 s double support, 0.1 s planning step, CoM height, sole size, feet spacing) and steps of 0.2 m
(0.25 m/s). Each ``replan`` (placo's own walking loop: ``replan_supports`` from its footstep
planner, then ``replan``) re-plans every footstep its planner gives: the supports (the footsteps,
hard), the CoM trajectory (one QP over every support: ZMP in the supports as hard constraints, jerk
and ZMP tracking as costs) and the swing and yaw splines of each. placo's look-ahead is what its
footstep planner is given, not ``planned_timesteps`` (which changes nothing here), so the
comparison sets the planner's number of steps: 2 steps is the same number of future steps as ours
(its horizon is then the current support, those steps and placo's closing double support: longer
than our 1.6 s, the nearest placo allows), and the ratio is also printed at 3 and 5 steps. The
expert's configuration: the same timing and robot as ours, the repetitive planner that places the
steps a constant-velocity walk takes, replanned at the rate ours is (every 0.1 s), over the same
walking time. placo needs frames named ``left_foot``, ``right_foot`` and ``trunk``: a temporary
copy of the Talos URDF with those fixed frames added is written to a temporary folder at run time
(nothing is committed).

The two take turns (:func:`in_turns`: our walk five times, each followed by its share of placo's
replans at every look-ahead), so that the machine's swings fall on all of them.

``--solvers`` also times the CasADi QP plugins on the same walk (how daqp was chosen, and what
CasADi's interface to it costs over calling it directly).
Run: ``python benchmarks/bench_wpg.py [--solvers] [--json]``.
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


def placo_walk(robot, params: WalkParams, steps: int, duration: float, step: float = 0.2):
    """placo's generator planning ``steps`` footsteps of ``step`` metres ahead, replanned every
    sample time for ``duration`` seconds of walking; its next replan as (wall time [s], how far its
    plan then reaches ahead [s]), None at the end."""
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
    planner.configure(step, 0.0, 0.0, steps)
    left, right = np.eye(4), np.eye(4)
    left[1, 3], right[1, 3] = params.step_width / 2, -params.step_width / 2
    footsteps = planner.plan(placo.HumanoidRobot_Side.left, left, right)
    supports = placo.FootstepsPlanner.make_supports(footsteps, 0.0, True, p.has_double_support(), True)
    state = {"t": params.sample_time, "last": 0.0,
             "trajectory": wpg.plan(supports, np.array([0.0, 0.0, params.com_height]), 0.0)}

    def replan() -> tuple[float, float] | None:
        while state["t"] < duration:
            t = state["t"]
            state["t"] += params.sample_time
            if wpg.can_replan_supports(state["trajectory"], t):
                t0 = time.perf_counter()
                supports = wpg.replan_supports(planner, state["trajectory"], t, state["last"])
                state["trajectory"] = wpg.replan(supports, state["trajectory"], t)
                wall = time.perf_counter() - t0
                state["last"] = t
                return wall, state["trajectory"].t_end - t
        return None

    return replan


WALKS = 5
PLACO_STEPS = (2, 3, 5)  # the first: as many future steps as ours


def in_turns(robot, params: WalkParams) -> tuple[list[float], list[float], dict[int, list[tuple[float, float]]]]:
    """``WALKS`` of our 3 m walks, each followed by its share of placo's replans at every look-ahead
    over the same walking time: a burst of the machine's load then falls on all, and each runs long
    enough to keep its own caches (one call of each in turn left our update cold after placo's
    larger replan). Our solve and update times [s]; per placo step count, its replans' (wall time
    [s], look-ahead [s])."""
    solves, updates = [], []
    gen, update = our_walk(params)
    walk_updates = list(iter(update, None))  # how long our walk takes sets placo's
    duration = len(walk_updates) * params.sample_time
    replans = {n: placo_walk(robot, params, n, duration) for n in PLACO_STEPS}
    done = {n: [] for n in PLACO_STEPS}
    share = -(-len(walk_updates) // WALKS)
    for _ in range(WALKS):
        gen, update = our_walk(params)
        updates += list(iter(update, None))
        solves += gen.solve_times
        for n, replan in replans.items():
            done[n] += [r for r in (replan() for _ in range(share)) if r is not None]
    for n, replan in replans.items():
        done[n] += list(iter(replan, None))
    return solves, updates, done


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
        (solves, updates), replans = run_ours(params), None
    else:
        placo_missing = None
        solves, updates, replans = in_turns(robot, params)
    med, p99 = stats_ms(solves)
    umed, up99 = stats_ms(updates)
    ours_horizon = params.horizon * params.sample_time
    results = {"ours_update_ms_median": round(umed, 4), "ours_solve_ms_median": round(med, 4),
               "ours_horizon_s": round(ours_horizon, 3), "placo_replan_ms_median": None, "placo_horizon_s": None,
               "placo_steps": None, "ratio_placo_update": None}
    walks = f"{WALKS} walks" if replans is not None else "a walk"
    print(f"robot_ctrl walking MPC ({params.solver}), {walks} of 3 m at 0.25 m/s, {len(updates)} updates, each the "
          f"CoM plan {ours_horizon:.1f} s ahead and 2 footsteps: median {umed:.3f} ms, p99 {up99:.3f} ms "
          f"(of which the QP solve: median {med:.3f} ms, p99 {p99:.3f} ms)")
    if args.solvers:
        for plugin in ("casadi-daqp", "qpoases", "osqp", "hpipm"):
            try:
                s, _ = run_ours(WalkParams(**{**params.__dict__, "solver": plugin}))
                m, q = stats_ms(s)
                print(f"  plugin {plugin:8s}: QP solve median {m:.3f} ms, p99 {q:.3f} ms")
            except (MpcInfeasible, RuntimeError) as exc:
                print(f"  plugin {plugin:8s}: failed ({str(exc).splitlines()[0][:100]})")
    if placo_missing:
        print(placo_missing)
        return finish(results, args.json)
    for n in PLACO_STEPS:
        rmed, rp99 = stats_ms([wall for wall, _ in replans[n]])
        ahead = float(np.median([reach for _, reach in replans[n]]))
        print(f"placo WalkPatternGenerator replan, {n} steps of 0.2 m ahead ({ahead:.2f} s, median), each the "
              f"supports, the CoM plan and every swing: median {rmed:.3f} ms, p99 {rp99:.3f} ms "
              f"({len(replans[n])} replans); ratio placo replan / robot_ctrl update: {rmed / umed:.2f}")
        if n == PLACO_STEPS[0]:
            results.update(placo_replan_ms_median=round(rmed, 4), placo_horizon_s=round(ahead, 3), placo_steps=n,
                           ratio_placo_update=round(rmed / umed, 3))
    finish(results, args.json)


def finish(results: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(results))


if __name__ == "__main__":
    main()
