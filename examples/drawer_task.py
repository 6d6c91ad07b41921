"""The headline task through the Python API: Talos walks to a chest of drawers, pulls the drawer
open with its left hand and reaches the object with its right.

    .venv/bin/python examples/drawer_task.py [--distance 2.0] [--slot front_left] [--out runs/example]
"""

import argparse
from pathlib import Path

from robot_ctrl import DrawerPlacement, DrawerTask, load_primitives, load_robot, open_hardware, run_drawer

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--distance", type=float, default=2.0, help="drawer front panel from the start pelvis [m]")
parser.add_argument("--slot", default="front_left", help="front_left, front_right, back_left or back_right")
parser.add_argument("--out", type=Path, help="folder for report.json and timeseries.npz")
args = parser.parse_args()

robot = load_robot("talos")
task = DrawerTask(args.distance, args.slot)
primitives = load_primitives(robot)  # the learned walk-and-reach movement primitives
task.check(primitives.comfort_distance, primitives.ranges.short[0])  # a goal the primitives can reach
with open_hardware("mujoco", robot, prop=DrawerPlacement(task.distance, task.slot)) as hw:
    report = run_drawer(robot, hw, primitives, task, out_dir=args.out, log=lambda line: None, progress=True)

print(f"success {report['success']}: drawer open {report['drawer_opening_m']} m, right hand "
      f"{report['hand_to_object_m'] * 1e3:.1f} mm from the object, step errors "
      f"{[round(e * 1e3, 1) for e in report['step_length_errors_m']]} mm, fell {report['fell']}")
