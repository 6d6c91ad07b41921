"""Synthesizer: online walk-and-reach synthesis from the learned primitives (thesis 3.3.4-3.4.2, 3.7).

Per call of :meth:`Synthesizer.step`:

1. the leading Andronov-Hopf oscillator and its star-coupled followers (one per periodic source)
   advance by ``dt`` (RK4) at the frequency ``2π / duration`` of the current action, blended with α
   across transitions;
2. a wrap of the leader's phase φ through 0 ends the current action (one action = one period);
3. every channel is synthesized as ``m + W0 s0 + Σ_k W_k f_k(R(φ_nk) x_k)``, ``s0 = cos(φ/2)``, with
   the weights and means of the actions around a transition blended by α(φ) (eq. 3.23) and the
   non-periodic weights by the sign rule;
4. the pelvis advance ``∫ vx dt`` is integrated (kinematic odometry along the walking direction).

Planning: the actions and their lengths come from :func:`plan_steps` for the distance left to the
goal; each action's duration, weights and means from the locally weighted regressions. When the
goal moves, the actions not yet started are replanned (an action that is already blending in is
kept), which adds steps when the goal jumps away (thesis Fig. 3.39).

Our addition to the thesis, stated: the blending of means and weights across transitions shifts a
few millimetres of pelvis advance between neighbouring actions, so the forward-speed means of the
actions not yet started are solved (one linear solve) such that a rollout of this same synthesis
reaches the planned pelvis position at the end of every action. The rollout is exact because
the advance is affine in those means: the oscillators do not depend on them.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from robot_ctrl.synthesis.oscillator import phase, star_step
from robot_ctrl.synthesis.primitives import ActionParams, WalkReachPrimitives
from robot_ctrl.synthesis.step_planning import BETA, Action, blend_nonperiodic, blend_weight, plan_steps

TWO_PI = 2 * np.pi
FOLLOWER_COUPLING = 10.0  # [1/s] star coupling of the source oscillators to the leader


class SynthesisError(ValueError):
    """The learned primitives cannot plan a goal (a property of the primitives and the goal, not a bug)."""


@dataclass(frozen=True)
class WalkReachGoal:
    """The drawer: ``distance`` [m] of its front panel from the pelvis's start position along the
    walking direction (the synthesizer's start frame, x forward), and the object slot."""

    distance: float
    slot: str = "front_left"


@dataclass(frozen=True)
class GoalJump:
    """The drawer moves: at ``time`` [s] after the start it is ``distance`` [m] from the start pelvis."""

    time: float
    distance: float


@dataclass(frozen=True)
class SynthesisOutput:
    pelvis_velocity: np.ndarray  # (vx, vy, ωz) in the pelvis heading frame [m/s, m/s, rad/s]
    upper_body_q: np.ndarray  # upper-body joint angles [rad], order of ``upper_body_joints``
    phase: float  # leader phase φ in [0, 2π) within the current action [rad]
    action: Action

    def __iter__(self):
        """``v, q, phase, action = synth.step(dt, goal)``."""
        return iter((self.pelvis_velocity, self.upper_body_q, self.phase, self.action))


@dataclass(frozen=True)
class SynthesisPreview:
    """The synthesis ahead of now: at times ``t`` [s] after it, the pelvis velocity (n, 3), the
    upper-body angles (n, J) and the action (0 once the sequence has ended)."""

    t: np.ndarray
    pelvis_velocity: np.ndarray
    upper_body_q: np.ndarray
    action: np.ndarray


@dataclass
class _Cursor:
    """Mutable integration state: oscillators (leader first), action index, pelvis advance."""

    x: np.ndarray
    index: int = 0
    progress: float = 0.0
    finished: bool = False

    def copy(self) -> "_Cursor":
        return _Cursor(self.x.copy(), self.index, self.progress, self.finished)


@dataclass
class _Blend:
    """Actions ``prev`` and ``post`` (plan indices) mixed with α; ``phi`` relative to the transition."""

    prev: int
    post: int
    alpha: float
    phi: float
    window: bool


@dataclass
class _Rollout:
    """The synthesis ahead for one plan, rolled out at steps of ``dt`` [s] from a cursor within
    action ``action_index``, outside its blends; :meth:`Synthesizer.preview` drops the samples that
    time has passed and extends the tail, so each call rolls only what is new."""

    dt: float
    plan_version: int
    action_index: int
    cursor: _Cursor  # at the tail
    last: SynthesisOutput | None  # the references at the tail
    end: float  # synthesis time of the tail [s]
    samples: deque  # (synthesis time [s], pelvis velocity, upper-body angles, action), oldest first

    def extend(self, primitives: WalkReachPrimitives, plan: list[ActionParams]) -> None:
        """One more sample at the tail; after the sequence ends the last references are held."""
        c = self.cursor
        if not c.finished:
            values = np.clip(_advance(primitives, plan, c, self.dt), primitives.lower, primitives.upper)
            if not c.finished:
                self.last = SynthesisOutput(values[:3], values[3:], 0.0, plan[c.index].action)
        self.end += self.dt
        if self.last is None:
            self.samples.append((self.end, np.zeros(3), np.zeros(len(primitives.channels) - 3), 0))
        elif c.finished:
            self.samples.append((self.end, np.zeros(3), self.last.upper_body_q, Action.ENDED))
        else:
            self.samples.append((self.end, self.last.pelvis_velocity, self.last.upper_body_q, self.last.action))


@dataclass
class ExecutedAction:
    action: Action
    planned_length: float
    start_progress: float
    end_progress: float | None = None


class Synthesizer:
    def __init__(self, primitives: WalkReachPrimitives, goal: WalkReachGoal, control_dt: float = 0.005):
        """``control_dt`` [s]: the step the planning rollout assumes until ``step`` is called (then
        the last ``dt`` given); stepping at another rate moves the realized lengths by millimetres."""
        self.primitives = primitives
        self._vx = primitives.channels.index("vx")
        self._upper = slice(3, None)
        K = primitives.rotations.shape[1]
        start = np.zeros((K + 1, 2))
        start[:, 0] = 1.0  # φ = 0 on the limit cycle: the start of the first action
        self._cursor = _Cursor(start)
        self.plan: list[ActionParams] = []
        self.targets: list[float] = []  # planned pelvis advance at the end of each action [m]
        self.history: list[ExecutedAction] = []
        self.replans = 0
        self._goal = None
        self._last = None
        self._dt = control_dt
        self._elapsed = 0.0  # synthesis time stepped so far [s]
        self._plan_version = 0
        self._rollout: _Rollout | None = None
        self._set_goal(goal)

    # -- public -------------------------------------------------------------------------------------
    @property
    def progress(self) -> float:
        """Pelvis advance since the start along the walking direction [m]."""
        return self._cursor.progress

    @property
    def finished(self) -> bool:
        return self._cursor.finished

    def step(self, dt: float, goal: WalkReachGoal | None = None) -> SynthesisOutput:
        """Advance by ``dt`` [s] towards ``goal`` (None: unchanged) and return the new references."""
        if not (np.isfinite(dt) and 0 < dt <= 0.1):
            raise ValueError(f"dt = {dt} s must be in (0, 0.1]")
        self._dt = dt
        self._elapsed += dt
        if goal is not None and goal != self._goal and not self.finished:
            self._set_goal(goal)
        c = self._cursor
        if c.finished:
            return self._last
        before = c.index
        values = _advance(self.primitives, self.plan, c, dt)
        if c.index != before:
            self.history[-1].end_progress = c.progress - values[self._vx] * dt
            if not c.finished:
                self.history.append(ExecutedAction(self.plan[c.index].action, self.plan[c.index].length,
                                                   self.history[-1].end_progress))
        if c.finished:  # hold the last references
            self._last = SynthesisOutput(self._last.pelvis_velocity, self._last.upper_body_q, self._last.phase, 0)
            return self._last
        values = np.clip(values, self.primitives.lower, self.primitives.upper)
        if not np.all(np.isfinite(values)):
            raise FloatingPointError("synthesis produced a non-finite value; refusing to output it")
        self._last = SynthesisOutput(values[:3], values[self._upper], float(phase(c.x[0])), self.plan[c.index].action)
        return self._last

    def preview(self, horizon: float, dt: float) -> SynthesisPreview:
        """The references of the next ``horizon`` [s] at steps of ``dt`` [s], from a rollout of this
        same synthesis (the goal as it stands); the synthesizer itself does not move. After the
        sequence ends the last references are held.

        The rollout is kept between calls: a call rolls only the tail that time has added since the
        last one. It starts anew when the plan changes (a replan), when an action ends, and at every
        call while the synthesis is within a transition's blend (and is not kept from there): in a
        blend the frequency changes within a step, so a rollout at steps of ``dt`` departs from the
        synthesis's own finer steps, and that departure must not be carried on into the next
        action. The samples lie on the rollout's grid: the first is less than ``dt`` ahead."""
        n = max(1, int(round(horizon / dt)))
        c, r = self._cursor, self._rollout
        blending = not c.finished and _blend(self.plan, c.index, float(phase(c.x[0]))).window
        if r is None or blending or r.dt != dt or r.plan_version != self._plan_version or r.action_index != c.index:
            r = _Rollout(dt, self._plan_version, c.index, c.copy(), self._last, self._elapsed, deque())
        self._rollout = None if blending else r
        while r.samples and r.samples[0][0] <= self._elapsed + 1e-9:
            r.samples.popleft()
        while len(r.samples) < n:
            r.extend(self.primitives, self.plan)
        ahead = [r.samples[k] for k in range(n)]
        return SynthesisPreview(np.array([a[0] for a in ahead]) - self._elapsed, np.array([a[1] for a in ahead]),
                                np.array([a[2] for a in ahead]), np.array([a[3] for a in ahead], dtype=int))

    @property
    def action_index(self) -> int:
        """Index of the action under way in :attr:`plan`."""
        return self._cursor.index

    # -- planning -----------------------------------------------------------------------------------
    def _set_goal(self, goal: WalkReachGoal) -> None:
        c = self._cursor
        if not self.plan:
            keep = 0
        else:
            in_window = phase(c.x[0]) >= (2 - BETA) * np.pi and c.index + 1 < len(self.plan)
            keep = c.index + 1 + int(in_window)
            self.replans += 1
        kept_end = self.targets[keep - 1] if keep else 0.0
        previous = self.plan[keep - 1] if keep else None
        steps = plan_steps(goal.distance - kept_end, self.primitives.comfort_distance, self.primitives.ranges,
                           after_short=previous is not None and previous.action is Action.SHORT)
        new, prev_len = [], previous.length if previous is not None else 0.0
        for action, length in zip(steps.actions, steps.lengths):
            new.append(self.primitives.action(action, length, goal.slot, prev_len))  # vx mean: solved below
            prev_len = length
        self.plan = self.plan[:keep] + new
        self.targets = self.targets[:keep] + list(kept_end + np.cumsum(steps.lengths))
        self._correct_speed_means(keep)
        self._goal = goal
        self._plan_version += 1
        if not self.history:
            self.history.append(ExecutedAction(self.plan[0].action, self.plan[0].length, 0.0))

    def _correct_speed_means(self, first: int) -> None:
        """Solve the vx means of actions ``first..`` so that the rollout ends each of them at its target."""
        unknown = list(range(first, len(self.plan)))
        sens, ends = _rollout_vx(self.primitives, self.plan, self._cursor.copy(), self._dt, self._vx)
        # ends[j] = base[j] + sens[j] @ means: progress at the end of plan action j.
        base = ends - sens @ np.array([p.means[self._vx] for p in self.plan])
        A = sens[np.ix_(unknown, unknown)]
        fixed = [j for j in range(len(self.plan)) if j not in unknown]
        rhs = np.array(self.targets)[unknown] - base[unknown]
        if fixed:
            rhs -= sens[np.ix_(unknown, fixed)] @ np.array([self.plan[j].means[self._vx] for j in fixed])
        means = np.linalg.solve(A, rhs)
        for j, m in zip(unknown, means):
            self.plan[j] = self.plan[j].with_mean(self._vx, m)


def _blend(plan: list[ActionParams], index: int, phi: float) -> _Blend:
    """Which actions are mixed at phase φ of action ``index``, and how (thesis 3.4.1)."""
    if phi >= (2 - BETA) * np.pi and index + 1 < len(plan):
        rel = phi - TWO_PI
        return _Blend(index, index + 1, float(blend_weight(rel)), rel, True)
    if phi <= BETA * np.pi and index > 0:
        return _Blend(index - 1, index, float(blend_weight(phi)), phi, True)
    return _Blend(index, index, 1.0, phi, False)


def _mixture_terms(plan, index, x, primitives: WalkReachPrimitives, channels=slice(None)):
    """(blend, non-periodic part + periodic part) of the selected channels, without the means."""
    phi = float(phase(x[0]))
    b = _blend(plan, index, phi)
    prev, post = plan[b.prev], plan[b.post]
    w0 = blend_nonperiodic(b.phi, prev.w0[channels], post.w0[channels]) if b.window else post.w0[channels]
    W = (1 - b.alpha) * prev.weights[channels] + b.alpha * post.weights[channels]
    sources = primitives.source_map.delayed(x[1:], np.atleast_2d(primitives.rotations[channels]))
    return b, w0 * np.cos(phi / 2) + np.sum(W * sources, axis=-1)


def _advance(primitives: WalkReachPrimitives, plan: list[ActionParams], c: _Cursor, dt: float) -> np.ndarray:
    """Step the oscillators, handle an action wrap, integrate the pelvis advance; all channels."""
    _step_oscillators(plan, c, dt)
    if c.finished:
        return np.zeros(len(primitives.channels))
    b, terms = _mixture_terms(plan, c.index, c.x, primitives)
    values = (1 - b.alpha) * plan[b.prev].means + b.alpha * plan[b.post].means + terms
    c.progress += values[primitives.channels.index("vx")] * dt
    return values


def _step_oscillators(plan: list[ActionParams], c: _Cursor, dt: float) -> None:
    before = float(phase(c.x[0]))
    b = _blend(plan, c.index, before)
    omega = (1 - b.alpha) * plan[b.prev].omega + b.alpha * plan[b.post].omega
    c.x = star_step(c.x, omega, FOLLOWER_COUPLING, dt)
    if float(phase(c.x[0])) < before - np.pi:  # the leader's phase wrapped through 0
        c.index += 1
        c.finished = c.index >= len(plan)


def _rollout_vx(primitives, plan, c: _Cursor, dt: float, vx: int):
    """Run the synthesis of ``vx`` to the end of the plan. Returns ``sens`` (A, A), the derivative of
    the advance at the end of each action w.r.t. each action's vx mean, and those advances (A,)."""
    n = len(plan)
    sens = np.zeros((n, n))
    ends = np.full(n, np.nan)
    coef = np.zeros(n)  # running ∫ (blend coefficient of each action's mean) dt
    progress = c.progress
    start = c.index
    for _ in range(int(60.0 / dt)):
        index = c.index
        _step_oscillators(plan, c, dt)
        if c.index != index:
            ends[index], sens[index] = progress, coef
            if c.finished:
                break
        b, terms = _mixture_terms(plan, c.index, c.x, primitives, [vx])
        coef[b.prev] += (1 - b.alpha) * dt
        coef[b.post] += b.alpha * dt
        progress += ((1 - b.alpha) * plan[b.prev].means[vx] + b.alpha * plan[b.post].means[vx] + terms[0]) * dt
    else:
        raise SynthesisError("the learned primitives cannot synthesize this goal: their rollout does not end "
                             "the sequence within 60 s")
    ends[:start] = 0.0
    return sens, ends
