"""WalkingPatternGenerator: gait state machine around the walking MPC, sampled at the control rate.

Gait phases (:class:`~robot_ctrl.wpg.plan.GaitPhase`): ``STAND`` (double support, indefinitely) →
``TRANSFER`` (double support that moves the ZMP onto the first stance foot) → ``SINGLE`` support
(the other foot swings to the MPC's first footstep) ↔ ``DOUBLE`` support after each touch-down.
A zero velocity reference while walking stops in two steps: the next footstep is still optimized,
the one after it is placed beside it (``step_width`` apart, parallel), then the robot stands in
double support with the ZMP reference moving to the middle of the feet. :meth:`stop_at` instead places those two last
footsteps at given positions, taking as many steps as the reach region requires (stopping at a
goal pose).

Every sample :meth:`update` solves the MPC from the generator's own planned CoM state
(balance feedback acts on the controller side, which may move that state: :meth:`shift`,
:meth:`add_com_velocity`) and advances the plan by one sample. :meth:`sample` interpolates it at
any time inside the current sample (a :class:`~robot_ctrl.wpg.plan.WalkReference`), :meth:`preview`
gives the solved plan over the horizon (a :class:`~robot_ctrl.wpg.plan.PlanPreview`).
All positions are in the world frame; the floor is z = 0.

Gait timing can be stretched online: with :meth:`set_time_scale` ``s``, every gait duration of
``WalkParams`` (samples, single and double support) lasts ``s`` times its nominal value from the
next sample on. The gait state machine counts *nominal* time; the LIP, the velocity reference and
the clock use physical time. This is how a crowd coupling sets the step period (``crowd.gait_bridge``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from robot_ctrl.geometry import GRAVITY, PlanarMove, Side, left_sign, mean_yaw, other, rotation, wrap_angle
from robot_ctrl.wpg.footstep import FootRef, Footstep
from robot_ctrl.wpg.lipm import com_at, dcm, natural_frequency
from robot_ctrl.wpg.mpc import MpcInfeasible, MpcProblem, MpcSolution, Reach, SampleSupports, WalkingMPC
from robot_ctrl.wpg.params import WalkParams
from robot_ctrl.wpg.plan import GaitPhase, PlanPreview, PreviewSample, SolePlan, Touchdown, WalkReference
from robot_ctrl.wpg.segments import Segment, blend, horizon_supports, midpoint, packed_segments, segment_at, swing_point
from robot_ctrl.wpg.swing import SwingTrajectory

#: [m] a foot this close to its stop footstep (in x and in y) is there: the plan follows the real
#: feet (``shift``), which land within millimetres of where they were sent, never exactly, and a
#: step to correct less than this would land as far off again, moving the robot while its hands
#: work.
STOP_TOLERANCE = 0.01
#: [rad] the same for a foot's yaw: a landed sole turns by a few milliradians on the floor, and the
#: plan that follows it would otherwise step in place for ever to take them out.
STOP_YAW_TOLERANCE = 0.02

Landing = tuple[int, FootRef, FootRef | None]  # footstep variable index, the foot, the footstep it is fixed to


@dataclass(frozen=True)
class _SolvedSample:
    """The sample the MPC last solved, as it stood when solved: what :meth:`~WalkingPatternGenerator.sample`,
    :meth:`~WalkingPatternGenerator.preview` and :meth:`~WalkingPatternGenerator.gait_phase` read."""

    com_x: np.ndarray  # (3,) CoM position, velocity, acceleration at the sample's start [m, m/s, m/s²]
    com_y: np.ndarray
    jerk_x: float  # [m/s³] over the sample
    jerk_y: float
    phase: GaitPhase
    phase_time: float  # [s] nominal time into the phase
    stance: str
    swing: SwingTrajectory | None
    time_scale: float
    steps_started: int
    segments: tuple[Segment, ...]  # the support segments over the horizon


class WalkingPatternGenerator:
    def __init__(self, params: WalkParams, left: Footstep, right: Footstep, com_xy: np.ndarray):
        if not params.resolved:
            raise ValueError("the pattern generator needs WalkParams with the robot's com_height, foot size and "
                             "step_width (WalkParams.for_robot)")
        self.p = params
        self.mpc = WalkingMPC(params)
        self.t = 0.0  # start time of the current sample [s]
        self.com_x = np.array([com_xy[0], 0.0, 0.0])
        self.com_y = np.array([com_xy[1], 0.0, 0.0])
        self.feet = {"left": left, "right": right}
        self.heading = mean_yaw([left.yaw, right.yaw])
        self.phase = GaitPhase.STAND
        self.phase_time = 0.0
        self.stance = "right"
        self.steps_to_stop = 0  # landings left before standing (0: not stopping)
        self.stop_feet: dict[Side, Footstep] | None = None  # where the feet must end when stopping at a pose
        self.velocity = np.zeros(3)  # (vx, vy, ωz) in the heading frame
        self.swing: SwingTrajectory | None = None
        self.settle_from: FootRef | None = None  # ZMP start of the last transfer to standing
        self.solution: MpcSolution | None = None
        self.touchdowns: list[Touchdown] = []
        self.solve_times: list[float] = []
        self._last_duration = params.sample_time
        self.time_scale = 1.0  # physical / nominal duration of the gait, for the next samples
        self.steps_started = 0  # single-support phases begun so far
        self._retarget_late = False  # the next update may move the landing inside swing_freeze
        self._solved = _SolvedSample(self.com_x.copy(), self.com_y.copy(), 0.0, 0.0, self.phase, 0.0, self.stance,
                                     None, 1.0, 0, ())

    # Reference --------------------------------------------------------------------------------
    def set_velocity(self, vx: float, vy: float, wz: float) -> None:
        """Reference pelvis velocity in the heading frame: vx, vy [m/s], ωz [rad/s]. A walk from
        standing starts along the way the feet stand (a stop at turned footsteps turned them)."""
        v = np.array([vx, vy, wz], dtype=float)
        if not np.all(np.isfinite(v)):
            raise ValueError(f"velocity reference must be finite, got {v}")
        moving = bool(np.any(np.abs(v) > 1e-6))
        if moving and self.phase is GaitPhase.STAND:
            self.heading = mean_yaw([self.feet["left"].yaw, self.feet["right"].yaw])
            self.stance = "left" if (vy < 0 or (vy == 0 and wz < 0)) else "right"
            self.phase, self.phase_time = GaitPhase.TRANSFER, 0.0
        elif not moving and self.phase is GaitPhase.TRANSFER:
            self.phase, self.phase_time = GaitPhase.STAND, 0.0
        elif not moving and self.phase.stepping and self.steps_to_stop == 0:
            self.steps_to_stop = 2
        elif moving and self.steps_to_stop:
            self.steps_to_stop = 0
            self.stop_feet = None
        self.velocity = v

    def set_time_scale(self, scale: float) -> None:
        """Stretch the gait: from the next sample on, each sample and support phase lasts ``scale``
        times its nominal duration (step period ``scale · step_period``)."""
        if not (np.isfinite(scale) and 0.5 <= scale <= 2.0):
            raise ValueError(f"time_scale = {scale} is outside the allowed range [0.5, 2.0]")
        self.time_scale = float(scale)

    @property
    def sample_duration(self) -> float:
        """Physical duration [s] of the next sample."""
        return self.p.sample_time * self.time_scale

    @property
    def sample_start(self) -> float:
        """Start time [s] of the last solved sample (the one :meth:`sample` interpolates)."""
        return self.t - self._last_duration

    def stop_at(self, left: Footstep, right: Footstep) -> None:
        """Stop with the feet at these footsteps: each next landing goes to its foot's stop footstep,
        clamped into the reach region of the previous foot, until both feet are there (if the QP is
        infeasible with them, the generator falls back to a plain stop)."""
        self.set_velocity(0.0, 0.0, 0.0)
        if self.steps_to_stop:
            self.stop_feet = {"left": left, "right": right}

    @property
    def standing(self) -> bool:
        return self.phase is GaitPhase.STAND

    # Horizon ----------------------------------------------------------------------------------
    def _segments(self) -> tuple[list[Segment], list[Landing]]:
        """Support segments from now over the horizon, and the landings (index, foot, fixed-to)."""
        p = self.p
        known = {side: FootRef.known(step) for side, step in self.feet.items()}
        segments: list[Segment] = []
        landings: list[Landing] = []
        left, right = known["left"], known["right"]
        remaining = {GaitPhase.TRANSFER: p.start_transfer, GaitPhase.SINGLE: p.single_support,
                     GaitPhase.DOUBLE: p.double_support}
        if self.phase is GaitPhase.STAND:
            zmp_from = self.settle_from or midpoint(left, right)
            segments.append(Segment(max(p.start_transfer - self.phase_time, 0.0), [left, right], zmp_from,
                                     midpoint(left, right)))
            segments.append(Segment(np.inf, [left, right], midpoint(left, right)))
            return segments, landings
        stance = known[self.stance]
        left_in_phase = remaining[self.phase] - self.phase_time
        if self.phase is GaitPhase.TRANSFER:
            mid = midpoint(left, right)
            start = blend(mid, stance, self.phase_time / p.start_transfer)
            segments.append(Segment(left_in_phase, [left, right], start, stance))
            segments.append(Segment(p.single_support, [stance], stance))
            t_land = left_in_phase + p.single_support
        elif self.phase is GaitPhase.SINGLE:
            segments.append(Segment(left_in_phase, [stance], stance))
            t_land = left_in_phase
        else:  # double: the stance foot has just landed, the previous one is still down
            prev = known[other(self.stance)]
            segments.append(Segment(left_in_phase, [prev, stance], prev, stance))
            segments.append(Segment(p.single_support, [stance], stance))
            t_land = left_in_phase + p.single_support
        horizon = p.sample_time * p.horizon
        previous = stance
        index = 0
        while t_land < horizon and index < 2:
            side = other(previous.side)
            heading = self.heading + self.velocity[2] * t_land * self.time_scale
            yaw = previous.yaw + min(max(wrap_angle(heading - previous.yaw), -p.max_yaw_step), p.max_yaw_step)
            if self.stop_feet is not None:
                fixed = FootRef.known(self._toward_goal(previous, side))
                final = self._at_goal(fixed) and self._at_goal(previous)
            else:
                final = self.steps_to_stop and index == self.steps_to_stop - 1
                fixed = previous.beside(p.step_width) if final else None
            foot = fixed if fixed is not None else FootRef.variable(index, side, float(yaw))
            landings.append((index, FootRef.variable(index, side, foot.yaw), fixed))
            if final:
                segments.append(Segment(np.inf, [previous, foot], previous, midpoint(previous, foot)))
                return segments, landings
            segments.append(Segment(p.double_support, [previous, foot], previous, foot))
            segments.append(Segment(p.single_support, [foot], foot))
            previous = foot
            t_land += p.step_period
            index += 1
        return segments, landings

    def _toward_goal(self, previous: FootRef, side: Side) -> Footstep:
        """The stop footstep of ``side``, clamped into the reach region (and yaw step) of ``previous``."""
        goal = self.stop_feet[side]
        yaw = previous.yaw + min(max(wrap_angle(goal.yaw - previous.yaw), -self.p.max_yaw_step), self.p.max_yaw_step)
        local = rotation(previous.yaw).T @ (goal.xy - previous.offset)
        box = self._reach_box(side)
        local = np.clip(local, [box[0], box[2]], [box[1], box[3]])
        x, y = previous.offset + rotation(previous.yaw) @ local
        return Footstep(side, float(x), float(y), float(yaw))

    def _at_goal(self, foot: FootRef) -> bool:
        goal = self.stop_feet[foot.side]
        return (not foot.S.any() and np.allclose(foot.offset, goal.xy, atol=STOP_TOLERANCE)
                and abs(wrap_angle(foot.yaw - goal.yaw)) <= STOP_YAW_TOLERANCE)

    def problem(self) -> MpcProblem:
        """The MPC problem of the current sample, from the plan's own CoM state."""
        return self._problem(*self._segments())

    def _problem(self, segments: list[Segment], landings: list[Landing]) -> MpcProblem:
        p = self.p
        length, width = 2 * (p.foot_length / 2 - p.zmp_margin), 2 * (p.foot_width / 2 - p.zmp_margin)
        supports = SampleSupports(*horizon_supports(*packed_segments(segments), p.sample_time, p.horizon, length,
                                                    width))
        # The velocity reference, turned by the integrated yaw rate at each sample (world frame).
        heading = self.heading + self.velocity[2] * self.time_scale * p.sample_time * np.arange(1, p.horizon + 1)
        cos, sin = np.cos(heading), np.sin(heading)
        vx, vy = self.velocity[:2]
        velocity = np.empty((p.horizon, 2))
        velocity[:, 0], velocity[:, 1] = cos * vx - sin * vy, sin * vx + cos * vy
        stance = FootRef.known(self.feet[self.stance])
        reach, fixed = [], {}
        nominal = np.zeros(4)
        previous = stance
        for index, foot, fix in landings:
            reach.append(Reach(index, previous, self._reach_box(foot.side)))
            if fix is not None:
                fixed[index] = fix
            # Footstep reference: forward, each step advances vx T_step; sideways the feet cannot cross
            # inside step_width, so the leading foot takes the whole 2 vy T_step and the trailing one
            # comes back to step_width.
            sign = left_sign(foot.side)
            vx, vy = self.velocity[:2]
            period = p.step_period * self.time_scale
            lateral = sign * p.step_width + (2.0 * vy * period if sign * vy > 0 else 0.0)
            step = rotation(foot.yaw) @ np.array([vx * period, lateral])
            nominal[2 * index : 2 * index + 2] = previous.position(nominal) + step
            previous = foot
        for index in range(len(landings), 2):  # footsteps beyond the horizon: kept at the stance foot
            nominal[2 * index : 2 * index + 2] = stance.offset
        return MpcProblem(self.com_x.copy(), self.com_y.copy(), velocity, supports, reach, fixed, nominal,
                          self.sample_duration)

    def _reach_box(self, side: Side) -> tuple[float, float, float, float]:
        w, (lo, hi) = self.p.step_width, self.p.reach_y
        y = (w + lo, w + hi) if side == "left" else (-w - hi, -w - lo)
        return (*self.p.reach_x, *y)

    def shift(self, move: PlanarMove) -> None:
        """Move the plan rigidly in the plane (world frame): its CoM state, its feet, the swing under
        way and its heading, so that it continues from where the feet really are. Call it between
        samples (before :meth:`update`); where the feet must end (``stop_at``) stays."""
        com = np.stack([self.com_x, self.com_y], axis=1)  # rows position, velocity, acceleration
        com = np.vstack([move.point(com[0]), move.direction(com[1:])])
        self.com_x, self.com_y = com[:, 0].copy(), com[:, 1].copy()
        self.feet = {s: f.moved(move) for s, f in self.feet.items()}
        self.heading += move.turn
        if self.swing is not None:
            self.swing.shift(move)
        if self.settle_from is not None:
            f = self.settle_from
            self.settle_from = FootRef(f.side, f.yaw + move.turn, move.point(f.offset), f.S)

    def dcm(self) -> np.ndarray:
        """The plan's DCM (2,) [m] (world frame) at the start of the next sample."""
        return dcm(np.array([self.com_x[0], self.com_y[0]]), np.array([self.com_x[1], self.com_y[1]]),
                   natural_frequency(self.p.com_height))

    def add_com_velocity(self, delta: np.ndarray) -> None:
        """Add ``delta`` (2,) [m/s] (world frame) to the plan's CoM velocity before the next
        :meth:`update`, which then re-plans the footsteps from it and moves the landing of the swing
        under way even within its last ``swing_freeze`` seconds (a push leaves no time to wait)."""
        self.com_x[1] += delta[0]
        self.com_y[1] += delta[1]
        self._retarget_late = True

    # Stepping ---------------------------------------------------------------------------------
    def update(self) -> MpcSolution:
        """Solve the MPC for the current sample and advance the plan by one sample."""
        segments, landings = self._segments()
        t0 = time.perf_counter()
        try:
            sol = self.mpc.solve(self._problem(segments, landings))
        except MpcInfeasible:
            if self.stop_feet is None:
                raise
            self.stop_feet = None  # the requested stop footsteps are not reachable: stop where possible
            segments, landings = self._segments()
            sol = self.mpc.solve(self._problem(segments, landings))
        self.solve_times.append(time.perf_counter() - t0)
        self.solution = sol
        late, self._retarget_late = self._retarget_late, False
        retarget_until = self.p.single_support - self.p.swing_freeze - 1e-9
        if self.phase is GaitPhase.SINGLE and (late or self.phase_time < retarget_until):
            landing_yaw = landings[0][1].yaw
            self.swing.retarget(self.phase_time, Footstep(other(self.stance), *sol.footsteps[:2], landing_yaw))
        self._solved = _SolvedSample(self.com_x.copy(), self.com_y.copy(), float(sol.jerk_x[0]), float(sol.jerk_y[0]),
                                     self.phase, self.phase_time, self.stance, self.swing, self.time_scale,
                                     self.steps_started, tuple(segments))
        T = self._last_duration = self.sample_duration
        self.com_x = com_at(self.com_x, sol.jerk_x[0], T)
        self.com_y = com_at(self.com_y, sol.jerk_y[0], T)
        self.heading += self.velocity[2] * T
        self.t += T
        self._advance(self.p.sample_time)
        return sol

    def _advance(self, T: float) -> None:
        """Advance the gait state machine by ``T`` nominal seconds (``self.t`` is already the new time)."""
        p = self.p
        self.phase_time += T
        if self.phase is GaitPhase.TRANSFER and self.phase_time >= p.start_transfer - 1e-9:
            self._start_single()
        elif self.phase is GaitPhase.SINGLE and self.phase_time >= p.single_support - 1e-9:
            landed = self.swing.landing
            self.feet[landed.side] = landed
            self.touchdowns.append(Touchdown(self.t, landed))
            self.stance = landed.side
            if self.stop_feet is not None:
                done = all(self._at_goal(FootRef.known(f)) for f in self.feet.values())
            else:
                done = self.steps_to_stop == 1
            if done:
                self.phase, self.phase_time, self.steps_to_stop = GaitPhase.STAND, 0.0, 0
                self.stop_feet = None
                self.settle_from = FootRef.known(self.feet[other(landed.side)])
            else:
                self.steps_to_stop = max(self.steps_to_stop - 1, 0)
                self.phase, self.phase_time = GaitPhase.DOUBLE, 0.0
                if p.double_support <= 1e-9:
                    self._start_single()
        elif self.phase is GaitPhase.DOUBLE and self.phase_time >= p.double_support - 1e-9:
            self._start_single()

    def _start_single(self) -> None:
        swing = other(self.stance)
        self.phase, self.phase_time = GaitPhase.SINGLE, 0.0
        self.steps_started += 1
        self.swing = SwingTrajectory(self.feet[swing], self.p.single_support, self.p.swing_apex)

    # Sampling ---------------------------------------------------------------------------------
    def preview(self) -> PlanPreview:
        """The last solved plan at the horizon's sample boundaries ``j T`` (j = 0..N) after the start
        of the last solved sample: CoM, cart-table ZMP and feet (world frame). Feet of steps after
        the current swing follow a rest-to-rest quintic from lift-off to the MPC's footstep with the
        swing apex bump (the trajectory :class:`SwingTrajectory` starts with); the current swing is
        its own trajectory."""
        sol, p, solved = self.solution, self.p, self._solved
        h_g = p.com_height / GRAVITY
        segments = list(solved.segments)
        out = []
        for j in range(p.horizon + 1):
            if j == 0:
                cx, cy = solved.com_x, solved.com_y
                com, zmp = np.array([cx[0], cy[0]]), np.array([cx[0] - h_g * cx[2], cy[0] - h_g * cy[2]])
            else:
                com, zmp = sol.com[j - 1], sol.zmp[j - 1]
            t = j * p.sample_time  # nominal
            k, start = segment_at(segments, t)
            seg = segments[k]
            feet = {f.side: SolePlan(np.array([*f.position(sol.footsteps), 0.0]), f.yaw) for f in seg.feet}
            if len(seg.feet) == 1:
                side = other(seg.feet[0].side)
                if k == 0 and solved.phase is GaitPhase.SINGLE:
                    pos, yaw, _, _ = solved.swing.at(solved.phase_time + t)
                    feet[side] = SolePlan(pos, yaw)
                else:
                    feet[side] = SolePlan(*swing_point(segments, k, side, sol.footsteps, (t - start) / seg.duration,
                                                       p.swing_apex, self.feet[side]))
            out.append(PreviewSample(j * p.sample_time * solved.time_scale, com, zmp, feet, len(seg.feet) == 1))
        return PlanPreview(self.sample_start, self._last_duration, tuple(out))

    def gait_phase(self, tau: float) -> float | None:
        """Gait phase [rad] ``tau`` physical seconds after the start of the last solved sample: π per
        step, counted from the start of the first single support (2π per gait cycle of two steps);
        None before the first step."""
        solved = self._solved
        if solved.steps_started == 0 or not solved.phase.stepping:
            return None
        elapsed = (solved.phase_time + tau / solved.time_scale
                   + (self.p.single_support if solved.phase is GaitPhase.DOUBLE else 0.0))
        return np.pi * (solved.steps_started - 1 + elapsed / self.p.step_period)

    def sample(self, tau: float) -> WalkReference:
        """The plan ``tau`` physical seconds (0 ≤ tau ≤ sample duration) after the start of the last
        solved sample."""
        solved = self._solved
        sx, sy = com_at(solved.com_x, solved.jerk_x, tau), com_at(solved.com_y, solved.jerk_y, tau)
        h_g = self.p.com_height / GRAVITY
        scale = solved.time_scale
        feet, contact = {}, {}
        for side in ("left", "right"):
            if solved.phase is GaitPhase.SINGLE and side != solved.stance:
                pos, yaw, vel, wz = solved.swing.at(solved.phase_time + tau / scale)  # on nominal time
                feet[side], contact[side] = SolePlan(pos, yaw, vel / scale, wz / scale), False
            else:
                step = self.feet[side]
                feet[side], contact[side] = SolePlan(np.array([step.x, step.y, 0.0]), step.yaw), True
        return WalkReference(
            t=self.sample_start + tau,
            com=np.array([sx[0], sy[0]]), com_velocity=np.array([sx[1], sy[1]]),
            com_acceleration=np.array([sx[2], sy[2]]),
            zmp=np.array([sx[0] - h_g * sx[2], sy[0] - h_g * sy[2]]),
            feet=feet, in_contact=contact, phase=solved.phase,
        )

