"""DrawerRecorder: what the walk-and-reach drawer task is judged by, measured in the simulation.

Per tick: the measured base pose, each ankle pitch servo's demanded torque, the vertical ground
reaction forces and the drawer scene's ground truth (``JointState.scene``: opening, pull force,
grasp, both hands' distances to their targets); and what a demonstration is made of
(``eval/campaigns/feasible_demonstrations.py``): the measured joint angles, the base's full pose and its twist
in the heading frame. The report (:meth:`DrawerRecorder.report`):

- ``realized_step_lengths_m``: the measured pelvis advance along the start heading over each
  synthesized action, between the ticks at which the synthesis switched action, the last (standing)
  until the run's end: the hands' pull and reach may outlast the synthesized sequence (the
  synthesizer's own sum is ``planned_step_lengths_m``'s counterpart, not this);
- ``final_pelvis_to_drawer_m``: measured pelvis to the drawer's closed front panel, at the end;
  ``final_pelvis_lateral_m`` and ``final_pelvis_yaw_error_deg``: its offset across the cabinet's axis
  and its heading against the cabinet's (the task's frame: the start pose, or in a room the
  hand-over pose); in a room, ``approach``: the path planned (and planned again after a goal jump)
  and walked, when the sequence took over and the pelvis's and the stance's errors then against the
  hand-over pose;
- ``grasp``: ``"contact"`` once the left hand's fingers touched the handle (``"none"`` if they never
  did), ``grasp_time_s`` when; ``hand_to_handle_m``: left gripper base to the handle's grip point
  then (or its least value); ``hand_to_object_m``: right gripper base to the object's reach point
  at the end; ``hand_to_object_synth_only_m``: the synthesized arm angles alone, by forward
  kinematics at the measured pelvis pose and legs, against the same point;
- from the contacts: ``drawer_pull_force_peak_n`` (the robot's force on the drawer along its
  opening), ``grip_force_peak_n`` (the fingers' on the handle), ``handle_slip_max_m`` (how far the
  handle moved in the hand while held), ``object_lift_m`` and ``object_held`` (the object's height
  gain and its contact with the right hand's fingers, at the end), ``unintended_contacts`` (how many
  times the robot began touching the cabinet, its drawer, a wall or an object elsewhere than the left
  hand's fingers on the handle and the right hand's on the object), ``unintended_contact_s`` (for how
  long) and ``unintended_force_peak_n`` (the largest such force);
- ``synthesis_step_length_errors_m``: the synthesizer's own pelvis advance over each finished
  action less the length it planned (the synthesis alone, kinematic: what it would do with a robot
  that followed it exactly);
- ``drawer_opening_share``: the opening over the required clearance; ``drawer_travel_share``: over the
  slide's travel;
- ``success``: no fall, every step within ``STEP_TOLERANCE``, pelvis within ``COMFORT_TOLERANCE`` of
  the comfort distance, the drawer open by at least ``OPENED_SHARE`` of the required clearance (the
  benchmarks' 95 % of a joint's travel), the right hand within ``OBJECT_TOLERANCE`` of the object.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from robot_ctrl.geometry import SIDES, base_pose_xy_yaw, mean_yaw, relative_pose
from robot_ctrl.geometry.drawer_geometry import DRAWER_READINGS
from robot_ctrl.geometry.room import Approach, Box, CabinetPose, Room
from robot_ctrl.synthesis.step_planning import Action

STEP_TOLERANCE = 0.010  # [m] per action (thesis Fig. 3.41: below 10 mm)
COMFORT_TOLERANCE = 0.03  # [m]
OBJECT_TOLERANCE = 0.02  # [m]
OPENED_SHARE = 0.95  # of the required opening: the drawer counts as opened
PATH_EVERY = 0.25  # [s] between the realized path's points in the report


class DrawerRecorder:
    def __init__(self, commander, robot):
        """``commander``: the :class:`~robot_ctrl.control.commanders.walk_reach_commander.WalkReachCommander`."""
        self.commander, self.robot = commander, robot
        self._ankles = [robot.config.joint_index("ankle_pitch", s) for s in SIDES]
        self._grippers = [robot.config.joint_index("grippers", s) for s in SIDES]
        self.ankle_limit = robot.effort[self._ankles]
        # Each tick's measured state, turned into rows when asked for: off the tick's serial path (a
        # JointState is a snapshot: its arrays are the backend's copies).
        self.states: list = []
        self._arrays: tuple[int, dict[str, np.ndarray]] | None = None  # arrays() of the first n states
        # The last standing tick's synthesized arm angles and measured configuration, and the object.
        self._stand: tuple[tuple[np.ndarray, np.ndarray], np.ndarray] | None = None

    def on_command(self, tick) -> None:
        pass

    def on_state(self, tick) -> None:
        self.states.append(tick.states[0])
        c = self.commander
        if c.output is not None and c.output.action is Action.STAND:
            self._stand = c.synthesized_pose_at_measured(), c.targets.object(tick.t, c.opening)

    @property
    def synth_hand_error(self) -> float:
        """The synthesized arm angles alone at the last standing tick, by forward kinematics at the
        measured pelvis pose and legs: the right hand's distance to the object [m] (NaN: never stood)."""
        if self._stand is None:
            return np.nan
        pose, target = self._stand
        return float(np.linalg.norm(self.commander.body.hands(*pose)["right"] - target))

    def _row(self, s) -> np.ndarray:
        base = base_pose_xy_yaw(s.base_pos, s.base_quat_xyzw)
        tau = s.tau_demand if s.tau_demand is not None else s.tau
        grf = [float((s.foot_wrench or {}).get(side, np.zeros(6))[2]) for side in SIDES]
        scene = (s.scene if s.scene is not None else np.full(len(DRAWER_READINGS), np.nan))[:len(DRAWER_READINGS)]
        return np.concatenate([[s.t], base, tau[self._ankles], grf, s.q[self._grippers], scene])

    def arrays(self) -> dict[str, np.ndarray]:
        """Per tick: time, base pose, ankle pitch torques, vertical GRFs, gripper angles and the
        drawer's readings; built once for the report and the saved series (read-only)."""
        if self._arrays is None or self._arrays[0] != len(self.states):
            a = np.array([self._row(s) for s in self.states]).reshape(-1, 10 + len(DRAWER_READINGS))
            a.flags.writeable = False
            out = {"t": a[:, 0], "base": a[:, 1:4], "ankle_pitch_torque": a[:, 4:6], "grf": a[:, 6:8],
                   "gripper_q": a[:, 8:10]}
            out.update({name: a[:, 10 + i] for i, name in enumerate(DRAWER_READINGS)})
            self._arrays = len(self.states), out
        return dict(self._arrays[1])

    def body_arrays(self) -> dict[str, np.ndarray]:
        """Per tick: ``base_twist`` (vx, vy [m/s] in the base's heading frame, ωz [rad/s] about the
        world's z), ``base_pos`` [m] and ``base_quat_xyzw`` (world), ``joint_q`` [rad] (joint order)."""
        a = np.array([np.concatenate([heading_twist(s), s.base_pos, s.base_quat_xyzw, s.q]) for s in self.states],
                     dtype=np.float32).reshape(-1, 10 + self.robot.nj)
        return {"base_twist": a[:, :3], "base_pos": a[:, 3:6], "base_quat_xyzw": a[:, 6:10], "joint_q": a[:, 10:]}

    def report(self, fell: bool, geometry, slot: str, comfort: float, footsteps: list[dict] = ()) -> dict:
        """``footsteps``: the walk's, realized poses in the start frame (``WalkRecorder.footsteps``)."""
        c = self.commander
        plan = c.synth.plan if c.synth is not None else []
        planned = [p.length for p in plan[: max(len(c.boundaries) - 1, 0)]]
        a = self.arrays()
        times = [t for t, _ in c.boundaries]
        if c.boundaries and c.boundaries[-1][1] is Action.ENDED and len(a["t"]):
            times[-1] = float(a["t"][-1])  # standing lasts as long as the hands' work, past the sequence's end
        return drawer_outcome(a, times, planned, c.targets.advance, fell=fell,
                              required_opening=geometry.required_opening(slot), comfort=comfort,
                              ankle_limit=self.ankle_limit, travel=geometry.travel) | dict(
            actions=[action for _, action in c.boundaries if action],
            synthesis_step_length_errors_m=_round([h.end_progress - h.start_progress - h.planned_length
                                                   for h in (c.synth.history if c.synth is not None else [])
                                                   if h.end_progress is not None]),
            hand_to_object_synth_only_m=round(self.synth_hand_error, 4),
            replans=c.synth.replans if c.synth is not None else 0) | self._in_task_frame(a, footsteps)

    def _in_task_frame(self, a: dict[str, np.ndarray], footsteps) -> dict:
        """The measured pelvis against the task's frame (the cabinet's axis, facing it) at the end:
        its offset across the axis [m] and its heading error [deg]; in a room, the approach: the
        path planned and walked (start frame, every ``PATH_EVERY`` s) and the pelvis at the hand-over
        against the hand-over pose (the last planned: a goal jump plans the path again, ``replanned``)."""
        c = self.commander
        if not len(a["t"]):
            return {}
        frame = c.targets.start
        final = relative_pose(a["base"][-1], frame)
        out = dict(final_pelvis_lateral_m=_round(float(final[1]), 4),
                   final_pelvis_yaw_error_deg=_round(float(np.degrees(final[2])), 2))
        if c.approach is None:
            return out
        (_, first), plan = c.approach.plans[0], c.approach.approach
        k = min(int(np.searchsorted(a["t"], c.handed_over if c.handed_over is not None else np.inf)), len(a["t"]) - 1)
        at = relative_pose(a["base"][k], frame)
        dt = float(np.median(np.diff(a["t"]))) if len(a["t"]) > 1 else PATH_EVERY
        every = max(1, int(round(PATH_EVERY / dt)))
        walked = np.array([relative_pose(b, a["base"][0])[:2] for b in a["base"][::every]])
        out["approach"] = dict(
            planned_path_m=np.round(first.waypoints, 3).tolist(), path_length_m=round(first.length, 3),
            replanned=[dict(time_s=round(t, 3), planned_path_m=np.round(p.waypoints, 3).tolist(),
                            path_length_m=round(p.length, 3)) for t, p in c.approach.plans[1:]],
            failed=c.approach.failed,
            handover_pose=[round(float(plan.handover[0]), 3), round(float(plan.handover[1]), 3),
                           round(float(np.degrees(plan.handover[2])), 2)],
            handover_distance_m=round(plan.handover_distance, 4),
            handover_time_s=None if c.handed_over is None else round(c.handed_over, 3),
            handover_error=dict(along_m=_round(float(at[0]), 4), lateral_m=_round(float(at[1]), 4),
                                yaw_deg=_round(float(np.degrees(at[2])), 2)) | _stance_error(
                footsteps, c.handed_over, plan.handover),
            realized_path_m=np.round(walked, 3).tolist())
        return out

    def save(self, out_dir: Path) -> Path:
        """Append the drawer's series to the walk's ``timeseries.npz`` (action boundaries too)."""
        path = Path(out_dir) / "timeseries.npz"
        with np.load(path) as f:
            data = dict(f)
        a = self.arrays()
        data.update({f"drawer_{k}" if k in ("t", "base", "grf") else k: v for k, v in a.items()})
        data.update(self.body_arrays())
        data["ankle_pitch_limit_nm"] = self.ankle_limit
        data["action_starts"] = np.array([[t, action] for t, action in self.commander.boundaries]).reshape(-1, 2)
        np.savez_compressed(path, **data)
        return path


def heading_twist(s) -> np.ndarray:
    """The base's measured twist ``(vx, vy, ωz)``: linear velocity in its heading frame (x forward
    along its yaw, z up), yaw rate about the world's z, from a ``JointState``."""
    yaw = base_pose_xy_yaw(s.base_pos, s.base_quat_xyzw)[2]
    c, si = np.cos(yaw), np.sin(yaw)
    v = s.base_linvel
    x, y, z, w = s.base_quat_xyzw
    world_angvel_z = 2 * (x * z - w * y) * s.base_angvel[0] + 2 * (y * z + w * x) * s.base_angvel[1] + \
        (1 - 2 * (x * x + y * y)) * s.base_angvel[2]  # third row of the base's rotation matrix
    return np.array([c * v[0] + si * v[1], -si * v[0] + c * v[1], world_angvel_z])


def drawer_outcome(a: dict[str, np.ndarray], boundaries: list[float], planned: list[float],
                   advance: Callable[[np.ndarray], float], *, fell: bool, required_opening: float, comfort: float,
                   ankle_limit: np.ndarray, travel: float) -> dict:
    """The drawer task's measured figures and ``success`` from its logged arrays (``a``, as
    :meth:`DrawerRecorder.arrays` gives them): ``boundaries``, the times [s] at which the synthesis
    switched action; ``planned``, the synthesized lengths [m] of the actions between them;
    ``advance(base_xy)``, the pelvis advance [m] along the start heading of a measured base."""

    def advance_at(t: float) -> float:
        k = min(int(np.searchsorted(a["t"], t - 1e-9)), len(a["t"]) - 1)
        return advance(a["base"][k, :2])

    realized = [advance_at(t1) - advance_at(t0) for t0, t1 in zip(boundaries, boundaries[1:])]
    errors = [r - p for r, p in zip(realized, planned)]
    grasped = a["grasped"] > 0.5
    to_handle = a["left_hand_to_handle_m"]
    at_grasp = to_handle[np.argmax(grasped)] if grasped.any() else np.nanmin(to_handle)
    final_distance = float(a["cabinet_distance_m"][-1]) - advance_at(a["t"][-1])
    opening = float(a["drawer_opening_m"][-1])
    hand_to_object = float(a["right_hand_to_object_m"][-1])
    step_error = float(np.abs(errors).max()) if errors else None
    ankle = np.abs(a["ankle_pitch_torque"]).max(axis=0) / ankle_limit
    success = bool(not fell and step_error is not None and step_error <= STEP_TOLERANCE
                   and abs(final_distance - comfort) <= COMFORT_TOLERANCE and opening >= OPENED_SHARE * required_opening
                   and hand_to_object <= OBJECT_TOLERANCE)
    unintended = a["unintended_contacts"] > 0
    dt = float(np.median(np.diff(a["t"]))) if len(a["t"]) > 1 else 0.0
    return dict(
        success=success, planned_step_lengths_m=_round(planned), realized_step_lengths_m=_round(realized),
        step_length_errors_m=_round(errors), step_length_error_max_m=_round(step_error),
        comfort_distance_m=round(comfort, 4), final_pelvis_to_drawer_m=round(final_distance, 4),
        drawer_opening_m=round(opening, 4), drawer_opening_required_m=required_opening,
        drawer_opening_share=round(opening / required_opening, 3), drawer_travel_share=round(opening / travel, 3),
        drawer_pull_force_peak_n=round(float(np.nanmax(a["drawer_pull_force_n"])), 2),
        grip_force_peak_n=round(float(np.nanmax(a["grip_force_n"])), 2),
        handle_slip_max_m=round(float(np.nanmax(np.where(grasped, a["handle_slip_m"], 0.0))), 4),
        object_lift_m=_round(float(a["object_lift_m"][-1]), 4), object_held=bool(a["object_held"][-1] > 0.5),
        unintended_contacts=int(np.count_nonzero(unintended[1:] & ~unintended[:-1]) + unintended[0]),
        unintended_contact_s=round(float(np.count_nonzero(unintended)) * dt, 3),
        unintended_force_peak_n=round(float(np.nanmax(a["unintended_force_n"])), 1),
        grasp="contact" if grasped.any() else "none",
        grasp_time_s=round(float(a["t"][np.argmax(grasped)]), 3) if grasped.any() else None,
        hand_to_handle_m=round(float(at_grasp), 4), hand_to_object_m=round(hand_to_object, 4),
        peak_ankle_pitch_torque_ratio={side: round(float(r), 4) for side, r in zip(SIDES, ankle)})


def _stance_error(footsteps, t: float | None, pose: np.ndarray) -> dict:
    """The measured stance at time ``t`` (the midpoint of each foot's last realized footstep by then,
    their mean yaw) against ``pose`` (start frame): ``stance_along_m``, ``stance_lateral_m``,
    ``stance_yaw_deg``; none without both feet's footsteps. The pelvis sways over the last stance
    foot as the robot comes to stand: the feet say where it stands."""
    last = {step["side"]: step["realized"] for step in footsteps if t is not None and step["t"] <= t + 1e-9}
    if len(last) < len(SIDES):
        return {}
    feet = np.array([last[side] for side in SIDES])
    error = relative_pose(np.array([*feet[:, :2].mean(axis=0), mean_yaw(feet[:, 2])]), pose)
    return dict(stance_along_m=_round(float(error[0]), 4), stance_lateral_m=_round(float(error[1]), 4),
                stance_yaw_deg=_round(float(np.degrees(error[2])), 2))


def drawer_criteria(report: dict) -> dict[str, bool]:
    """Each drawer criterion of ``success`` (besides not falling) by name, met or not, from a report."""
    step, hand = report.get("step_length_error_max_m"), report.get("hand_to_object_m")
    pelvis, comfort = report.get("final_pelvis_to_drawer_m"), report.get("comfort_distance_m")
    opening, required = report.get("drawer_opening_m"), report.get("drawer_opening_required_m")
    return {"drawer opened": opening is not None and required is not None and opening >= OPENED_SHARE * required,
            "object reached": hand is not None and hand <= OBJECT_TOLERANCE,
            "steps within 10 mm": step is not None and step <= STEP_TOLERANCE,
            "pelvis at the comfort distance": pelvis is not None and comfort is not None
            and abs(pelvis - comfort) <= COMFORT_TOLERANCE}


def failed_criteria(report: dict) -> list[str]:
    """The names of the drawer criteria a report's run missed (:func:`drawer_criteria`)."""
    return [name for name, met in drawer_criteria(report).items() if not met]


def room_layout(cabinet: CabinetPose, room: Room, plan: Approach, footprint: Box, moves=()) -> dict:
    """Where the cabinet and the room's walls stood, start frame: the cabinet's pose, its outline on
    the floor (``footprint``, its frame), the room's inside corners [m], and where each goal jump
    (``moves``, :class:`~robot_ctrl.geometry.room.CabinetMove`) put the cabinet."""

    def pose(c: CabinetPose) -> dict:
        return {"x_m": c.x, "y_m": c.y, "front_yaw_deg": round(float(np.degrees(c.front_yaw)), 2),
                "footprint_m": np.round(c.to_start(footprint.corners()), 3).tolist()}

    corners = np.round(plan.room.frame.to_start(plan.interior.corners()), 3).tolist()
    return {"cabinet": pose(cabinet),
            "room": {"width_m": room.width, "depth_m": room.depth, "against_wall": room.against_wall,
                     "corners_m": corners},
            "cabinet_moves": [{"time_s": m.time} | pose(m.pose) for m in moves]}


def _round(values, digits: int = 5):
    if values is None:
        return None
    if isinstance(values, float):
        return round(values, digits) + 0.0  # + 0.0: no "-0.0" in a report
    return [round(float(v), digits) + 0.0 for v in values]
