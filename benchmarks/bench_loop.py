"""Full walking loop real-time factor: Talos in MuJoCo (1 ms physics), 200 Hz control.

Walks 2 m at 0.25 m/s with the complete controller (MPC pattern generator, DCM stabilizer and
state estimator, stack-of-tasks IK, torque feedforward) through the hardware adapter, and prints
the real-time factor (simulated seconds per wall second) with the median wall time of each stage
per control tick. A tick is: ``step`` (estimator, stabilizer, IK finish, feedforward), ``write``
(which starts the period's physics on the backend's thread), ``prepare`` of the next tick while
the physics runs, and ``read`` (which waits for the physics). For reference it also prints the
physics-only factor (the robot standing under constant servo commands). Run:
``python benchmarks/bench_loop.py``.
"""

from __future__ import annotations

import time
from collections import defaultdict

import numpy as np

from robot_ctrl.control import walking_controller as wc
from robot_ctrl.control.path_follower import WalkGoal
from robot_ctrl.hw.mujoco_backend import MujocoBackend
from robot_ctrl.hw.types import JointCommand
from robot_ctrl.robot import load_robot
from robot_ctrl.scenarios.walk import run_walk


class StageTimer:
    """Wraps callables and records their wall time per call."""

    def __init__(self):
        self.samples = defaultdict(list)

    def wrap(self, name, fn):
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.samples[name].append(time.perf_counter() - t0)
        return timed


def physics_only_rtf(robot, seconds: float = 5.0) -> float:
    hw = MujocoBackend(robot)
    hw.configure()
    hw.activate()
    state = hw.read()
    zero = np.zeros(robot.nj)
    command = JointCommand(q=state.q, dq=zero, kp=robot.kp, kd=robot.kd, tau_ff=zero)
    ticks = round(seconds / hw.control_dt)
    t0 = time.perf_counter()
    for _ in range(ticks):
        hw.write(command)
        hw.read()
    return seconds / (time.perf_counter() - t0)


def main() -> None:
    robot = load_robot("talos")
    timer = StageTimer()
    hw = MujocoBackend(robot)
    hw.write = timer.wrap("write (command in, physics started)", hw.write)
    hw.read = timer.wrap("read (waits for the physics)", hw.read)
    hw.world._run_period = timer.wrap("physics period (5 steps, own thread)", hw.world._run_period)
    original = wc.WalkingController.__init__

    def instrumented(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self.wpg.update = timer.wrap("  MPC update (every 20th tick)", self.wpg.update)
        self.ik.prepare = timer.wrap("  IK prepare", self.ik.prepare)
        self.ik.finish = timer.wrap("  IK finish", self.ik.finish)
        self.estimator.estimate = timer.wrap("  estimator", self.estimator.estimate)
        self.prepare = timer.wrap("controller prepare (during the physics)", self.prepare)
        self.step = timer.wrap("controller step (after the read)", self.step)

    wc.WalkingController.__init__ = instrumented
    try:
        report = run_walk(robot, hw, WalkGoal(distance=2.0, speed=0.25), log=lambda _: None)
    finally:
        wc.WalkingController.__init__ = original
    print(f"full loop, 2 m walk, {report['time_s']:.1f} s simulated: real-time factor {report['rtf']:.2f}x "
          f"(target >= 10x), fell: {report['fell']}")
    for name, samples in timer.samples.items():
        print(f"  {name:48s} median {np.median(samples) * 1e3:7.3f} ms  ({len(samples)} calls)")
    print(f"physics only (standing, same backend): real-time factor {physics_only_rtf(robot):.1f}x")


if __name__ == "__main__":
    main()
