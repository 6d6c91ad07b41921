"""One stack-of-tasks IK tick for Talos: robot_ctrl's strict 3-level hierarchy vs mink's solve_ik and
placo's KinematicsSolver.

All three solve the same tasks on the same robot, from the same configuration, for a right-hand
reach (the balance demo's): feet 6D ×2, CoM 3D, waist orientation, right-hand position, posture
over all joints, with joint position and velocity limits; one solve per tick each, and the whole
tick timed on every side. What each solves:
- robot_ctrl: a strict hierarchy (feet > CoM + waist > hand + posture), each level a QP with the
  joint limits, the higher levels' tasks held exactly.
- mink: one weighted QP (``solve_ik`` with quadprog, its fastest solver installed here). The feet
  are soft tasks of cost 100, as high as the CoM's: mink can hold them exactly instead
  (``solve_ik(..., constraints=[...])``, equality constraints), but soft feet are the faster of its
  two options, so the comparison gives mink its best case.
- placo (C++ ``KinematicsSolver``): the feet hard (equality constraints), the rest soft, weighted
  as mink's but for the hand, weighted up until it reaches as close as robot_ctrl's (at mink's
  weight it stops centimetres short; the script prints each one's hand error): placo's own
  recommended use, supports hard and everything else soft.
A tick is one solve plus the integration of the configuration (and, for placo, its kinematics
update, which robot_ctrl's tick includes).

Prints the median and p99 tick time and the ratios mink / robot_ctrl and placo / robot_ctrl (mink
and placo are the optional ``bench`` extra; without them only robot_ctrl is timed). The three are
timed in turns (:func:`interleaved`), so that the machine's swings fall on all of them. Run:
``python benchmarks/bench_sot.py``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Callable

import numpy as np
import pinocchio as pin

from robot_ctrl.robot import load_robot
from robot_ctrl.sot import WholeBodyIK

DT = 0.005


def percentiles(samples: list[float]) -> tuple[float, float]:
    us = np.array(samples) * 1e6
    return float(np.median(us)), float(np.percentile(us, 99))


def reach_target(ik: WholeBodyIK) -> np.ndarray:
    mid = (ik.pose("left_foot").translation + ik.pose("right_foot").translation) / 2
    return mid + np.array([0.4, -0.2, 0.8])


def robot_ctrl_tick(robot) -> tuple[Callable[[], object], Callable[[], float]]:
    """robot_ctrl's tick from half-sitting, and its hand's distance to the target [m]."""
    ik = WholeBodyIK(robot, robot.q_half_sitting)
    target = reach_target(ik)
    ik.hands["right"].active = True
    ik.hands["right"].set_target(pin.SE3(np.eye(3), target))
    return (lambda: ik.step(DT)), lambda: float(np.linalg.norm(ik.pose("right_hand").translation - target))


def mink_tick(robot) -> tuple[Callable[[], object], Callable[[], float]]:
    """mink's tick on the same tasks, and its hand's distance to the target [m]."""
    import mink
    import mujoco

    from robot_ctrl.robot.joint_map import MujocoJointMap, pin_to_mujoco_qpos

    model = mujoco.MjModel.from_xml_path(str(robot.mjcf_path))
    jmap = MujocoJointMap.build(model, robot.joint_names, f"{robot.name}/", robot.config.base_link)
    q0 = np.zeros(model.nq)
    pin_to_mujoco_qpos(robot.q_half_sitting, robot.q_index, jmap, q0)
    conf = mink.Configuration(model, q0)
    name = lambda role: f"{robot.name}/{robot.config.frames[role]}"  # noqa: E731
    feet = [mink.FrameTask(name(f"{s}_foot"), "body", position_cost=100.0, orientation_cost=100.0, gain=0.2)
            for s in ("left", "right")]
    com = mink.ComTask(cost=100.0, gain=0.2)
    waist = mink.FrameTask(name("waist"), "body", position_cost=0.0, orientation_cost=10.0, gain=0.2)
    hand = mink.FrameTask(name("right_hand"), "body", position_cost=1.0, orientation_cost=0.0, gain=0.2)
    posture = mink.PostureTask(model, cost=0.03, gain=0.2)
    for task in (*feet, waist):
        task.set_target_from_configuration(conf)
    com.set_target_from_configuration(conf)
    posture.set_target_from_configuration(conf)
    ik = WholeBodyIK(robot, robot.q_half_sitting)
    target = reach_target(ik)
    hand.set_target(mink.SE3.from_translation(target))
    velocities = {f"{robot.name}/{n}": v * robot.config.velocity_fraction
                  for n, v in zip(robot.joint_names, robot.velocity_limit)}
    limits = [mink.ConfigurationLimit(model), mink.VelocityLimit(model, velocities)]
    tasks = [*feet, com, waist, hand, posture]

    def tick():
        conf.integrate_inplace(mink.solve_ik(conf, tasks, DT, solver="quadprog", damping=1e-5, limits=limits), DT)

    def error():
        reached = conf.get_transform_frame_to_world(name("right_hand"), "body").translation()
        return float(np.linalg.norm(reached - target))

    return tick, error


def placo_tick(robot) -> tuple[Callable[[], object], Callable[[], float]]:
    """placo's tick on the same tasks, and its hand's distance to the target [m]."""
    import placo

    from robot_ctrl.robot.description import resolve_package_uris

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"{robot.name}.urdf"
        path.write_text(resolve_package_uris(robot.files.urdf.read_text()))
        wrapper = placo.RobotWrapper(str(path), placo.Flags.ignore_collisions)
    wrapper.state.q = robot.q_half_sitting.copy()
    wrapper.update_kinematics()
    solver = placo.KinematicsSolver(wrapper)
    solver.dt = DT
    solver.enable_velocity_limits(True)
    frames = robot.config.frames
    for side in ("left", "right"):
        foot = frames[f"{side}_foot"]
        solver.add_frame_task(foot, wrapper.get_T_world_frame(foot)).configure(foot, "hard", 1.0, 1.0)
    solver.add_com_task(wrapper.com_world()).configure("com", "soft", 100.0)
    waist = frames["waist"]
    solver.add_orientation_task(waist, wrapper.get_T_world_frame(waist)[:3, :3]).configure("waist", "soft", 10.0)
    ik = WholeBodyIK(robot, robot.q_half_sitting)
    target = reach_target(ik)
    solver.add_position_task(frames["right_hand"], target).configure("hand", "soft", 30.0)
    posture = solver.add_joints_task()
    posture.set_joints({n: float(a) for n, a in zip(robot.joint_names, robot.config.half_sitting)})
    posture.configure("posture", "soft", 0.03)

    def tick():
        solver.solve(True)
        wrapper.update_kinematics()

    return tick, lambda: float(np.linalg.norm(wrapper.get_T_world_frame(frames["right_hand"])[:3, 3] - target))


ROUNDS = 20


def interleaved(ticks: list[Callable[[], object]], count: int) -> list[list[float]]:
    """Each tick function's wall times over ``count`` calls, made in ``ROUNDS`` turns of
    ``count / ROUNDS`` calls per function: a burst of the machine's load then falls on every peer
    alike instead of on whichever was being timed. Each turn first makes one call that is not
    timed: it finds the caches cold from the other peers' turn."""
    samples = [[] for _ in ticks]
    for _ in range(ROUNDS):
        for tick, out in zip(ticks, samples):
            tick()
            for _ in range(count // ROUNDS):
                t0 = time.perf_counter()
                tick()
                out.append(time.perf_counter() - t0)
    return samples


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=2000)
    parser.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    args = parser.parse_args()
    results = {"ours_us_median": None, "ours_us_p99": None, "mink_us_median": None, "placo_us_median": None,
               "ratio_mink": None, "ratio_placo": None}
    robot = load_robot("talos")
    peers = [("robot_ctrl", robot_ctrl_tick, f"HierarchicalQP, 3 levels, Talos (nv = {robot.pin.nv})")]
    for peer, setup, how in (("mink", mink_tick, "solve_ik, one weighted level (quadprog), same tasks"),
                             ("placo", placo_tick, "KinematicsSolver, feet hard, the rest soft, same tasks")):
        try:
            __import__(peer)
        except ImportError as exc:
            print(f"{peer} does not import ({exc}; make bench, or pip install -e '.[bench]'): no comparison")
            continue
        peers.append((peer, setup, how))
    for _, setup, _ in peers:  # warm-up on a throwaway solver: compiled kernels, caches
        tick, _ = setup(robot)
        for _ in range(100):
            tick()
    solvers = [setup(robot) for _, setup, _ in peers]
    samples = interleaved([tick for tick, _ in solvers], args.ticks)
    med = None
    for (peer, _, how), (_, error), times in zip(peers, solvers, samples):
        t_med, t_p99 = percentiles(times)
        print(f"{peer} {how}: median {t_med:.1f} us, p99 {t_p99:.1f} us  "
              f"(hand error after {len(times) + ROUNDS} ticks {error() * 1e3:.1f} mm)")
        if med is None:
            med = t_med
            results.update(ours_us_median=round(t_med, 2), ours_us_p99=round(t_p99, 2))
        else:
            print(f"ratio {peer} / robot_ctrl (median): {t_med / med:.2f}")
            results.update({f"{peer}_us_median": round(t_med, 2), f"ratio_{peer}": round(t_med / med, 3)})
    finish(results, args.json)


def finish(results: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(results))


if __name__ == "__main__":
    main()
