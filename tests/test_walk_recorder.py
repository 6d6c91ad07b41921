"""What a walk report measures, fed synthetic ticks with a known answer: the ZMP in the support
polygon and the realized footsteps come from the measured state, never from the plan."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pinocchio as pin

from robot_ctrl.control.commanders.path_follower import WalkGoal
from robot_ctrl.control.estimation.state_estimator import Estimate
from robot_ctrl.eval.recording.walk_log import WalkLog
from robot_ctrl.eval.recording.walk_recorder import SETTLE_AFTER_TOUCHDOWN, WalkRecorder
from robot_ctrl.geometry.support_polygon import SupportPolygon
from robot_ctrl.wpg.footstep import Footstep
from robot_ctrl.wpg.plan import GaitPhase, SolePlan, Touchdown, WalkReference

DT = 0.005
SOLE = (0.21, 0.13)


def sole(x, y):
    return pin.SE3(np.eye(3), np.array([x, y, 0.0]))


class Walk:
    """A controller as the recorder sees it: its plan (``reference``), its estimate of the measured
    state and its touch-downs, set by the test tick by tick."""

    def __init__(self):
        self.heading, self.touchdowns, self.solve_times = 0.0, [], [0.001]
        self.set(planned_zmp=[0.0, 0.0], measured_zmp=[0.0, 0.0], soles={"left": (0.0, 0.09), "right": (0.0, -0.09)})

    def set(self, planned_zmp, measured_zmp, soles):
        feet = {s: SolePlan(np.array([*soles[s], 0.0]), 0.0) for s in soles}
        self.reference = WalkReference(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.asarray(planned_zmp, float), feet,
                                       {"left": True, "right": True}, GaitPhase.DOUBLE)
        support = SupportPolygon.of_soles([(np.array(xy), 0.0) for xy in soles.values()], *SOLE)
        self.estimate = Estimate(np.array([0.0, 0.0, 0.9]), np.zeros(3), {s: sole(*xy) for s, xy in soles.items()},
                                 {"left": True, "right": True}, np.asarray(measured_zmp, float), support, {},
                                 np.zeros(3), np.zeros(39))


def run(walk, recorder, ticks, t0):
    for k in range(ticks):
        t = t0 + k * DT
        state = SimpleNamespace(t=t + DT, foot_wrench={"left": np.zeros(6), "right": np.zeros(6)})
        recorder.on_command(SimpleNamespace(t=t, states=[SimpleNamespace(t=t, foot_wrench=state.foot_wrench)]))
        recorder.on_state(SimpleNamespace(t=t, states=[state]))
    return t0 + ticks * DT


def recorder_for(walk):
    return WalkRecorder(walk, WalkLog(900.0, np.zeros(3), SOLE), np.zeros(3), lambda line: None)


def test_zmp_in_support_counts_the_measured_zmp_in_the_measured_feet():
    walk = Walk()
    recorder = recorder_for(walk)
    t = run(walk, recorder, 30, 0.0)  # measured ZMP between the feet
    # The plan's ZMP stays between the feet; the measured one is 0.3 m ahead of them for 10 ticks.
    walk.set(planned_zmp=[0.0, 0.0], measured_zmp=[0.3, 0.0], soles={"left": (0.0, 0.09), "right": (0.0, -0.09)})
    run(walk, recorder, 10, t)
    assert recorder.zmp_in_support_ratio == 0.75


def test_realized_footsteps_are_the_measured_soles():
    walk = Walk()
    recorder = recorder_for(walk)
    t = run(walk, recorder, 10, 0.0)
    # The plan lands the left foot 0.3 m ahead, then the right one 0.3 m ahead of it; each sole is
    # measured 2 cm short of its planned landing.
    for side, x in (("left", 0.3), ("right", 0.6)):
        walk.touchdowns.append(Touchdown(t, Footstep(side, x, 0.09 if side == "left" else -0.09, 0.0)))
        soles = {s: (xy.translation[0], xy.translation[1]) for s, xy in walk.estimate.soles.items()}
        soles[side] = (x - 0.02 * (side == "right"), soles[side][1])
        walk.set(planned_zmp=[x, 0.0], measured_zmp=[soles[side][0], soles[side][1] / 2], soles=soles)
        t = run(walk, recorder, round(2 * SETTLE_AFTER_TOUCHDOWN / DT), t)
    planned = [f["planned"][0] for f in recorder.footsteps]
    realized = [f["realized"][0] for f in recorder.footsteps]
    assert planned == [0.3, 0.6] and realized == [0.3, 0.58]  # the measured soles, not the plan's
    report = recorder.report(SimpleNamespace(base_pos=np.zeros(3), base_quat_xyzw=np.array([0.0, 0.0, 0.0, 1.0])),
                             SimpleNamespace(distance=0.6, turn=0.0, lateral=0.0, speed=0.25,
                                             pose_at=lambda s: np.zeros(3), length=0.6))
    # Step length: the distance between consecutive soles, 0.3 m ahead and 0.18 m across.
    assert report["step_length_error_m"] == [round(np.hypot(0.28, 0.18) - np.hypot(0.30, 0.18), 5)]


def test_the_report_compares_where_the_base_ended_with_the_goal_and_logs_the_measured_ticks():
    """Every field of a walk report from a known end: the base measured 3 cm behind and 1.2 cm to the
    left (start frame) of the end of a 1 m walk turning 90°, 2° short of its heading; the WPG's solve
    times; and, in the log, the single-support stance foot with its measured sole, the measured ZMP
    and the vertical forces."""
    walk = Walk()
    walk.solve_times = [0.00111111, 0.00122222, 0.0013, 0.00300001]  # [s]
    recorder = recorder_for(walk)
    walk.reference = dataclasses.replace(walk.reference, phase=GaitPhase.SINGLE,
                                         in_contact={"left": False, "right": True})
    walk.heading = 0.3
    walk.estimate = dataclasses.replace(walk.estimate, soles={"left": sole(0.0, 0.09), "right": sole(0.05, -0.08)},
                                        zmp=np.array([0.04, -0.07]))
    wrench = {"left": np.array([0, 0, 12.5, 0, 0, 0.0]), "right": np.array([0, 0, 870.0, 0, 0, 0.0])}
    recorder.on_command(SimpleNamespace(t=0.2, states=[SimpleNamespace(t=0.205, foot_wrench=wrench)]))
    a = recorder.log.arrays()
    assert a["t"].tolist() == [0.205] and a["stance"].tolist() == [1] and a["heading"].tolist() == [0.3]
    assert a["stance_sole_xy"].tolist() == [[0.05, -0.08]] and a["zmp"].tolist() == [[0.04, -0.07]]
    assert a["grf"].tolist() == [[12.5, 870.0]]

    goal = WalkGoal(distance=1.0, turn=np.pi / 2)
    target = goal.pose_at(goal.length)
    yaw = target[2] - np.radians(2.0514321)
    end = target[:2] + [-0.03, 0.012]
    quat = np.array([0, 0, np.sin(yaw / 2), np.cos(yaw / 2)])
    state = SimpleNamespace(base_pos=np.array([*end, 0.9]), base_quat_xyzw=quat)
    walk.estimate = dataclasses.replace(walk.estimate, in_contact={"left": True, "right": True})
    report = recorder.report(state, goal)
    assert report["goal"] == {"distance_m": 1.0, "turn_deg": 90.0, "lateral_m": 0.0, "speed_mps": 0.25}
    assert report["final_base_xy_yaw"] == [round(float(end[0]), 4), round(float(end[1]), 4), round(float(yaw), 5)]
    assert report["commanded_base_xy_yaw"] == [round(float(v), 4) for v in target]
    assert report["final_position_error_m"] == round(float(np.hypot(0.03, 0.012)), 4) == 0.0323
    assert report["final_yaw_error_deg"] == 2.051 and report["ended_in_double_support"] is True
    assert report["final_base_xy_yaw"][2] == 1.53499
    assert report["zmp_in_support_ratio"] == recorder.zmp_in_support_ratio and report["footsteps"] == []
    assert report["wpg_solve_ms_median"] == 1.2611 and report["wpg_solve_ms_p99"] == round(
        float(np.percentile([1.11111, 1.22222, 1.3, 3.00001], 99)), 4) == 2.949
    c, s = np.cos(0.3), np.sin(0.3)  # the ZMP error (0.04, −0.07) in the heading frame
    assert report["zmp_error_max_m"] == {"x": round(abs(c * 0.04 - s * 0.07), 5),
                                         "y": round(abs(-s * 0.04 - c * 0.07), 5)}
    assert report["grf_over_limit"] == {"left": False, "right": False}


def test_a_landing_is_measured_once_it_has_settled_and_not_before():
    walk = Walk()
    recorder = recorder_for(walk)
    walk.touchdowns.append(Touchdown(0.0126, Footstep("left", 0.312345, 0.09, 0.1)))
    run(walk, recorder, 1, 0.0)  # the touch-down is seen at the first tick
    assert recorder.log.arrays()["stance"].tolist() == [-1]  # double support: no stance foot
    settle = 0.0126 + SETTLE_AFTER_TOUCHDOWN
    walk.set(planned_zmp=[0.0, 0.0], measured_zmp=[0.0, 0.0], soles={"left": (0.312345, 0.09), "right": (0.0, -0.09)})
    recorder.on_state(SimpleNamespace(t=settle - 1e-6, states=[SimpleNamespace(t=settle - 1e-6)]))
    assert recorder.footsteps == []
    recorder.on_state(SimpleNamespace(t=settle, states=[SimpleNamespace(t=settle)]))
    assert recorder.footsteps == [{"side": "left", "t": 0.013, "planned": [0.3123, 0.09, 0.1],
                                   "realized": [0.3123, 0.09, 0.0]}]
    # Two touch-downs seen in one tick are measured in their order, after the first.
    walk.touchdowns += [Touchdown(0.3, Footstep("right", 0.6, -0.09, 0.0)),
                        Touchdown(0.3, Footstep("left", 0.9, 0.09, 0.0))]
    run(walk, recorder, round(0.2 / DT), 0.3)
    landed = [(f["side"], f["planned"][0]) for f in recorder.footsteps]
    assert landed == [("left", 0.3123), ("right", 0.6), ("left", 0.9)]
