"""Measuring a robot's gait profile g(φ) in MuJoCo: walk straight at a constant speed reference and
bin the measured CoM's forward speed (world frame, along the walking direction +x) over the
pattern generator's gait phase, skipping the first gait cycle (start-up) and stopping after
``cycles`` more."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import numpy as np

from robot_ctrl.control.walking_controller import WalkingController
from robot_ctrl.crowd.gait_profile import GaitProfile, binned_speed
from robot_ctrl.eval import FallCriterion, RunMetrics
from robot_ctrl.hw.mujoco_backend import MujocoBackend
from robot_ctrl.robot.model import RobotModel


def measure_gait_profile(robot: RobotModel, speed: float = 0.2, cycles: int = 6, bins: int = 32,
                         out: Path | None = None, log: Callable[[str], None] = print,
                         control_dt: float = 0.005) -> GaitProfile:
    if not (np.isfinite(speed) and 0.05 <= speed <= 0.3):
        raise ValueError(f"speed = {speed} m/s is outside the allowed range [0.05, 0.3]")
    if not (isinstance(cycles, int) and 2 <= cycles <= 50):
        raise ValueError(f"cycles = {cycles!r} must be an integer in [2, 50]")
    hw = MujocoBackend(robot, control_dt)
    hw.configure()
    hw.activate()
    state = hw.read()
    controller = WalkingController(robot, state, None, control_dt)
    wpg = controller.wpg
    metrics = RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(state.base_pos[2])))
    phases, speeds = [], []
    try:
        while True:
            t = controller.k * control_dt
            if controller.sample_due:
                wpg.set_velocity(speed, 0.0, 0.0)
            phase = wpg.gait_phase(t - wpg.sample_start) if controller.k else None
            hw.write(controller.step(state))
            state = hw.read()
            metrics.update(state)
            if metrics.fell:
                raise RuntimeError(f"the robot fell while measuring its gait profile: {metrics.fall_reason}")
            if phase is not None and 2 * np.pi <= phase < 2 * np.pi * (cycles + 1):
                phases.append(phase)
                speeds.append(controller.estimate.com_velocity[0])
            if phase is not None and phase >= 2 * np.pi * (cycles + 1):
                break
    finally:
        hw.close()
    omega = np.pi / controller.params.step_period
    profile = GaitProfile(binned_speed(np.array(phases), np.array(speeds), bins), speed, float(omega),
                          f"measured in MuJoCo: robot-ctrl crowd gait-profile --speed {speed} --cycles {cycles}")
    log(f"{robot.name}: forward CoM speed over the gait cycle min {profile.speed.min():.3f}, "
        f"mean {profile.speed.mean():.3f}, max {profile.speed.max():.3f} m/s at {speed} m/s, ω = {omega:.3f} rad/s")
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(profile.to_json(), indent=2) + "\n")
        log(f"wrote {out}")
    return profile
