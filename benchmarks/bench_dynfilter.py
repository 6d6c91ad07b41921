"""Dynamic filter cost: one filter pass per pattern-generator sample, and the full walking loop's
real-time factor with the filter off and on (target: ≥ 5× real time with the filter on).

A pass is the whole-body preview (19 weighted least-squares Newton steps over the 1.6 s horizon), its multibody ZMP
(Pinocchio RNEA at 15 samples) and the preview-control correction. Talos walks 2 m at 0.25 m/s in
MuJoCo (1 ms physics, 200 Hz control) with the arms swinging; the filter runs its passes once per
0.1 s sample, in the control loop (``inline``) or in a worker process one sample behind (``worker``,
the default of ``robot-ctrl walk``). The simulated robot runs in its own process, as in
``robot-ctrl walk``. Run: ``python benchmarks/bench_dynfilter.py [--passes 2]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from robot_ctrl.backends import open_hardware
from robot_ctrl.control.commanders.path_follower import WalkGoal
from robot_ctrl.control.controllers.walking_controller import WalkingOptions
from robot_ctrl.dynfilter import dynamic_filter as df
from robot_ctrl.modes import ArmMotion, FilterMode
from robot_ctrl.robot import load_robot
from robot_ctrl.scenarios.walk import WalkSettings, run_walk


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--passes", type=int, default=2)
    args = parser.parse_args()
    robot = load_robot("talos")
    samples: list[tuple[float, int]] = []
    original = df.DynamicFilter.refine

    def timed(self, *a, **k):
        t0 = time.perf_counter()
        original(self, *a, **k)
        samples.append((time.perf_counter() - t0, self.passes))

    runs = {"off": ("off", False), "full, inline": ("full", False), "full, worker": ("full", True)}
    results = {}
    df.DynamicFilter.refine = timed  # the worker process's calls are not seen here: only the inline run's
    try:
        for name, (mode, worker) in runs.items():
            with open_hardware("mujoco", robot) as hw:
                options = WalkingOptions(dynfilter=FilterMode(mode), dynfilter_passes=args.passes,
                                         dynfilter_worker=worker)
                settings = WalkSettings(options, arms=ArmMotion.SWING)
                results[name] = run_walk(robot, hw, WalkGoal(distance=2.0, speed=0.25), settings, log=lambda _: None)
    finally:
        df.DynamicFilter.refine = original
    per_pass = np.array([t / n for t, n in samples]) * 1e3
    per_sample = np.array([t for t, _ in samples]) * 1e3
    print(f"filter pass (whole-body preview + multibody ZMP + preview correction): median {np.median(per_pass):.2f} ms, "
          f"p99 {np.percentile(per_pass, 99):.2f} ms")
    print(f"per WPG sample ({args.passes} passes, every 0.1 s): median {np.median(per_sample):.2f} ms "
          f"= {np.median(per_sample) / 100:.1%} of real time")
    for mode, report in results.items():
        print(f"full loop, 2 m walk with arm swing, dynfilter {mode:12s}: real-time factor {report['rtf']:.2f}x "
              f"(target with the filter on >= 5x), fell: {report['fell']}")


if __name__ == "__main__":
    main()
