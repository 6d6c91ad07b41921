"""The drawer task's speed: the whole loop's real-time factor (synthesis → WPG → dynamic filter
`full` in its worker → IK → MuJoCo in its robot process) on one drawer run, and the synthesis's own
tick inside it (each ``Synthesizer.step`` of that run timed), with the tick against the 5 ms period.

Run: ``python benchmarks/bench_drawer.py [DISTANCE]`` (default 2.0 m, slot front_left).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from robot_ctrl.hw.drawer_cabinet import DrawerPlacement
from robot_ctrl.hw.hardware import open_hardware
from robot_ctrl.modes import FilterMode
from robot_ctrl.robot import load_robot
from robot_ctrl.scenarios.drawer import run_drawer
from robot_ctrl.scenarios.drawer_task import DrawerTask
from robot_ctrl.synthesis.learned import load_primitives
from robot_ctrl.synthesis.synthesizer import Synthesizer


def main() -> None:
    distance = float(sys.argv[1]) if len(sys.argv) > 1 else 2.0
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
    with open_hardware("mujoco", robot, prop=DrawerPlacement(distance, "front_left")) as hw:
        report = run_drawer(robot, hw, primitives, task, log=lambda line: None)
    Synthesizer.step = step
    us = np.array(ticks) * 1e6
    print(f"drawer at {distance} m, filter full: {report['time_s']:.2f} s simulated, real-time factor "
          f"{report['rtf']:.2f} (loop and physics together; success {report['success']})")
    print(f"synthesis tick: median {np.median(us):.0f} us, p99 {np.percentile(us, 99):.0f} us over {len(us)} "
          f"ticks = {np.median(us) / 5000:.1%} of the 5 ms control period")


if __name__ == "__main__":
    main()
