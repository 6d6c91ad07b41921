"""The torque a servo command produces at a measured state, and the command bounded so that it
stays within the servo's effort limit. Pure numpy, per joint.
"""

from __future__ import annotations

import numpy as np


def servo_torque(q_des, dq_des, kp, kd, tau_ff, q, dq) -> np.ndarray:
    """τ = kp (q_des − q) + kd (dq_des − dq) + τ_ff, at the measured ``q``, ``dq``."""
    return kp * (q_des - q) + kd * (dq_des - dq) + tau_ff


def bound_servo_torque(q_des, dq_des, kp, kd, tau_ff, q, dq, effort, lower, upper):
    """A command whose torque at the measured state (``q``, ``dq``) is within ± ``effort`` and whose
    target stays within [``lower``, ``upper``]. Returns ``(q_des, kp, kd, tau_ff, changed)``.

    1. τ_ff is clipped to ± effort.
    2. The target moves: with r = τ_ff + kd (dq_des − dq), |τ| ≤ E holds for
       q_des ∈ [q + (−E − r)/kp, q + (E − r)/kp]; the target is clipped into that interval
       intersected with the position limits (stiffness kept, the target moved less far).
    3. Where that is not enough (the interval lies outside the limits, or kp = 0 and the damping
       term alone exceeds E), both gains scale by s = (E − sign(f) τ_ff) / |f| ∈ [0, 1], f the
       feedback part kp (q_des − q) + kd (dq_des − dq): then |s f + τ_ff| ≤ E because |τ_ff| ≤ E.
    """
    effort = np.asarray(effort, dtype=float)
    tau = np.clip(tau_ff, -effort, effort)
    rest = tau + kd * (dq_des - dq)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo = np.where(kp > 0, q + (-effort - rest) / kp, -np.inf)
        hi = np.where(kp > 0, q + (effort - rest) / kp, np.inf)
    lo, hi = np.maximum(lo, lower), np.minimum(hi, upper)
    target = np.where(lo <= hi, np.clip(q_des, lo, hi), np.clip(q_des, lower, upper))
    feedback = kp * (target - q) + kd * (dq_des - dq)
    over = np.abs(feedback + tau) > effort
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(over, (effort - np.sign(feedback) * tau) / np.abs(feedback), 1.0)
    scale = np.clip(np.nan_to_num(scale, nan=0.0), 0.0, 1.0)
    changed = (tau != tau_ff) | (target != q_des) | over
    return target, kp * scale, kd * scale, tau, changed
