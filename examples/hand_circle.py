"""Your own controller in robot_ctrl's loop: Talos stands and draws a circle with its right hand.

A controller is ``prepare()`` (work that needs no measurement, done while the robot moves),
``step(state) -> JointCommand`` and ``close()``. This one holds the feet and the CoM with the
stack of tasks, moves the right hand on a circle in the world's y-z plane, and measures the real
hand's distance from it.   .venv/bin/python examples/hand_circle.py [--turns 2]
"""

import argparse

import numpy as np
import pinocchio as pin

from robot_ctrl import (
    ControlLoop,
    FallCriterion,
    Fell,
    JointCommand,
    MetricsRecorder,
    RunMetrics,
    TimeLimit,
    WholeBodyIK,
    configuration,
    load_robot,
    open_hardware,
    static_torques,
)

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--turns", type=float, default=2.0, help="circles drawn, 5 s each")
args = parser.parse_args()
RADIUS, PERIOD, DT = 0.06, 5.0, 0.005  # [m], [s], [s]


class HandCircle:
    def __init__(self, robot, state):
        self.robot, self.k, self.worst_error = robot, 0, 0.0
        self.data, self.measured = robot.pin.createData(), robot.pin.createData()
        self.ik = WholeBodyIK(robot, configuration(robot, state.base_pos, state.base_quat_xyzw, state.q))
        self.ik.hands["right"].active = True
        self.start = self.ik.pose("right_hand").translation  # world frame [m]

    def target(self, t: float) -> np.ndarray:  # a circle through the start, its radius growing over the first turn
        a, s = 2 * np.pi * t / PERIOD, min(t / PERIOD, 1.0)
        return self.start + RADIUS * s * s * (3 - 2 * s) * np.array([0.0, np.cos(a) - 1.0, np.sin(a)])

    def prepare(self) -> None:
        r, feet = self.robot, [self.robot.frame_ids["left_foot"], self.robot.frame_ids["right_foot"]]
        self.ik.hands["right"].set_target(pin.SE3(np.eye(3), self.target((self.k + 1) * DT)))
        v = self.ik.step(DT)
        tau, _ = static_torques(r.pin, self.data, self.ik.q, feet, [0.5, 0.5])  # gravity, weight on both feet
        self.command = JointCommand(r.joints_from_q(self.ik.q), v[r.v_index], r.kp, r.kd, tau[r.v_index])

    def step(self, state) -> JointCommand:
        pin.framesForwardKinematics(self.robot.pin, self.measured, configuration(
            self.robot, state.base_pos, state.base_quat_xyzw, state.q))
        hand = self.measured.oMf[self.robot.frame_ids["right_hand"]].translation
        if state.t > 0.5:  # once the hand has caught up with the moving target
            self.worst_error = max(self.worst_error, float(np.linalg.norm(hand - self.target(state.t))))
        if self.k == 0:
            self.prepare()
        self.k += 1
        return self.command

    def close(self) -> None:
        pass


robot = load_robot("talos")
with open_hardware("mujoco", robot) as hw:
    hw.bring_up()
    state = hw.read()
    controller = HandCircle(robot, state)
    metrics = RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(state.base_pos[2])))
    ControlLoop([hw], [controller], DT, recorders=[MetricsRecorder([metrics])],
                stops=[Fell([metrics]), TimeLimit(args.turns * PERIOD, "circles drawn")]).run([state])
    safety = hw.report()["interventions"]
report = metrics.report()
print(f"{report['time_s']} s, fell {report['fell']}, largest hand error {controller.worst_error * 1e3:.1f} mm, "
      f"peak torque {report['peak_torque_ratio']:.2f} of the limit, safety interventions {safety}")
