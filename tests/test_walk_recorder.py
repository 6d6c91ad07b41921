"""What a walk report measures, fed synthetic ticks with a known answer: the ZMP in the support
polygon and the realized footsteps come from the measured state, never from the plan."""

from types import SimpleNamespace

import numpy as np
import pinocchio as pin

from robot_ctrl.control.estimator import Estimate
from robot_ctrl.eval.walk_log import WalkLog
from robot_ctrl.eval.walk_recorder import SETTLE_AFTER_TOUCHDOWN, WalkRecorder
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
