"""Measuring a robot's gait profile g(φ) in MuJoCo: walk straight at a constant speed reference and
bin the measured CoM's forward speed (world frame, along the walking direction +x) over the
pattern generator's gait phase, skipping the first gait cycle (start-up) and stopping after
``cycles`` more."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import numpy as np

from robot_ctrl.control.controllers.walking_controller import WalkingController, WalkingOptions
from robot_ctrl.control.loop.control_loop import ControlLoop
from robot_ctrl.crowd.gait_profile import GaitProfile, binned_speed
from robot_ctrl.eval.recording import FallCriterion, RunMetrics
from robot_ctrl.eval.recording.phase_speed import PhaseSpeedRecorder
from robot_ctrl.eval.recording.recorders import Fell, MetricsRecorder, ProgressBar, TimeLimit
from robot_ctrl.hw.safety import SafetyLayer
from robot_ctrl.robot.model import RobotModel


def measure_gait_profile(robot: RobotModel, hw: SafetyLayer, speed: float = 0.2, cycles: int = 6, bins: int = 32,
                         out: Path | None = None, log: Callable[[str], None] = print, control_dt: float = 0.005,
                         progress: bool = False) -> GaitProfile:
    if not (np.isfinite(speed) and 0.05 <= speed <= 0.3):
        raise ValueError(f"speed = {speed} m/s is outside the allowed range [0.05, 0.3]")
    if not (isinstance(cycles, int) and 2 <= cycles <= 50):
        raise ValueError(f"cycles = {cycles!r} must be an integer in [2, 50]")
    hw.configure()
    hw.activate()
    state = hw.read()
    controller = WalkingController(robot, state, WalkingOptions(control_dt=control_dt))
    controller.on_sample(lambda sample: controller.set_velocity(speed, 0.0, 0.0))
    recorder = PhaseSpeedRecorder(controller, cycles)
    metrics = RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(state.base_pos[2])))
    expected = controller.params.start_transfer + 2 * (cycles + 1) * controller.params.step_period
    bar = ProgressBar(expected, progress)
    loop = ControlLoop([hw], [controller], control_dt, recorders=[MetricsRecorder([metrics]), recorder, bar],
                       stops=[Fell([metrics]), recorder, TimeLimit(2 * expected + 10.0, "the gait cycles did not end")])
    try:
        result = loop.run([state])
    finally:
        bar.close()
    if metrics.fell or recorder.reason(None) is None:
        raise RuntimeError(f"measuring the gait profile failed: {result.stop_reason}")
    omega = np.pi / controller.params.step_period
    profile = GaitProfile(binned_speed(np.array(recorder.phases), np.array(recorder.speeds), bins), speed,
                          float(omega), f"measured in MuJoCo: robot-ctrl crowd gait-profile --speed {speed} --cycles {cycles}")
    log(f"{robot.name}: forward CoM speed over the gait cycle min {profile.speed.min():.3f}, "
        f"mean {profile.speed.mean():.3f}, max {profile.speed.max():.3f} m/s at {speed} m/s, ω = {omega:.3f} rad/s")
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(profile.to_json(), indent=2) + "\n")
        log(f"wrote {out}")
    return profile
