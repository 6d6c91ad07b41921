"""Full walking loop real-time factor: Talos in MuJoCo (1 ms physics), 200 Hz control.

Walks 2 m at 0.25 m/s with the complete controller (MPC pattern generator, DCM stabilizer and
state estimator, stack-of-tasks IK, torque feedforward) through the hardware adapter, with the
simulated robot in its own process (``RobotProcess``, as ``robot-ctrl walk`` runs it), and prints
the real-time factor (simulated seconds per wall second) with the median wall time of each stage
of the controller's tick: ``step`` (estimator, stabilizer, IK finish), ``write`` (the command
handed to the robot's process), ``prepare`` of the next tick while the robot moves, and ``read``
(the wait for the robot's period and state). It splits the ticks at the robot process's adapter
(:class:`TickSplit`): the serial path, from a state's arrival to the next command's hand-over
while the robot waits, bounds the ratio to the physics under lockstep. For reference it also
prints the physics-only factor (the robot standing under constant servo commands), with the
backend in this process and in its own. The one in its own process, which the ratio divides by,
is measured before the walk and after it (the machine's speed drifts over a minute), and the faster
of the two is taken: a slow moment of the physics alone never flatters the loop. Last, the same
walk with a period of command latency (``--latency-ms 5``): the robot's process then simulates each
next period while the controller computes (``MujocoBackend.run_ahead``), so no serial path remains.
Run: ``python benchmarks/bench_loop.py``.
"""

from __future__ import annotations

import argparse
import functools
import json
import time
from collections import defaultdict

import numpy as np

from robot_ctrl.control.commanders.path_follower import WalkGoal
from robot_ctrl.control.controllers import walking_controller as wc
from robot_ctrl.hw.safety import SafetyLayer, SafetyLimits
from robot_ctrl.hw.types import JointCommand
from robot_ctrl.robot import load_robot
from robot_ctrl.scenarios.walk import run_walk
from robot_ctrl.sim.disturbances import Disturbances
from robot_ctrl.sim.mujoco_backend import MujocoBackend
from robot_ctrl.sim.robot_process import RobotProcess


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


class TickSplit:
    """Where a loop's ticks go, timed at the robot process's adapter (``RobotProcess``), whose
    handing over the physics-only figure pays as well: ``serial``, from a state's arrival (its
    ``read`` returns) to the next command's hand-over (its ``write`` is called): the controller's
    step and the safety layer's checks, while the robot waits; ``waits``: each ``read``'s wait for
    the robot's period. The rest of a tick is the controller's work while the robot moves. Reads
    before the first write (the run's set-up) are left out."""

    def __init__(self, process: RobotProcess):
        self.serial, self.waits = [], []
        arrived = written = None
        read, write = process.read, process.write

        def timed_read():
            nonlocal arrived
            t0 = time.perf_counter()
            state = read()
            if written:
                arrived = time.perf_counter()
                self.waits.append(arrived - t0)
            return state

        def timed_write(command):
            nonlocal arrived, written
            written = True
            if arrived is not None:
                self.serial.append(time.perf_counter() - arrived)
                arrived = None
            write(command)

        process.read, process.write = timed_read, timed_write

    def lockstep_bound(self, physics_rtf: float, dt: float = 0.005) -> float:
        """The loop / physics ratio that the mean serial path leaves even when all other work
        overlaps the robot's period: ``t / (t + s)``, ``t`` the physics-only tick (``dt`` over
        ``physics_rtf``), ``s`` the serial path."""
        tick = dt / physics_rtf
        return tick / (tick + float(np.mean(self.serial)))

    def summary(self, loop_rtf: float, physics_rtf: float, dt: float = 0.005) -> str:
        """The split of the loop's mean tick (``dt`` over ``loop_rtf``) and the bound of the serial path."""
        tick, serial, wait = dt / loop_rtf, float(np.mean(self.serial)), float(np.mean(self.waits))
        return (f"mean tick {tick * 1e3:.3f} ms: serial path (a state's arrival to the next command's hand-over, the "
                f"robot waiting) {serial * 1e3:.3f} ms, the controller's work while the robot moves "
                f"{(tick - serial - wait) * 1e3:.3f} ms, waiting for the robot {wait * 1e3:.3f} ms; against the "
                f"physics-only tick of {dt / physics_rtf * 1e3:.3f} ms, this serial path allows at most "
                f"{self.lockstep_bound(physics_rtf, dt):.2f} x the physics")


def physics_around(robot, make_hw, run):
    """``run()``, with the physics-only factor of a fresh ``make_hw()`` measured before and after it:
    ``(run's result, before, after, the faster of the two)``."""
    before = physics_only_rtf(robot, make_hw())
    result = run()
    after = physics_only_rtf(robot, make_hw())
    return result, before, after, max(before, after)


def physics_only_rtf(robot, hw, seconds: float = 5.0, warm_up: int = 100) -> float:
    """The real-time factor of ``hw`` stepped under a constant command, after ``warm_up`` ticks
    that are not timed: the first ticks of a process load its compiled kernels (the command's
    check) and ran at half speed."""
    hw.configure()
    hw.activate()
    state = hw.read()
    zero = np.zeros(robot.nj)
    command = JointCommand(q=state.q, dq=zero, kp=robot.kp, kd=robot.kd, tau_ff=zero)
    for _ in range(warm_up):
        hw.write(command)
        hw.read()
    ticks = round(seconds / 0.005)
    t0 = time.perf_counter()
    for _ in range(ticks):
        hw.write(command)
        hw.read()
    rtf = seconds / (time.perf_counter() - t0)
    hw.close()
    return rtf


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    args = parser.parse_args()
    robot = load_robot("talos")
    timer = StageTimer()
    original = wc.WalkingController.__init__

    def robot_process(disturbances: Disturbances = Disturbances()) -> RobotProcess:
        return RobotProcess(functools.partial(MujocoBackend, robot, disturbances=disturbances), robot.nj)

    def walk(stages: StageTimer, disturbances: Disturbances = Disturbances()):
        """The 2 m walk with its stages timed into ``stages``."""

        def instrumented(self, *args, **kwargs):
            original(self, *args, **kwargs)
            self.wpg.update = stages.wrap("  MPC update (every 20th tick)", self.wpg.update)
            self.ik.prepare = stages.wrap("  IK prepare", self.ik.prepare)
            self.ik.finish = stages.wrap("  IK finish", self.ik.finish)
            self.estimator.estimate = stages.wrap("  estimator", self.estimator.estimate)
            self.prepare = stages.wrap("controller prepare (while the robot moves)", self.prepare)
            self.step = stages.wrap("controller step (after the read)", self.step)

        # The walk's robot process starts here, not while the physics alone is measured before it.
        process = robot_process(disturbances)
        process.write = stages.wrap("write (command handed to the robot)", process.write)
        process.read = stages.wrap("read (waits for the robot's period)", process.read)
        split = TickSplit(process)
        hw = SafetyLayer(process, SafetyLimits.for_simulation(robot), clock=None)  # as open_hardware("mujoco")
        hw.write = stages.wrap("safety layer write (checks, then the write above)", hw.write)
        wc.WalkingController.__init__ = instrumented
        try:
            return run_walk(robot, hw, WalkGoal(distance=2.0, speed=0.25), log=lambda _: None), split
        finally:
            wc.WalkingController.__init__ = original
            hw.close()

    def walks():
        # The second walk is timed as the first; its stages are not printed.
        return walk(timer), walk(StageTimer(), Disturbances(latency=0.005))[0]

    ((report, split), delayed), before, after, remote = physics_around(robot, robot_process, walks)
    print(f"full loop, 2 m walk, {report['time_s']:.1f} s simulated: real-time factor {report['rtf']:.2f}x "
          f"(target: >= 0.8 x the physics alone in its own process), fell: {report['fell']}")
    for name, samples in timer.samples.items():
        print(f"  {name:48s} median {np.median(samples) * 1e3:7.3f} ms  ({len(samples)} calls)")
    inline = physics_only_rtf(robot, MujocoBackend(robot))
    print(f"physics only (standing): real-time factor {inline:.1f}x in this process, {remote:.1f}x in its own "
          f"({before:.1f}x before the walk, {after:.1f}x after)")
    print(f"loop / physics in its own process: {report['rtf'] / remote:.2f}")
    print(split.summary(report["rtf"], remote))
    print(f"the same walk with a period of command latency (--latency-ms 5), the robot simulating each next period "
          f"while the controller computes its command: real-time factor {delayed['rtf']:.2f}x, "
          f"{delayed['rtf'] / remote:.2f} x the physics, fell: {delayed['fell']}")
    if args.json:
        print(json.dumps({"rtf_loop": round(report["rtf"], 3), "rtf_physics_only": round(remote, 3),
                          "ratio_to_physics": round(report["rtf"] / remote, 3),
                          "serial_path_ms": round(float(np.mean(split.serial)) * 1e3, 4),
                          "lockstep_bound": round(split.lockstep_bound(remote), 3),
                          "rtf_loop_latency_5ms": round(delayed["rtf"], 3),
                          "ratio_to_physics_latency_5ms": round(delayed["rtf"] / remote, 3)}))


if __name__ == "__main__":
    main()
