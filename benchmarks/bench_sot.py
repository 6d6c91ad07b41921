"""One stack-of-tasks IK tick for Talos: robot_ctrl's strict 3-level hierarchy vs mink's solve_ik.

Both solve the same tasks on the same robot, from the same configuration, for a right-hand reach
(the balance demo's): feet 6D ×2, CoM 3D, waist orientation, right-hand position, posture over
all joints, with joint position and velocity limits. robot_ctrl solves them as a strict hierarchy
(feet > CoM + waist > hand + posture) with quadprog; mink as one weighted QP (feet and CoM
weighted highest). A tick is one solve plus the integration of the configuration.

Prints the median and p99 tick time and the ratio mink / robot_ctrl (mink is the optional
``bench`` extra; without it only robot_ctrl is timed). Run: ``python benchmarks/bench_sot.py``.
"""

from __future__ import annotations

import argparse
import json
import time

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


def time_robot_ctrl(robot, ticks: int) -> tuple[list[float], float]:
    ik = WholeBodyIK(robot, robot.q_half_sitting)
    target = reach_target(ik)
    ik.hands["right"].active = True
    ik.hands["right"].set_target(pin.SE3(np.eye(3), target))
    samples = []
    for _ in range(ticks):
        t0 = time.perf_counter()
        ik.step(DT)
        samples.append(time.perf_counter() - t0)
    return samples, float(np.linalg.norm(ik.pose("right_hand").translation - target))


def time_mink(robot, ticks: int) -> tuple[list[float], float]:
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
    samples = []
    for _ in range(ticks):
        t0 = time.perf_counter()
        v = mink.solve_ik(conf, tasks, DT, solver="quadprog", damping=1e-5, limits=limits)
        conf.integrate_inplace(v, DT)
        samples.append(time.perf_counter() - t0)
    hand_pos = conf.get_transform_frame_to_world(name("right_hand"), "body").translation()
    return samples, float(np.linalg.norm(hand_pos - target))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=2000)
    parser.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    args = parser.parse_args()
    results = {"ours_us_median": None, "ours_us_p99": None, "mink_us_median": None, "placo_us_median": None,
               "ratio_mink": None, "ratio_placo": None}  # placo's KinematicsSolver: not compared yet
    robot = load_robot("talos")
    time_robot_ctrl(robot, 100)  # warm-up
    ours, ours_err = time_robot_ctrl(robot, args.ticks)
    med, p99 = percentiles(ours)
    results.update(ours_us_median=round(med, 2), ours_us_p99=round(p99, 2))
    print(f"robot_ctrl HierarchicalQP, 3 levels, Talos (nv = {robot.pin.nv}): "
          f"median {med:.1f} us, p99 {p99:.1f} us  (hand error after {args.ticks} ticks {ours_err * 1e3:.1f} mm)")
    try:
        import mink  # noqa: F401
    except ImportError as exc:
        print(f"mink does not import ({exc}; pip install -e '.[bench]'): no comparison")
        return finish(results, args.json)
    time_mink(robot, 100)
    theirs, theirs_err = time_mink(robot, args.ticks)
    m_med, m_p99 = percentiles(theirs)
    print(f"mink solve_ik, same tasks, one weighted level (quadprog): median {m_med:.1f} us, p99 {m_p99:.1f} us  "
          f"(hand error {theirs_err * 1e3:.1f} mm)")
    print(f"ratio mink / robot_ctrl (median): {m_med / med:.2f}")
    results.update(mink_us_median=round(m_med, 2), ratio_mink=round(m_med / med, 3))
    finish(results, args.json)


def finish(results: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(results))


if __name__ == "__main__":
    main()
