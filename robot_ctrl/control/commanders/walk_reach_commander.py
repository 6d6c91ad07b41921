"""WalkReachCommander: the walk-and-reach synthesis drives a walking controller (thesis 3.8, Fig. 3.40).

The synthesizer (stage 1) runs at the control rate; what it gives reaches the controller only
through its command API:

- pelvis velocity → the pattern generator's velocity reference, at every WPG sample. The MPC plans
  with one velocity over its 1.6 s horizon, so it gets the mean of the synthesizer's own rollout
  (:meth:`Synthesizer.preview`) over the next step within the action under way, not the in-cycle
  signal (whose sway and speed
  dips the MPC's own gait makes), plus a feedback of the planned pelvis's lag behind the
  synthesized advance, so that each action ends where the synthesis planned it;
- actions ↔ gait: the synthesis starts at a touch-down and one action is two steps; the gait's
  time scale follows the duration of the action under way (``set_time_scale``). The walk before
  (the WPG's start from standing and ``WALK_IN_STEPS`` steps at the first action's mean speed) is
  not part of the synthesis: the thesis's robot sequences also start after a step. At the last
  short cycle the controller is told to stop with the pelvis at the comfort distance (``stop_at``);
- upper-body angles → the posture task now and the dynamic filter's preview (``posture(t)`` over
  the horizon from the same rollout);
- the hands' final approach, the grasp and the pull: :class:`~robot_ctrl.control.commanders.drawer_hands.DrawerHands`;
- from the last short cycle on, the CoM leans by what the reaching arms move it ahead of the pelvis
  (``shift_balance``), so that the pelvis, not the CoM, ends at the comfort distance;
- the synthesis's clock is coupled to the measured body at the end of the approach: over the last
  short cycle's second half the leader oscillator slows while the measured pelvis lags the
  synthesized one, so that standing begins when the pelvis has come to rest.

In a room, an :class:`~robot_ctrl.control.commanders.approach_walk.ApproachWalk` first walks the robot
round to the hand-over pose in front of the cabinet; all of the above begins once it stands there.

Frames: ``start`` is the task's frame: the base's world pose (x, y, yaw) at the start, or the
hand-over pose in a room; distances are along its heading.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from robot_ctrl.control.commanders.approach_walk import ApproachWalk
from robot_ctrl.control.commanders.drawer_hands import DrawerHands
from robot_ctrl.control.commanders.drawer_targets import DrawerTargets
from robot_ctrl.control.commanders.synthesized_body import SynthesizedBody
from robot_ctrl.control.controllers.walking_controller import PlanSample, WalkingController
from robot_ctrl.geometry import SIDES, minimum_jerk, rotation
from robot_ctrl.kernels import FLOAT, MATRIX, VECTOR, kernel
from robot_ctrl.synthesis.primitives import WalkReachPrimitives
from robot_ctrl.synthesis.step_planning import BETA, Action
from robot_ctrl.synthesis.synthesizer import SynthesisOutput, SynthesisPreview, Synthesizer, WalkReachGoal
from robot_ctrl.wpg.footstep import stance_at

POSITION_GAIN = 2.5  # [1/s] feedback of the planned pelvis's lag behind the synthesized advance
WALK_IN_STEPS = 2  # the synthesis starts at this touch-down, the gait at its steady speed
WALK_IN_BLEND = 1.2  # [s] the upper body blends from its start posture to the synthesis's first one
PREVIEW_DT = 0.02  # [s] step of the synthesizer's rollout for the WPG and the filter
MIN_PREVIEW = 0.2  # [s] of the synthesizer's rollout averaged for the MPC's velocity, at least
MAX_ACTION_TIME = 4.0  # [s] longer than any learned action
STANCE_SHARE = 0.5  # of the reach's final CoM shift taken by placing the stop stance ahead
MAX_STANCE_SHIFT = 0.04  # [m]
PELVIS_GAIN = 1.0  # [1/s] standing: integral gain of the measured pelvis's error into the lean
SLOWING_LAG = 0.03  # [m] measured pelvis lag at which the synthesis runs at MIN_SYNTHESIS_RATE
#: A speed class faster than the learned one decelerates the synthesized pelvis sooner than the
#: robot can follow (at 1.2 the pelvis arrived about 1 cm after the standing action began): its
#: slowing starts at SLOWING_LAG / scale**FAST_SLOWING_EXPONENT of lag (measured on the fast trials,
#: docs/campaigns.md).
FAST_SLOWING_EXPONENT = 4
MIN_SYNTHESIS_RATE = 0.2
STAND_BLEND_PHASE = (2 - BETA) * np.pi  # [rad] of the last short cycle: its blend into standing begins
STAND_READY_LAG = 0.002  # [m]
MAX_STAND_WAIT = 1.0  # [s]
GRASP_TIMEOUT = 2.0  # [s] after the sequence, a hand that never got hold of the handle gives up


def gait_time_scale(controller: WalkingController, duration: float, speed: float) -> float:
    """The gait's time scale for an action of ``duration`` [s] of synthesis time played ``speed``
    times as fast: one action is two steps."""
    period = 2 * controller.params.step_period
    return float(np.clip(duration / speed / period, 0.5, 2.0))


def step_synthesis(synth: Synthesizer, dt: float, goal: WalkReachGoal, t: float,
                   boundaries: list[tuple[float, Action]]) -> SynthesisOutput | None:
    """Advance ``synth`` by ``dt`` [s] of its time towards ``goal``; an action that starts, or the
    sequence's end (``Action.ENDED``), is appended to ``boundaries`` at time ``t`` [s]. Returns the new
    output, None once the sequence has ended."""
    index = synth.action_index
    output = synth.step(dt, goal)
    if synth.finished:
        boundaries.append((t, Action.ENDED))
        return None
    if synth.action_index != index:
        boundaries.append((t, synth.plan[synth.action_index].action))
    return output


class WalkReachCommander:
    def __init__(self, controller: WalkingController, primitives: WalkReachPrimitives, targets: DrawerTargets,
                 log: Callable[[str], None] = print, *, speed: float = 1.0, position_feedback: bool = True,
                 approach: ApproachWalk | None = None):
        """``speed``: the synthesis's time runs this many times the robot's (``modes.SpeedClass``):
        its durations are divided by it, its pelvis velocities multiplied, its lengths kept.
        ``position_feedback`` False turns off the four loops that bring the measured pelvis to where
        the synthesis planned it (the lag feedback into the WPG's velocity, the stop at the final
        footsteps, the synthesis clock waiting for the pelvis, the standing lean): the WPG then gets
        the synthesized velocity alone and a zero velocity once the robot should stand, and what the
        task achieves is the synthesis's own (thesis Fig. 3.41 without the controller's help).
        ``approach``: in a room, the walk to the pose where the sequence takes over (``targets``'
        start frame); the sequence begins once the robot stands there."""
        self.controller, self.primitives, self.targets, self.log = controller, primitives, targets, log
        self.speed = speed
        self.position_feedback = position_feedback
        self._slowing_lag = SLOWING_LAG / max(speed, 1.0) ** FAST_SLOWING_EXPONENT
        self.body = SynthesizedBody(controller.robot)
        self.hands = DrawerHands(controller, targets, self.body)
        self.base_posture = controller.start_posture.copy()
        self._posture_now = self.base_posture.copy()
        self._preview: SynthesisPreview | None = None
        self._preview_t = 0.0
        self.approach = approach
        self.synth: Synthesizer | None = None
        self.synth_start_advance = 0.0  # measured pelvis advance when the synthesis started [m]
        self.output = None  # the synthesizer's last output of a running sequence
        self.stopping_at: float | None = None  # the pelvis advance the controller was told to stop at [m]
        self.boundaries: list[tuple[float, Action]] = []  # (time [s], action) at each action start, ENDED at the end
        self._stance_shift = 0.0  # [m] the stop stance ahead of the pelvis's target (:meth:`_stop`)
        self._lean_integral = 0.0  # [m]
        self._stood_at: float | None = None  # [s] when the plan stood on its stop footsteps
        self._waiting_for_pelvis = False  # standing begins once the pelvis has arrived
        self.t = 0.0
        self.handed_over: float | None = None  # [s] when the synthesized sequence's walk began
        controller.set_upper_body(self.posture)
        if approach is None:
            self._walk_off(0.0)
        controller.on_sample(self._on_sample)

    def _walk_off(self, t: float) -> None:
        """Walk off from standing at the task's start at the first action's mean speed until the
        synthesis starts; meanwhile the upper body blends to the synthesis's first posture."""
        c, start = self.controller, self.targets.start
        self.handed_over = t
        self._touchdowns_before = len(c.touchdowns)
        self.feet_offset = {s: rotation(start[2]).T @ (f.xy - start[:2]) for s, f in c.footsteps().items()}
        self._com_from_pelvis = c.reference_com()[:2] - c.reference_configuration()[:2]  # world axes
        self._com_offset = float(self._com_from_pelvis @ self.targets.forward[:2])
        dry = Synthesizer(self.primitives, self._goal(t))
        first = dry.plan[0]
        self._walk_in_posture = self.base_posture.copy()
        self._walk_in_posture[self.body.upper] = dry.step(c.dt).upper_body_q
        c.set_time_scale(gait_time_scale(c, first.duration, self.speed))
        c.set_velocity(self.speed * first.length / first.duration, 0.0, 0.0)

    def advance(self) -> float:
        """Measured pelvis advance along the start heading [m]."""
        est = self.controller.estimate
        return 0.0 if est is None else self.targets.advance(est.base_xy_yaw)

    def synthesized_pose_at_measured(self) -> tuple[np.ndarray, np.ndarray]:
        """The synthesized arm angles alone and the measured configuration (pelvis pose and legs),
        for ``body.hands``."""
        return self.output.upper_body_q, self.controller.estimate.configuration

    @property
    def opening(self) -> float:
        """How far the hand has pulled the drawer, measured [m]."""
        return self.hands.opening

    @property
    def done(self) -> bool:
        """The task is over: the sequence ended, the drawer is pulled, the robot stands."""
        return self.finished and self.controller.standing

    @property
    def finished(self) -> bool:
        """The sequence has ended, the drawer is pulled and the right hand at the object (or the left
        hand never got hold of the drawer)."""
        if self.synth is None or not self.synth.finished:
            return False
        return self.hands.reached or (not self.hands.holding and self.t - self.boundaries[-1][0] > GRASP_TIMEOUT)

    def _goal(self, t: float) -> WalkReachGoal:
        """The drawer in the synthesizer's start frame (the pelvis where the synthesis started)."""
        return WalkReachGoal(self.targets.distance(t) - self.synth_start_advance, self.targets.slot)

    # The posture the controller's IK and dynamic filter follow ----------------------------------
    def posture(self, t: float) -> np.ndarray:
        """Posture-task target (joint order) at time ``t`` [s]: the synthesized upper body, from the
        rollout for times ahead of now."""
        if self._preview is None or t <= self.t + 1e-9:
            return self._posture_now
        q = self._posture_now.copy()
        p = self._preview
        times = self._preview_t + p.t / self.speed
        q[self.body.upper] = interpolated_row(t, times, p.upper_body_q)
        return q

    # Per tick -------------------------------------------------------------------------------------
    def begin_tick(self, t: float) -> None:
        self.t = t
        for jump in self.targets.jumps:
            if abs(t - jump.time) < self.controller.dt / 2:
                self.log(f"t = {t:6.2f} s  the drawer moved to {jump.distance:.2f} m")
        if self.synth is None:
            if self.handed_over is None:  # on the approach: the start posture
                return
            s, _ = minimum_jerk(t - self.handed_over, WALK_IN_BLEND)
            self._posture_now = self.base_posture + s * (self._walk_in_posture - self.base_posture)
            return
        rate = 0.0 if self.synth.finished else self._synthesis_rate()
        if rate > 0.0:
            output = step_synthesis(self.synth, self.controller.dt * rate * self.speed, self._goal(t), t, self.boundaries)
            if output is not None:
                self.output = output
        share = 1.0 if self.synth.finished else self.output.phase / (2 * np.pi)
        upper = self.output.upper_body_q
        self._posture_now = self.base_posture.copy()
        self._posture_now[self.body.upper] = upper
        if self.output.action is Action.STAND or self.synth.finished:  # the hands' work outlasts the sequence
            self.hands.stand(t, share, upper, self._posture_now, self._final_upper)
        elif self._last_short:
            self.hands.reach(t, share, upper, self._posture_now, self._final_upper)
        self._lean(share)

    def _synthesis_rate(self) -> float:
        """How fast the synthesis's time runs against the robot's. Over the second half of the last
        short cycle, the leader oscillator slows while the measured pelvis lags the synthesized one:
        the synthesized pelvis comes to rest at once, the walking robot's settles over about half a
        second, and the next action (standing, the pull) must not begin before it has. Its blend into
        standing waits (rate 0) while the robot still steps (a stop can take a step more than the
        synthesis planned, when a landing missed its stop footstep), then while the standing pelvis
        is more than ``STAND_READY_LAG`` short of where the stop must leave it (at most
        ``MAX_STAND_WAIT``; the lean integrates the rest out meanwhile)."""
        self._waiting_for_pelvis = False
        if not self.position_feedback or self.output is None or not self._last_short or self.output.phase < np.pi:
            return 1.0
        lag = self.synth_start_advance + self.synth.progress - self.advance()
        if self.output.phase >= STAND_BLEND_PHASE:
            if not self.controller.standing:
                self._stood_at = None
                return 0.0
            self._stood_at = self.t if self._stood_at is None else self._stood_at
            short_of_stop = self.stopping_at - self.advance()  # where standing must begin, not where the synthesis is
            self._waiting_for_pelvis = short_of_stop > STAND_READY_LAG and self.t - self._stood_at < MAX_STAND_WAIT
            if self._waiting_for_pelvis:  # the lean takes the lag out meanwhile (_lean)
                return 0.0
        return float(np.clip(1.0 - lag / self._slowing_lag, MIN_SYNTHESIS_RATE, 1.0))

    @property
    def _last_short(self) -> bool:
        return self.synth.plan[self.synth.action_index].action is Action.SHORT and \
            self.synth.action_index == len(self.synth.plan) - 2

    def _final_upper(self) -> np.ndarray:
        """The upper-body angles at the end of the sequence (the synthesizer's rollout)."""
        if self.synth.finished:
            return self.output.upper_body_q
        return self.synth.preview(2 * MAX_ACTION_TIME, PREVIEW_DT).upper_body_q[-1]

    def _lean(self, share: float) -> None:
        """From the last short cycle on, lean the CoM by what the synthesized arms move it against the
        pelvis, less the stance's own forward shift (:meth:`_stop`), so that the pelvis ends at the
        comfort distance with the ZMP a few centimetres off the soles' centre; standing, and while
        standing waits for the pelvis (:meth:`_synthesis_rate`), the measured pelvis's remaining
        error is integrated in as well."""
        c = self.controller
        if self.stopping_at is None:
            return
        s = 1.0 if self.output.action is Action.STAND else minimum_jerk(share, 0.5)[0]
        forward = self.targets.forward[:2]
        arms = c.reference_com()[:2] - c.reference_configuration()[:2] - self._com_from_pelvis - forward * self._stance_shift
        if self.output.action is Action.STAND or self._waiting_for_pelvis:
            self._lean_integral += PELVIS_GAIN * c.dt * (self.stopping_at - self.advance())
        c.shift_balance(s * arms + self._lean_integral * forward)

    # Per WPG sample -------------------------------------------------------------------------------
    def _on_sample(self, sample: PlanSample) -> None:
        c = self.controller
        if self.handed_over is None:
            self.approach.steer(sample)
            if self.approach.done:
                self.log(f"t = {sample.t:6.2f} s  hand-over: the synthesized walk-and-reach begins")
                self._walk_off(sample.t)
            return
        if self.synth is None:
            if len(c.touchdowns) - self._touchdowns_before < WALK_IN_STEPS:
                return
            self._start_synthesis(sample)
        if self.synth.finished or self.synth.plan[self.synth.action_index].action is Action.STAND:
            if not self.position_feedback:
                c.set_velocity(0.0, 0.0, 0.0)  # the WPG's own stop: the next footstep, then one beside it
            if self.synth.finished:
                return
        plan = self.synth.plan[self.synth.action_index]
        self._preview = self.synth.preview(c.params.horizon * c.params.sample_time * self.speed, PREVIEW_DT)
        self._preview_t = sample.t
        if plan.action is Action.STAND:
            return
        c.set_time_scale(gait_time_scale(c, plan.duration, self.speed))
        if self._last_short and self.position_feedback:
            target = self.synth_start_advance + self.synth.targets[-1]
            if self.stopping_at != target:
                self._stop(target, sample.t)
            return
        # The next step, within the action under way: the MPC must not slow this action for the
        # next, when a replan made the next ones shorter.
        remaining = (1.0 - self.output.phase / (2 * np.pi)) * plan.duration if self.output is not None else plan.duration
        ahead = self._preview.t <= max(min(plan.duration / 2, remaining), MIN_PREVIEW * self.speed)  # synthesis time
        v = self.speed * self._preview.pelvis_velocity[ahead].mean(axis=0)
        lag = self.synth_start_advance + self.synth.progress - self._planned_advance(sample)
        c.set_velocity(float(v[0] + (POSITION_GAIN * lag if self.position_feedback else 0.0)), 0.0, 0.0)

    def _stop(self, target: float, t: float) -> None:
        """Stop with the pelvis ``target`` [m] from the start. The synthesized reach moves the CoM
        forward of the pelvis (the arms go out); the stance is put forward by ``STANCE_SHARE`` of that
        shift at the end of the sequence, so the lean that keeps the pelvis in place stays small."""
        c = self.controller
        final = self.body.com_from_pelvis(self._final_upper(), c.reference_configuration()) - self._com_from_pelvis
        forward = self.targets.forward[:2]
        self._stance_shift = float(np.clip(final @ forward * STANCE_SHARE, 0.0, MAX_STANCE_SHIFT))
        self.stopping_at = target
        ahead = target + self._stance_shift
        c.stop_at(*stance_at(self.targets.start, {s: self.feet_offset[s] + [ahead, 0.0] for s in SIDES}))
        self.log(f"t = {t:6.2f} s  last short cycle: stopping with the pelvis {target:.3f} m from the start "
                 f"(feet {self._stance_shift * 100:.1f} cm ahead of it for the reach)")

    def _planned_advance(self, sample: PlanSample) -> float:
        return self.targets.advance(sample.com_xy) - self._com_offset

    def _start_synthesis(self, sample: PlanSample) -> None:
        t = sample.t
        self.synth_start_advance = self.advance()
        # The plan's CoM leads the pelvis by what the walking posture puts ahead of it: measured here,
        # at a touch-down, as every action boundary is.
        self._com_offset = self._planned_advance(sample) + self._com_offset - self.synth_start_advance
        self.synth = Synthesizer(self.primitives, self._goal(t), self.controller.dt * self.speed)
        self.boundaries.append((t, self.synth.plan[0].action))
        self.log(f"t = {t:6.2f} s  synthesis starts {self.synth_start_advance:.3f} m from the start: actions "
                 f"{[p.action for p in self.synth.plan]}, lengths {[round(p.length, 3) for p in self.synth.plan]} m")


@kernel((FLOAT, VECTOR, MATRIX))
def interpolated_row(t, times, values):
    """``np.interp(t, times, values[:, j])`` for every column ``j`` at once (the same arithmetic:
    the end values outside ``times``, ``slope (t − tᵢ) + vᵢ`` between); ``times`` increasing.
    Compiled: a posture ahead of now is asked on every tick, a dozen joints of the rollout."""
    n, columns = values.shape
    if t < times[0]:
        return values[0].copy()
    if t >= times[n - 1]:
        return values[n - 1].copy()
    i = np.searchsorted(times, t, side="right") - 1
    if t == times[i]:
        return values[i].copy()
    out = np.empty(columns)
    for j in range(columns):
        slope = (values[i + 1, j] - values[i, j]) / (times[i + 1] - times[i])
        out[j] = slope * (t - times[i]) + values[i, j]
        if np.isnan(out[j]):
            out[j] = slope * (t - times[i + 1]) + values[i + 1, j]
            if np.isnan(out[j]) and values[i, j] == values[i + 1, j]:
                out[j] = values[i, j]
    return out
