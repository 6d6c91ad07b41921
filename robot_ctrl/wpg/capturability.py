"""N-step capturability of the linear inverted pendulum with rectangular soles (Koolen et al. 2012,
"Capturability-based analysis and control of legged locomotion, Part 1").

In the LIP the divergent component of motion ξ = c + ċ/ω obeys ξ̇ = ω (ξ − p), p the ZMP. With the
ZMP anywhere in a convex sole S for τ seconds the DCM reaches exactly the set::

    ξ(τ) ∈ e^{ωτ} ξ₀ − (e^{ωτ} − 1) S                                                         (1)

A state is N-step capturable when at most N steps bring the robot to rest: after the last landing
the DCM lies in the hull of the two soles, where the ZMP can hold it still. Per axis of the stance
sole's frame (sole half-size h, origin at its centre) the N-step regions are intervals::

    C₀ = [−h, h]
    G_n = [min(min(0, r⁻) − h,  r⁻ + c⁻ₙ₋₁),  max(max(0, r⁺) + h,  r⁺ + c⁺ₙ₋₁)]
    C_n = [−h + (G⁻_n + h) e^{−ωτ},  h + (G⁺_n − h) e^{−ωτ}]                                   (2)

with [r⁻, r⁺] where the next sole's centre may land relative to the stance sole, cₙ₋₁ the
(n−1)-step region of that sole (its own reach, mirrored sideways: the feet do not cross), and τ
the earliest the swing foot can land. (2) follows from (1): landing as early as possible is always
best, so both axes use the same landing times and the axes decouple exactly.

Relaxations, all in the robot's favour, so that a state outside these regions cannot be captured
by any stepping controller within the same reach: the ZMP may reach the sole's very edge; the
double support between steps takes no time; the hull of two soles is taken as their bounding box;
the soles stay parallel to the stance sole. Outside the LIP: no angular momentum about the CoM (a
hip strategy shifts the CMP beyond the sole, by a few centimetres for a short while).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.geometry import other

Box = tuple[np.ndarray, np.ndarray]  # (low corner (2,), high corner (2,)) [m]


@dataclass(frozen=True)
class CaptureModel:
    omega: float  # [1/s] LIP natural frequency √(g/h)
    sole: tuple[float, float]  # (length, width) of the region the ZMP may reach [m]
    reach_x: tuple[float, float]  # next sole's centre relative to the stance sole, forward [m]
    reach_y: tuple[float, float]  # the same sideways, toward the swing side (a left foot from a right stance) [m]
    min_swing: float  # [s] the shortest swing, lift-off to touch-down
    steps: int = 8  # N

    def __post_init__(self):
        if not (self.omega > 0 and min(self.sole) > 0 and self.min_swing >= 0 and self.steps >= 0):
            raise ValueError(f"CaptureModel needs omega > 0, a sole and min_swing ≥ 0, got {self}")
        if self.reach_y[0] < 0:
            raise ValueError(f"CaptureModel.reach_y = {self.reach_y}: feet that cross are not modelled")


def _interval(h: float, r: tuple[float, float], inner: tuple[float, float] | None, decay: float) -> tuple[float, float]:
    """C_n of (2) on one axis from the next sole's reach ``r`` and its region ``inner`` (None: n = 0)."""
    if inner is None:
        return -h, h
    g_lo = min(min(0.0, r[0]) - h, r[0] + inner[0])
    g_hi = max(max(0.0, r[1]) + h, r[1] + inner[1])
    return -h + (g_lo + h) * decay, h + (g_hi - h) * decay


def capture_box(model: CaptureModel, stance: str, wait: float) -> Box:
    """The DCM region, in the stance sole's frame (x forward, y left, origin at the sole's centre),
    from which at most ``model.steps`` steps capture the robot, when the swing foot can land
    ``wait`` seconds from now at the earliest (:math:`C_N` of (2))."""
    half = (model.sole[0] / 2, model.sole[1] / 2)
    swing = other(stance)
    reach_y = {"right": model.reach_y, "left": (-model.reach_y[1], -model.reach_y[0])}  # by stance side
    x = y = None
    for k in range(model.steps, -1, -1):  # from the last step back to the stance now: C_0, C_1, … C_N
        side = stance if k % 2 == 0 else swing
        decay = np.exp(-model.omega * (max(wait, 0.0) if k == 0 else model.min_swing))
        x = _interval(half[0], model.reach_x, x, decay)
        y = _interval(half[1], reach_y[side], y, decay)
    return np.array([x[0], y[0]]), np.array([x[1], y[1]])


def capture_boxes(model: CaptureModel, support: dict[str, np.ndarray], wait: float,
                  stays: str | None = None) -> list[Box]:
    """Capture regions in a frame aligned with the soles: ``support`` maps each foot on the floor to
    its sole centre in that frame. One foot: single support on it, the swing foot landing ``wait``
    seconds from now at the earliest. Both feet: their hull, or a foot lifting now and landing
    ``model.min_swing`` later, either foot or only the other than ``stays``."""
    if len(support) == 1:
        (side, centre), = support.items()
        lo, hi = capture_box(model, side, wait)
        return [(centre + lo, centre + hi)]
    half = np.array(model.sole) / 2
    centres = np.array(list(support.values()))
    boxes = [(centres.min(axis=0) - half, centres.max(axis=0) + half)]
    for side, centre in support.items():
        if stays in (None, side):
            lo, hi = capture_box(model, side, model.min_swing)
            boxes.append((centre + lo, centre + hi))
    return boxes


def largest_capturable_impulse(model: CaptureModel, dcm: np.ndarray, direction: np.ndarray, boxes: list[Box],
                               duration: float = 0.0, limit: float = 2.0, resolution: float = 0.005) -> float:
    """The largest impulse J [N·s/kg] along the unit ``direction`` such that every push up to J,
    starting now and lasting ``duration`` D seconds at constant force, leaves the DCM ``dcm``
    capturable (in one of ``boxes``, same frame); 0 when it already is not, ``limit`` when all are.

    With the force f = J/D the DCM obeys ξ̇ = ω (ξ − p) + f/ω, which over the push gives
    ξ(D) = e^{ωD} (ξ₀ + Δ) − (e^{ωD} − 1) p̄ with Δ = (J/ω) (1 − e^{−ωD}) / (ωD): for capturability the
    push is the instantaneous shift Δ now (exact when the earliest landing is not within the push)."""
    direction = np.asarray(direction, float) / np.linalg.norm(direction)
    spread = 1.0 if duration <= 0 else (1.0 - np.exp(-model.omega * duration)) / (model.omega * duration)
    largest = 0.0
    for impulse in np.arange(0.0, limit + resolution / 2, resolution):
        xi = np.asarray(dcm, float) + impulse * spread * direction / model.omega
        if not any(np.all(xi >= lo - 1e-12) and np.all(xi <= hi + 1e-12) for lo, hi in boxes):
            return largest
        largest = float(impulse)
    return largest
