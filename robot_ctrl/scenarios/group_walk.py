"""Group walk: several robots in one MuJoCo world, each with its own walking controller, walking
side by side with their gaits coupled (:class:`~robot_ctrl.control.commanders.coupling_commander.CouplingCommander`).

The robots stand in a row along the world y axis, ``spacing`` metres apart, facing +x, and start
walking after random delays in [0, one gait cycle), so their step phases start at random. The
report has the certificate computed before the run, the phase dispersion R̂(t) with its fitted
empirical rate, the time after which all phase differences stay below ``sync_tolerance``, the
measured touch-down phase differences, and each robot's fall, torque and GRF figures.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from robot_ctrl.backends import open_group_hardware
from robot_ctrl.control.commanders.coupling_commander import CouplingCommander
from robot_ctrl.control.controllers.walking_controller import WalkingController, WalkingOptions
from robot_ctrl.control.loop.control_loop import ControlLoop
from robot_ctrl.crowd.group_walk_settings import GroupWalk, certified_coupling
from robot_ctrl.eval.recording import FallCriterion, RunMetrics
from robot_ctrl.eval.recording.recorders import Fell, MetricsRecorder, ProgressBar, TimeLimit
from robot_ctrl.eval.reports.group_walk_report import TouchdownRecorder, group_walk_report
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.sim.disturbances import Disturbances
from robot_ctrl.sim.mujoco_video import Video
from robot_ctrl.wpg.params import WalkParams

STAND_AFTER = 1.5  # [s] standing after the stop


def run_group_walk(robot: RobotModel, g: GroupWalk = GroupWalk(), hw_kind: str = "mujoco", *,
                   out_dir: Path | None = None, viewer: bool = False, video: Video | Path | None = None,
                   log: Callable[[str], None] = print, progress: bool = False, control_dt: float = 0.005,
                   disturbances: Disturbances = Disturbances()) -> dict:
    coupling, bridge, profile, conditions = certified_coupling(robot.name, g, WalkParams().step_period, log)
    starts = np.random.default_rng(g.seed).uniform(0.0, 2 * bridge.step_period, g.n)
    log("start delays [s]: " + " ".join(f"{s:.3f}" for s in starts))
    poses = [(0.0, float(y), 0.0) for y in (np.arange(g.n) - (g.n - 1) / 2) * g.spacing]
    with open_group_hardware(hw_kind, robot, poses, viewer, control_dt, video, disturbances) as (world, hws):
        for hw in hws:
            hw.configure()
        for hw in hws:
            hw.activate()
        world.open_viewer()
        states = [hw.read() for hw in hws]
        controllers = [WalkingController(robot, s, WalkingOptions(control_dt=control_dt)) for s in states]
        commander = CouplingCommander(controllers, coupling, bridge, g.speed, starts, g.coupled_time, log)
        metrics = [RunMetrics(robot.joint_names, robot.effort, FallCriterion(float(s.base_pos[2]))) for s in states]
        touchdowns = TouchdownRecorder(controllers)
        bar = ProgressBar(starts.max() + g.coupled_time + 2 * bridge.step_period + STAND_AFTER + 2.0, progress)
        stood = _StoodAfterStop(commander, controllers, 2 * bridge.step_period + STAND_AFTER)
        limit = TimeLimit(starts.max() + g.coupled_time + 20.0, "the group did not stop")
        loop = ControlLoop(hws, controllers, control_dt, commanders=[commander],
                           recorders=[MetricsRecorder(metrics), touchdowns, bar], stops=[Fell(metrics), stood, limit])
        try:
            result = loop.run(states)
        finally:
            bar.close()
        safety = [hw.report() for hw in hws]
    log(result.stop_reason)
    return group_walk_report(robot, g, commander, metrics, safety, touchdowns, conditions, profile, bridge, starts,
                             result, out_dir, log, disturbances.to_dict())


class _StoodAfterStop:
    """Stops once every robot's plan stands and the stop command is ``after`` seconds old."""

    def __init__(self, commander: CouplingCommander, controllers: list[WalkingController], after: float):
        self.commander, self.controllers, self.after = commander, controllers, after

    def reason(self, tick) -> str | None:
        since = self.commander.stopped_for(tick.t)
        if since is not None and since > self.after and all(c.standing for c in self.controllers):
            return f"t = {tick.t:6.2f} s  the group stopped and stood"
        return None
