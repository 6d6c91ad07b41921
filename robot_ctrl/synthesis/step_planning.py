"""Action sequencing: how many actions of which type, and how far each moves the pelvis
(thesis 3.4.2, end-state comfort), and the event-based blending between actions (thesis 3.4.1).

Actions: 1 = normal gait cycle, 2 = shortened gait cycle that starts the reach, 3 = standing
while pulling the drawer and reaching. Distances are along the walking direction [m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

GAMMA = 0.385  # share of the short (last) gait cycle in D − c (thesis 3.4.2, fitted to human data)
BETA = 0.2  # width of the blending interval, thesis β = 1/5


@dataclass(frozen=True)
class ActionRanges:
    """Lengths [m] the learned actions reproduce without artifacts (the training range)."""

    normal: tuple[float, float]
    short: tuple[float, float]


class Action(IntEnum):
    """The walk-and-reach actions (thesis 3.8): gait cycles of two steps, then standing."""

    ENDED = 0  # the sequence has ended (synthesis output only)
    WALK = 1  # a normal gait cycle
    SHORT = 2  # a short cycle that comes to rest, the arms starting to reach
    STAND = 3  # standing: the left hand pulls the drawer open, the right reaches the object


@dataclass(frozen=True)
class StepPlan:
    """Action types and their pelvis advances [m], in execution order; ends with ``Action.STAND``."""

    actions: tuple[Action, ...]
    lengths: tuple[float, ...]


#: The farthest goal a plan accepts [m]: a dozen gait cycles, about a room's length.
MAX_GOAL_DISTANCE = 10.0


def plan_steps(distance: float, comfort: float, ranges: ActionRanges, gamma: float = GAMMA,
               after_short: bool = False) -> StepPlan:
    """Plan the remaining actions for a pelvis-to-goal ``distance`` [m].

    End-state comfort: the last action (3) starts at ``comfort`` from the goal. The rest,
    ``R = distance − comfort``, is split ``D1 = R (1 − γ)``, ``D2 = R γ``: the short cycle that ends at
    rest takes the γ share. Thesis 3.4.2 prints the split the other way round (``D1 = R γ``), but its
    own HRP-2 runs (3.8.4) walked a first cycle of 50.5-56.1 cm and a second of 16.3-35.9 cm, which
    only ``D2 = R γ`` fits, and the other order makes the robot speed up (a cycle 1.6 times the
    normal one) just before it must stop; we follow the runs. When D1 would exceed the normal range,
    ``n`` extra normal cycles are added with the same proportion, ``D1 = R / (n + 1 + ρ)`` for each of
    the ``n + 1`` normal cycles and ``D2 = ρ D1`` with ``ρ = γ / (1 − γ)``. When D1 would be shorter
    than the normal range, only short cycles are planned: one with ``D2 = R``, or ``k`` equal ones if
    R exceeds the short range. ``after_short``: the current action is already a short cycle (the
    pelvis is slowing down), so only short cycles may follow.
    """
    if not (math.isfinite(distance) and math.isfinite(comfort)):
        raise ValueError(f"distance = {distance} m and comfort = {comfort} m must be finite")
    if distance > MAX_GOAL_DISTANCE:
        raise ValueError(f"goal distance = {distance:.3f} m is too far: at most {MAX_GOAL_DISTANCE} m")
    R = distance - comfort
    lo1, hi1 = ranges.normal
    lo2, hi2 = ranges.short
    if R < lo2:
        raise ValueError(f"goal distance = {distance:.3f} m is too close: it must be at least comfort distance + "
                         f"shortest step = {comfort + lo2:.3f} m")
    rho = gamma / (1 - gamma)
    if after_short or R / (1 + rho) < lo1:
        k = max(1, math.ceil(R / hi2))
        return StepPlan((Action.SHORT,) * k + (Action.STAND,), (R / k,) * k + (0.0,))
    n = max(0, math.ceil(R / hi1 - 1 - rho))
    D1 = R / (n + 1 + rho)
    return StepPlan((Action.WALK,) * (n + 1) + (Action.SHORT, Action.STAND), (D1,) * (n + 1) + (R - (n + 1) * D1, 0.0))


def blend_weight(phi: float | np.ndarray, beta: float = BETA) -> float | np.ndarray:
    """α(φ) of thesis eq. 3.23, φ [rad] relative to the transition (negative before it)::

        α = 0 for φ < −βπ;  (1 + sin(φ / (2β))) / 2 for |φ| ≤ βπ;  1 for φ > βπ
    """
    return np.where(phi < -beta * np.pi, 0.0,
                    np.where(phi > beta * np.pi, 1.0, 0.5 * (1 + np.sin(np.clip(phi, -beta * np.pi, beta * np.pi)
                                                                        / (2 * beta)))))


def blend_nonperiodic(phi: float, w_prev: np.ndarray, w_post: np.ndarray, beta: float = BETA) -> np.ndarray:
    """Weights of the non-periodic source across a transition (thesis 3.4.1): they may change sign
    only where φ crosses 0, where s0 jumps from −1 to 1::

        W = sign(φ) [(α − 1) W_prev + α W_post]

    so that ``W s0`` is continuous, passing through ``(W_post − W_prev) / 2`` at φ = 0."""
    a = blend_weight(phi, beta)
    return (1.0 if phi >= 0 else -1.0) * ((a - 1) * w_prev + a * w_post)
