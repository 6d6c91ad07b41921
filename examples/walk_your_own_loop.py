"""Walk Talos in MuJoCo with your own velocity commands, in your own loop, and print the report.

    .venv/bin/python examples/walk_your_own_loop.py [--duration 12]
"""

import argparse
import json

from robot_ctrl import FallCriterion, RunMetrics, WalkingController, WalkingOptions, load_robot, open_hardware

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--duration", type=float, default=12.0, help="simulated seconds [s]")
args = parser.parse_args()


def velocity(t: float) -> tuple[float, float, float]:
    """(vx, vy, ωz) in the robot's heading frame [m/s, m/s, rad/s]: straight, then a left arc, then stop."""
    return (0.25, 0.0, 0.0) if t < 4.0 else (0.2, 0.0, 0.3) if t < 7.0 else (0.0, 0.0, 0.0)


robot = load_robot("talos")
with open_hardware("mujoco", robot) as hw:  # the simulated robot, behind the safety layer
    hw.bring_up()
    state = hw.read()
    controller = WalkingController(robot, state, WalkingOptions(control_dt=0.005))
    # A command takes effect at the pattern generator's next 0.1 s sample: give it there.
    controller.on_sample(lambda sample: controller.set_velocity(*velocity(sample.t)))
    metrics = RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(state.base_pos[2])))
    for k in range(round(args.duration / controller.dt)):
        hw.write(controller.step(state))  # the measured state in, the joint command out
        controller.prepare()  # the next tick's planning, while the robot moves
        state = hw.read()
        metrics.update(state)
        if metrics.fell:
            break
    controller.close()
    safety = hw.report()["interventions"]

report = metrics.report()
summary = {key: report[key] for key in ("fell", "time_s", "peak_torque_ratio", "peak_torque_joint", "peak_grf_n")}
print(json.dumps(summary | {"steps": len(controller.touchdowns), "safety_interventions": safety,
                            "final_base_xy_m": state.base_pos[:2].round(3).tolist()}, indent=2))
