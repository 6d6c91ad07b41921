"""Walk scenario: walk a path (straight, arc or side-step) with the MPC walking controller, stop in
double support, stand 2 s, and report falls, torques, ZMP and footsteps.

Poses in the report are in the *start frame*: the base's pose at the start (x forward, y left,
yaw about z), on the floor.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import numpy as np

from robot_ctrl.control.arm_swing import DEFAULT_JOINTS, ArmSwing
from robot_ctrl.control.path_follower import PathFollower, WalkGoal
from robot_ctrl.control.walking_controller import WalkingController
from robot_ctrl.eval import FallCriterion, RunMetrics
from robot_ctrl.eval.report_file import write_report
from robot_ctrl.eval.walk_log import GRF_LIMIT_RATIO, WalkLog, step_length_errors
from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.sot.joint_limits import JointLimits
from robot_ctrl.wpg.footstep import Footstep, rotation, wrap_angle, yaw_of
from robot_ctrl.wpg.params import WalkParams

STAND_AFTER = 2.0  # [s] standing after the stop
SETTLE_AFTER_TOUCHDOWN = 0.1  # [s] when a landed foot's pose is measured


def base_pose(state) -> np.ndarray:
    """World (x, y, yaw) of the base from a JointState."""
    x, y, z, w = state.base_quat_xyzw
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.array([state.base_pos[0], state.base_pos[1], yaw])


def relative(pose: np.ndarray, origin: np.ndarray) -> np.ndarray:
    xy = rotation(origin[2]).T @ (pose[:2] - origin[:2])
    return np.array([xy[0], xy[1], wrap_angle(pose[2] - origin[2])])


def run_walk(robot: RobotModel, hw: HardwareAdapter, goal: WalkGoal, params: WalkParams | None = None,
             stabilize: bool = True, out_dir: Path | None = None, log: Callable[[str], None] = print,
             control_dt: float = 0.005, grf_limit_ratio: float = GRF_LIMIT_RATIO, arms: str = "none",
             dynfilter: str = "off", dynfilter_passes: int = 2, dynfilter_worker: bool = True) -> dict:
    """Walk ``goal`` and report. ``arms``: ``none`` (half-sitting arms) or ``swing`` (``ArmSwing``:
    elbows ±0.5 rad at 1 Hz); ``dynfilter``: ``off``, ``legs`` or ``full`` (``DynamicFilter``), in a
    worker process one WPG sample behind unless ``dynfilter_worker`` is False (``DynamicFilterWorker``)."""
    if arms not in ("none", "swing"):
        raise ValueError(f"arms {arms!r} is not one of none, swing")
    hw.configure()
    hw.activate()
    state = hw.read()
    if state.base_pos is None or state.foot_wrench is None:
        raise ValueError("walking needs a backend that reports the base pose and the foot wrenches")
    upper_body = None
    if arms == "swing":
        limits = JointLimits.from_robot(robot)
        upper_body = ArmSwing.for_joints(DEFAULT_JOINTS, robot.joint_names,
                                         np.clip(robot.config.half_sitting, limits.q_min, limits.q_max),
                                         limits.q_min, limits.q_max)
    controller = WalkingController(robot, state, params, control_dt, upper_body=upper_body, dynfilter=dynfilter,
                                   dynfilter_passes=dynfilter_passes, dynfilter_worker=dynfilter_worker)
    controller.stabilizer.enabled = stabilize
    wpg = controller.wpg
    start = base_pose(state)
    com_offset = rotation(start[2]).T @ (controller.ik.com_position()[:2] - start[:2])  # CoM in the base frame
    feet0 = {side: np.array([f.x, f.y]) for side, f in wpg.feet.items()}
    feet_offset = {side: rotation(start[2]).T @ (xy - start[:2]) for side, xy in feet0.items()}  # base frame
    follower = PathFollower(goal, start, tolerance=(0.03, 0.03))
    goal_base = follower.world_pose(goal.pose_at(goal.length))
    metrics = RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(state.base_pos[2])))
    foot = robot.config.foot
    log_series = WalkLog(robot.mass * 9.81, start, (foot.length, foot.width), grf_limit_ratio)
    inside = contact_samples = 0
    footsteps: list[dict] = []
    pending: list[tuple[float, object]] = []
    stood_since = None
    max_time = follower.end_time + follower.settle_time + 10.0

    def steer(t: float) -> None:
        """At a pattern-generator sample: the path follower's velocity, or the final footsteps."""
        if not controller.sample_due:
            return
        planned_base = np.array([*(np.array([wpg.com_x[0], wpg.com_y[0]]) - rotation(wpg.heading) @ com_offset),
                                 wpg.heading])
        was_done = follower.done
        velocity = follower.velocity(t, planned_base)
        if follower.done and not was_done:
            # Final footsteps: the start stance, carried to the goal pose.
            wpg.stop_at(*(Footstep(side, *(goal_base[:2] + rotation(goal_base[2]) @ feet_offset[side]),
                                   float(goal_base[2])) for side in ("left", "right")))
            log(f"t = {t:6.2f} s  path done, stopping at the goal")
        elif not follower.done:
            wpg.set_velocity(*velocity)

    wall0 = time.perf_counter()
    k = 0
    steer(0.0)
    try:
        while True:
            t = k * control_dt
            command = controller.step(state)
            hw.write(command)
            # While the robot moves: log this tick, then plan the next one (nothing here reads the
            # state the write will produce).
            _record(log_series, controller, state)
            est = controller.estimate
            if est.zmp is not None:
                contact_samples += 1
                inside += est.support.contains(est.zmp)
            while len(pending) + len(footsteps) < len(wpg.touchdowns):
                td = wpg.touchdowns[len(pending) + len(footsteps)]
                pending.append((td.t + SETTLE_AFTER_TOUCHDOWN, td))
                log(f"t = {td.t:6.2f} s  {td.planned.side} foot down at ({td.planned.x:.3f}, {td.planned.y:.3f}) m")
            plan_standing = wpg.standing and follower.done  # before the next tick's plan
            steer((k + 1) * control_dt)
            controller.prepare()
            state = hw.read()
            metrics.update(state)
            while pending and state.t >= pending[0][0] - 1e-9:
                _, td = pending.pop(0)
                sole = est.soles[td.planned.side]
                realized = np.array([sole.translation[0], sole.translation[1], yaw_of(sole.rotation)])
                planned = np.array([td.planned.x, td.planned.y, td.planned.yaw])
                footsteps.append({"side": td.planned.side, "t": round(td.t, 3),
                                  "planned": relative(planned, start).round(4).tolist(),
                                  "realized": relative(realized, start).round(4).tolist()})
            if metrics.fell:
                log(f"t = {state.t:6.2f} s  FELL: {metrics.fall_reason}")
                break
            if plan_standing:
                stood_since = state.t if stood_since is None else stood_since
                if state.t - stood_since >= STAND_AFTER:
                    break
            else:
                stood_since = None
            if t > max_time:
                log(f"t = {t:6.2f} s  did not finish the path in {max_time:.1f} s")
                break
            k += 1
    finally:
        wall = time.perf_counter() - wall0
        controller.close()
        hw.close()
    final = relative(base_pose(state), start)
    target = goal.pose_at(goal.length)
    est = controller.estimate
    report = metrics.report()
    report.update(
        robot=robot.name,
        goal={"distance_m": goal.distance, "turn_deg": float(np.degrees(goal.turn)), "lateral_m": goal.lateral,
              "speed_mps": goal.speed},
        final_base_xy_yaw=[round(float(final[0]), 4), round(float(final[1]), 4), round(float(final[2]), 5)],
        commanded_base_xy_yaw=[round(float(v), 4) for v in target],
        final_position_error_m=round(float(np.linalg.norm(final[:2] - target[:2])), 4),
        final_yaw_error_deg=round(float(np.degrees(abs(wrap_angle(final[2] - target[2])))), 3),
        ended_in_double_support=bool(all(est.in_contact.values())),
        stood_s=round(state.t - stood_since, 3) if stood_since is not None else 0.0,
        zmp_in_support_ratio=round(inside / max(contact_samples, 1), 5),
        footsteps=footsteps,
        step_length_error_m=step_length_errors(footsteps),
        **log_series.metrics(),
        wpg_solve_ms_median=round(float(np.median(wpg.solve_times)) * 1e3, 4),
        wpg_solve_ms_p99=round(float(np.percentile(wpg.solve_times, 99)) * 1e3, 4),
        stabilizer=stabilize,
        arms=arms,
        dynfilter=dynfilter,
        dynfilter_passes=dynfilter_passes if dynfilter != "off" else 0,
        dynfilter_worker=dynfilter_worker and dynfilter != "off",
        rtf=round(metrics.t / wall, 3),
        control_rate_hz=round(1.0 / control_dt, 3),
    )
    log(f"fell: {str(report['fell']).lower()}  final base (x, y, yaw) {report['final_base_xy_yaw']} vs commanded "
        f"{report['commanded_base_xy_yaw']}  zmp_in_support_ratio {report['zmp_in_support_ratio']}  "
        f"peak_torque_ratio {report['peak_torque_ratio']:.3f}  steps {len(footsteps)}  rtf {report['rtf']}")
    write_report(report, out_dir, log)
    if out_dir is not None:
        log(f"wrote {log_series.save(out_dir)}")
    return report


def _record(series: WalkLog, controller: WalkingController, state) -> None:
    """Log the tick's plan against the state the controller just estimated."""
    ref, est = controller.reference, controller.estimate
    stance = next(s for s in ("left", "right") if ref.in_contact[s]) if ref.phase == "single" else None
    sole = None
    if stance is not None:
        pose = est.soles[stance]
        sole = (pose.translation[:2], yaw_of(pose.rotation))
    grf = {side: float(w[2]) for side, w in (state.foot_wrench or {}).items()}
    series.record(state.t, ref.zmp, est.zmp, ref.com, est.com, controller.wpg.heading, stance, sole, grf)
