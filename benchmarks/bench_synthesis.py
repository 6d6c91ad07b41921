"""Walk-and-reach synthesis for Talos: one Synthesizer tick (oscillators, blending, 21 channels)
and one planning call (step plan, regressions and the rollout that solves the speed means).

Prints medians and p99 over several distances; learning the primitives is timed once.
Run: ``python benchmarks/bench_synthesis.py``.
"""

from __future__ import annotations

import time

import numpy as np

from robot_ctrl.robot import load_robot
from robot_ctrl.synthesis.learned import load_primitives
from robot_ctrl.synthesis.synthesizer import Synthesizer, WalkReachGoal

DT = 0.005


def main() -> None:
    robot = load_robot("talos")
    t0 = time.perf_counter()
    primitives = load_primitives(robot)
    print(f"learning (stepwise SISA + regressions, 30 trials): {time.perf_counter() - t0:.2f} s")
    plans, ticks, simulated = [], [], 0.0
    for distance in np.linspace(1.3, 3.0, 8):
        t0 = time.perf_counter()
        synth = Synthesizer(primitives, WalkReachGoal(float(distance)))
        plans.append(time.perf_counter() - t0)
        while not synth.finished:
            t0 = time.perf_counter()
            synth.step(DT)
            ticks.append(time.perf_counter() - t0)
            simulated += DT
    ticks_us = np.array(ticks) * 1e6
    print(f"plan: median {1e3 * np.median(plans):.0f} ms, max {1e3 * max(plans):.0f} ms (8 distances 1.3-3.0 m)")
    print(f"tick: median {np.median(ticks_us):.0f} us, p99 {np.percentile(ticks_us, 99):.0f} us "
          f"({len(ticks)} ticks; {simulated / sum(ticks):.0f}x real time at {1 / DT:.0f} Hz)")


if __name__ == "__main__":
    main()
