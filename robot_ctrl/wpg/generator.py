"""WalkingPatternGenerator: gait state machine around the walking MPC, sampled at the control rate.

Gait phases: ``stand`` (double support, indefinitely) → ``transfer`` (double support that moves
the ZMP onto the first stance foot) → ``single`` support (the other foot swings to the MPC's
first footstep) ↔ ``double`` support after each touch-down. A zero velocity reference while
walking stops in two steps: the next footstep is still optimized, the one after it is placed
beside it (``step_width`` apart, parallel), then the robot stands in double support with the ZMP
reference moving to the middle of the feet. :meth:`stop_at` instead places those two last
footsteps at given positions, taking as many steps as the reach region requires (stopping at a
goal pose).

Every sample :meth:`update` solves the MPC from the generator's own planned CoM state
(balance feedback acts on the controller side, which may move that state: :meth:`shift`,
:meth:`add_com_velocity`) and advances the plan by one sample. :meth:`sample` interpolates it at
any time inside the current sample.
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

from robot_ctrl.geometry import GRAVITY, PlanarMove, other, rotation, wrap_angle
from robot_ctrl.geometry.support_polygon import SupportPolygon
from robot_ctrl.wpg.footstep import FootRef, Footstep
from robot_ctrl.wpg.lipm import com_at, dcm, natural_frequency
from robot_ctrl.wpg.mpc import MpcInfeasible, MpcProblem, MpcSolution, Reach, SampleSupport, WalkingMPC
from robot_ctrl.wpg.params import WalkParams
from robot_ctrl.wpg.swing import SwingTrajectory

#: [m] a foot this close to its stop footstep (in x and in y) is there: the plan follows the real
#: feet (``shift``), which land within millimetres of where they were sent, never exactly, and a
#: step to correct less than this would land as far off again, moving the robot while its hands
#: work.
STOP_TOLERANCE = 0.01


@dataclass(frozen=True)
class WalkReference:
    """The walking plan at one control instant (world frame)."""

    t: float
    com: np.ndarray  # (2,) [m]
    com_velocity: np.ndarray  # (2,) [m/s]
    com_acceleration: np.ndarray  # (2,) [m/s²]
    zmp: np.ndarray  # (2,) ZMP of the cart-table model [m]
    foot_position: dict[str, np.ndarray]  # side -> sole position (3,) [m]
    foot_yaw: dict[str, float]  # [rad]
    foot_velocity: dict[str, np.ndarray]  # side -> (linear (3,), yaw rate)
    in_contact: dict[str, bool]
    phase: str


@dataclass(frozen=True)
class PreviewSample:
    """The plan at one horizon sample (world frame)."""

    t: float  # [s] after the start of the last solved sample (physical time)
    com: np.ndarray  # (2,) [m]
    zmp: np.ndarray  # (2,) cart-table ZMP [m]
    feet: dict[str, tuple[np.ndarray, float]]  # side -> sole position (3,) [m], yaw [rad]
    single_support: bool


@dataclass
class Touchdown:
    """A footstep when it lands: the plan's target; the controller adds where the foot really was."""

    t: float
    planned: Footstep
    realized: Footstep | None = None


@dataclass
class _Segment:
    duration: float  # [s] (inf for standing)
    feet: list[FootRef]  # one (single support) or two (double support)
    zmp_from: FootRef | None  # ZMP reference moves linearly from this …
    zmp_to: FootRef | None = None  # … to this over the segment (None: stays at zmp_from)


def _midpoint(a: FootRef, b: FootRef) -> FootRef:
    return FootRef(a.side, a.yaw, (a.offset + b.offset) / 2, (a.S + b.S) / 2)


def _blend(a: FootRef, b: FootRef, s: float) -> FootRef:
    return FootRef(b.side, b.yaw, (1 - s) * a.offset + s * b.offset, (1 - s) * a.S + s * b.S)


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
        self.heading = float(np.arctan2(np.sin(left.yaw) + np.sin(right.yaw), np.cos(left.yaw) + np.cos(right.yaw)))
        self.phase = "stand"
        self.phase_time = 0.0
        self.stance = "right"
        self.steps_to_stop = 0  # landings left before standing (0: not stopping)
        self.stop_feet: dict[str, Footstep] | None = None  # where the feet must end when stopping at a pose
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
        self._sample_state = (self.com_x.copy(), self.com_y.copy(), 0.0, 0.0)
        self._sample_phase = (self.phase, 0.0, self.stance, None, 1.0, 0)

    # Reference --------------------------------------------------------------------------------
    def set_velocity(self, vx: float, vy: float, wz: float) -> None:
        """Reference pelvis velocity in the heading frame: vx, vy [m/s], ωz [rad/s]."""
        v = np.array([vx, vy, wz], dtype=float)
        if not np.all(np.isfinite(v)):
            raise ValueError(f"velocity reference must be finite, got {v}")
        moving = bool(np.any(np.abs(v) > 1e-6))
        if moving and self.phase == "stand":
            self.stance = "left" if (vy < 0 or (vy == 0 and wz < 0)) else "right"
            self.phase, self.phase_time = "transfer", 0.0
        elif not moving and self.phase == "transfer":
            self.phase, self.phase_time = "stand", 0.0
        elif not moving and self.phase in ("single", "double") and self.steps_to_stop == 0:
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
        return self.phase == "stand"

    # Horizon ----------------------------------------------------------------------------------
    def _segments(self) -> tuple[list[_Segment], list[tuple[int, FootRef, FootRef | None]]]:
        """Support segments from now over the horizon, and the landings (index, foot, fixed-to)."""
        p = self.p
        known = {side: FootRef.known(step) for side, step in self.feet.items()}
        segments: list[_Segment] = []
        landings: list[tuple[int, FootRef, FootRef | None]] = []
        left, right = known["left"], known["right"]
        remaining = {"transfer": p.start_transfer, "single": p.single_support, "double": p.double_support}
        if self.phase == "stand":
            zmp_from = self.settle_from or _midpoint(left, right)
            segments.append(_Segment(max(p.start_transfer - self.phase_time, 0.0), [left, right], zmp_from,
                                     _midpoint(left, right)))
            segments.append(_Segment(np.inf, [left, right], _midpoint(left, right)))
            return segments, landings
        stance = known[self.stance]
        left_in_phase = remaining[self.phase] - self.phase_time
        if self.phase == "transfer":
            mid = _midpoint(left, right)
            start = _blend(mid, stance, self.phase_time / p.start_transfer)
            segments.append(_Segment(left_in_phase, [left, right], start, stance))
            segments.append(_Segment(p.single_support, [stance], stance))
            t_land = left_in_phase + p.single_support
        elif self.phase == "single":
            segments.append(_Segment(left_in_phase, [stance], stance))
            t_land = left_in_phase
        else:  # double: the stance foot has just landed, the previous one is still down
            prev = known[other(self.stance)]
            segments.append(_Segment(left_in_phase, [prev, stance], prev, stance))
            segments.append(_Segment(p.single_support, [stance], stance))
            t_land = left_in_phase + p.single_support
        horizon = p.sample_time * p.horizon
        previous = stance
        index = 0
        while t_land < horizon and index < 2:
            side = other(previous.side)
            heading = self.heading + self.velocity[2] * t_land * self.time_scale
            yaw = previous.yaw + np.clip(wrap_angle(heading - previous.yaw), -p.max_yaw_step, p.max_yaw_step)
            if self.stop_feet is not None:
                fixed = FootRef.known(self._toward_goal(previous, side))
                final = self._at_goal(fixed) and self._at_goal(previous)
            else:
                final = self.steps_to_stop and index == self.steps_to_stop - 1
                fixed = previous.beside(p.step_width) if final else None
            foot = fixed if fixed is not None else FootRef.variable(index, side, float(yaw))
            landings.append((index, FootRef.variable(index, side, foot.yaw), fixed))
            if final:
                segments.append(_Segment(np.inf, [previous, foot], previous, _midpoint(previous, foot)))
                return segments, landings
            segments.append(_Segment(p.double_support, [previous, foot], previous, foot))
            segments.append(_Segment(p.single_support, [foot], foot))
            previous = foot
            t_land += p.step_period
            index += 1
        return segments, landings

    def _toward_goal(self, previous: FootRef, side: str) -> Footstep:
        """The stop footstep of ``side``, clamped into the reach region (and yaw step) of ``previous``."""
        goal = self.stop_feet[side]
        yaw = previous.yaw + np.clip(wrap_angle(goal.yaw - previous.yaw), -self.p.max_yaw_step, self.p.max_yaw_step)
        local = rotation(previous.yaw).T @ (goal.xy - previous.offset)
        box = self._reach_box(side)
        local = np.clip(local, [box[0], box[2]], [box[1], box[3]])
        x, y = previous.offset + rotation(previous.yaw) @ local
        return Footstep(side, float(x), float(y), float(yaw))

    def _at_goal(self, foot: FootRef) -> bool:
        goal = self.stop_feet[foot.side]
        return (not foot.S.any() and np.allclose(foot.offset, goal.xy, atol=STOP_TOLERANCE)
                and abs(wrap_angle(foot.yaw - goal.yaw)) < 1e-6)

    def problem(self) -> MpcProblem:
        p = self.p
        segments, landings = self._segments()
        self._planned_segments = segments
        self._landing_yaws = [foot.yaw for _, foot, _ in landings]
        half = np.array([p.foot_length / 2 - p.zmp_margin, p.foot_width / 2 - p.zmp_margin])
        supports = []
        polygons: dict[tuple[int, bool], tuple] = {}  # (segment, second half) -> (H, h, anchor)
        velocity = np.zeros((p.horizon, 2))
        for j in range(p.horizon):
            t = (j + 1) * p.sample_time  # nominal
            start = 0.0
            for seg in segments:
                if t <= start + seg.duration + 1e-9 or seg is segments[-1]:
                    break
                start += seg.duration
            s = 1.0 if not np.isfinite(seg.duration) or seg.duration == 0 else (t - start) / seg.duration
            s = min(max(s, 0.0), 1.0)
            key = (id(seg), s >= 0.5)
            if key not in polygons:
                polygons[key] = _polygon(seg, s, half)
            zmp_ref = seg.zmp_from if seg.zmp_to is None else _blend(seg.zmp_from, seg.zmp_to, s)
            supports.append(SampleSupport(*polygons[key], zmp_ref))
            heading = self.heading + self.velocity[2] * t * self.time_scale
            velocity[j] = rotation(heading) @ self.velocity[:2]
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
            sign = 1.0 if foot.side == "left" else -1.0
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

    def _reach_box(self, side: str) -> tuple[float, float, float, float]:
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
        prob = self.problem()
        t0 = time.perf_counter()
        try:
            sol = self.mpc.solve(prob)
        except MpcInfeasible:
            if self.stop_feet is None:
                raise
            self.stop_feet = None  # the requested stop footsteps are not reachable: stop where possible
            prob = self.problem()
            sol = self.mpc.solve(prob)
        self.solve_times.append(time.perf_counter() - t0)
        self.solution = sol
        late, self._retarget_late = self._retarget_late, False
        if self.phase == "single" and (late or self.phase_time < self.p.single_support - self.p.swing_freeze - 1e-9):
            self.swing.retarget(self.phase_time, Footstep(other(self.stance), *sol.footsteps[:2], self._landing_yaws[0]))
        self._sample_state = (self.com_x.copy(), self.com_y.copy(), float(sol.jerk_x[0]), float(sol.jerk_y[0]))
        self._preview_segments = self._planned_segments
        T = self._last_duration = self.sample_duration
        self._sample_phase = (self.phase, self.phase_time, self.stance, self.swing, self.time_scale, self.steps_started)
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
        if self.phase == "transfer" and self.phase_time >= p.start_transfer - 1e-9:
            self._start_single()
        elif self.phase == "single" and self.phase_time >= p.single_support - 1e-9:
            landed = self.swing.landing
            self.feet[landed.side] = landed
            self.touchdowns.append(Touchdown(self.t, landed))
            self.stance = landed.side
            if self.stop_feet is not None:
                done = all(self._at_goal(FootRef.known(f)) for f in self.feet.values())
            else:
                done = self.steps_to_stop == 1
            if done:
                self.phase, self.phase_time, self.steps_to_stop = "stand", 0.0, 0
                self.stop_feet = None
                self.settle_from = FootRef.known(self.feet[other(landed.side)])
            else:
                self.steps_to_stop = max(self.steps_to_stop - 1, 0)
                self.phase, self.phase_time = "double", 0.0
                if p.double_support <= 1e-9:
                    self._start_single()
        elif self.phase == "double" and self.phase_time >= p.double_support - 1e-9:
            self._start_single()

    def _start_single(self) -> None:
        swing = other(self.stance)
        self.phase, self.phase_time = "single", 0.0
        self.steps_started += 1
        self.swing = SwingTrajectory(self.feet[swing], self.p.single_support, self.p.swing_apex)

    # Sampling ---------------------------------------------------------------------------------
    def preview(self) -> list[PreviewSample]:
        """The last solved plan at the horizon's sample boundaries ``j T`` (j = 0..N) after the start
        of the last solved sample: CoM, cart-table ZMP and feet (world frame). Feet of steps after
        the current swing follow a rest-to-rest quintic from lift-off to the MPC's footstep with the
        swing apex bump (the trajectory :class:`SwingTrajectory` starts with); the current swing is
        its own trajectory."""
        sol, p = self.solution, self.p
        cx, cy, _, _ = self._sample_state
        h_g = p.com_height / GRAVITY
        phase, phase_time, stance, swing, scale, _ = self._sample_phase
        segments = self._preview_segments
        out = []
        for j in range(p.horizon + 1):
            if j == 0:
                com, zmp = np.array([cx[0], cy[0]]), np.array([cx[0] - h_g * cx[2], cy[0] - h_g * cy[2]])
            else:
                com, zmp = sol.com[j - 1], sol.zmp[j - 1]
            t = j * p.sample_time  # nominal
            start = 0.0
            for k, seg in enumerate(segments):
                if t <= start + seg.duration + 1e-9 or k == len(segments) - 1:
                    break
                start += seg.duration
            feet = {f.side: (np.array([*f.position(sol.footsteps), 0.0]), f.yaw) for f in seg.feet}
            if len(seg.feet) == 1:
                side = other(seg.feet[0].side)
                if k == 0 and phase == "single":
                    pos, yaw, _, _ = swing.at(phase_time + t)
                    feet[side] = (pos, yaw)
                else:
                    feet[side] = _swing_point(segments, k, side, sol.footsteps, (t - start) / seg.duration,
                                              p.swing_apex, self.feet[side])
            out.append(PreviewSample(j * p.sample_time * scale, com, zmp, feet, len(seg.feet) == 1))
        return out

    def gait_phase(self, tau: float) -> float | None:
        """Gait phase [rad] ``tau`` physical seconds after the start of the last solved sample: π per
        step, counted from the start of the first single support (2π per gait cycle of two steps);
        None before the first step."""
        phase, phase_time, _, _, scale, steps = self._sample_phase
        if steps == 0 or phase not in ("single", "double"):
            return None
        elapsed = phase_time + tau / scale + (self.p.single_support if phase == "double" else 0.0)
        return np.pi * (steps - 1 + elapsed / self.p.step_period)

    def sample(self, tau: float) -> WalkReference:
        """The plan ``tau`` physical seconds (0 ≤ tau ≤ sample duration) after the start of the last
        solved sample."""
        cx, cy, jx, jy = self._sample_state
        sx, sy = com_at(cx, jx, tau), com_at(cy, jy, tau)
        h_g = self.p.com_height / GRAVITY
        phase, phase_time, stance, swing, scale, _ = self._sample_phase
        positions, yaws, velocities, contact = {}, {}, {}, {}
        for side in ("left", "right"):
            if phase == "single" and side != stance:
                pos, yaw, vel, wz = swing.at(phase_time + tau / scale)  # the swing runs on nominal time
                positions[side], yaws[side], velocities[side], contact[side] = pos, yaw, (vel / scale, wz / scale), False
            else:
                step = self.feet[side]
                positions[side] = np.array([step.x, step.y, 0.0])
                yaws[side], velocities[side], contact[side] = step.yaw, (np.zeros(3), 0.0), True
        return WalkReference(
            t=self.sample_start + tau,
            com=np.array([sx[0], sy[0]]), com_velocity=np.array([sx[1], sy[1]]),
            com_acceleration=np.array([sx[2], sy[2]]),
            zmp=np.array([sx[0] - h_g * sx[2], sy[0] - h_g * sy[2]]),
            foot_position=positions, foot_yaw=yaws, foot_velocity=velocities, in_contact=contact, phase=phase,
        )


def _swing_point(segments: list[_Segment], k: int, side: str, F: np.ndarray, s: float, apex: float,
                 fallback: Footstep) -> tuple[np.ndarray, float]:
    """Swing foot ``side`` at fraction ``s`` of single-support segment ``k``: from where it stood in
    the segment before to where it lands in the segment after (min-jerk in the plane and yaw,
    ``16 apex s²(1 − s)²`` in height). A landing the plan does not hold yet (beyond its footstep
    variables) repeats the last step: the lift foot mirrored through the stance foot's heading line
    and carried the step's length ahead, so the preview's legs keep up with its CoM."""
    def where(seg):
        return next(((f.position(F), f.yaw) for f in seg.feet if f.side == side), None)

    lift = where(segments[k - 1]) if k > 0 else None
    land = where(segments[k + 1]) if k + 1 < len(segments) else None
    lift = lift or (fallback.xy, fallback.yaw)
    if land is None:
        stance = segments[k].feet[0]
        R = rotation(stance.yaw)
        step = R.T @ (stance.position(F) - lift[0])  # lift → stance, in the stance foot's frame
        land = (stance.position(F) + R @ np.array([step[0], -step[1]]), stance.yaw)
    s = min(max(s, 0.0), 1.0)
    blend = s**3 * (10 - 15 * s + 6 * s * s)
    xy = lift[0] + blend * (land[0] - lift[0])
    yaw = lift[1] + blend * wrap_angle(land[1] - lift[1])
    return np.array([xy[0], xy[1], 16.0 * apex * s * s * (1 - s) ** 2]), float(yaw)


def _polygon(seg: _Segment, s: float, half: np.ndarray) -> tuple[np.ndarray, np.ndarray, FootRef]:
    """Support half-planes ``H (z − anchor) ≤ h`` of a segment at fraction ``s`` of it."""
    if len(seg.feet) == 2 and not seg.feet[0].same_anchor(seg.feet[1]):
        # Double support towards a foot that is still a decision variable: the hull would not be
        # linear in it, so the ZMP is kept in the rear foot for the first half, in the front one after
        # (a subset of the hull).
        feet = [seg.feet[0] if s < 0.5 else seg.feet[1]]
    else:
        feet = seg.feet
    anchor = feet[0]
    soles = [(f.offset - anchor.offset, f.yaw) for f in feet]
    H, h = SupportPolygon.of_soles(soles, 2 * half[0], 2 * half[1]).halfplanes
    return H, h, anchor
