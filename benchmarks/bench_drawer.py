"""The drawer task's speed: the whole loop's real-time factor (synthesis → WPG → dynamic filter
`full` in its worker → IK → MuJoCo in its robot process) on one drawer run, and the synthesis's own
tick inside it (each ``Synthesizer.step`` of that run timed), with the tick against the 5 ms period,
and the physics of the drawer scene alone (the robot standing before the cabinet, in its own
process; before the run and after it, the faster of the two) for the ratio of the two, with the
ticks split as ``bench_loop.py`` splits them (the serial path, the controller's work while the
robot moves, and the wait for the robot). Last, the same run with a period of command latency
(``--latency-ms 5``), in which the robot simulates each next period while the controller computes.

Run: ``python benchmarks/bench_drawer.py [--distance D] [--json]`` (default 2.0 m, slot front_left).
"""

from __future__ import annotations

import argparse
import functools
import json
import time

import numpy as np
from bench_loop import TickSplit, physics_around

from robot_ctrl.backends import open_hardware
from robot_ctrl.modes import FilterMode
from robot_ctrl.robot import load_robot
from robot_ctrl.scenarios.drawer import run_drawer
from robot_ctrl.scenarios.drawer_task import DrawerTask
from robot_ctrl.sim.disturbances import Disturbances
from robot_ctrl.sim.drawer_cabinet import DrawerPlacement
from robot_ctrl.sim.mujoco_backend import MujocoBackend
from robot_ctrl.sim.robot_process import RobotProcess
from robot_ctrl.synthesis.learned import load_primitives
from robot_ctrl.synthesis.synthesizer import Synthesizer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--distance", type=float, default=2.0)
    parser.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    args = parser.parse_args()
    distance = args.distance
    robot = load_robot("talos")
    primitives = load_primitives(robot)
    ticks = []
    step = Synthesizer.step

    def timed(self, *args, **kwargs):
        t0 = time.perf_counter()
        out = step(self, *args, **kwargs)
        ticks.append(time.perf_counter() - t0)
        return out

    Synthesizer.step = timed
    task = DrawerTask(distance, "front_left", dynfilter=FilterMode.FULL)
    placement = DrawerPlacement(distance, "front_left")

    def drawer(disturbances: Disturbances = Disturbances()):
        with open_hardware("mujoco", robot, prop=placement, disturbances=disturbances) as hw:
            split = TickSplit(hw.backend)
            return run_drawer(robot, hw, primitives, task, log=lambda line: None), split

    def drawers():
        lockstep = drawer()
        synthesis = len(ticks)
        delayed, _ = drawer(Disturbances(latency=0.005))
        del ticks[synthesis:]
        return lockstep, delayed

    ((report, split), delayed), before, after, physics = physics_around(
        robot, lambda: RobotProcess(functools.partial(MujocoBackend, robot, prop=placement), robot.nj), drawers)
    Synthesizer.step = step
    us = np.array(ticks) * 1e6
    print(f"drawer at {distance} m, filter full: {report['time_s']:.2f} s simulated, real-time factor "
          f"{report['rtf']:.2f} (loop and physics together; success {report['success']})")
    print(f"synthesis tick: median {np.median(us):.0f} us, p99 {np.percentile(us, 99):.0f} us over {len(us)} "
          f"ticks = {np.median(us) / 5000:.1%} of the 5 ms control period")
    print(f"physics only (the drawer scene, its own process): real-time factor {physics:.1f}x ({before:.1f}x "
          f"before the run, {after:.1f}x after); loop / physics: {report['rtf'] / physics:.2f}")
    print(split.summary(report["rtf"], physics))
    print(f"the same run with a period of command latency (--latency-ms 5), the robot simulating each next period "
          f"while the controller computes its command: real-time factor {delayed['rtf']:.2f}, "
          f"{delayed['rtf'] / physics:.2f} x the physics (success {delayed['success']})")
    if args.json:
        print(json.dumps({"rtf_loop": round(report["rtf"], 3), "rtf_physics_only": round(physics, 3),
                          "ratio_to_physics": round(report["rtf"] / physics, 3),
                          "serial_path_ms": round(float(np.mean(split.serial)) * 1e3, 4),
                          "lockstep_bound": round(split.lockstep_bound(physics), 3),
                          "rtf_loop_latency_5ms": round(delayed["rtf"], 3),
                          "ratio_to_physics_latency_5ms": round(delayed["rtf"] / physics, 3)}))


if __name__ == "__main__":
    main()
