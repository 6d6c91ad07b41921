"""The IK velocities whose servo command stays within the servo's effort limit at the measured state."""

from __future__ import annotations

import numpy as np

from robot_ctrl.kernels import FLOAT, VECTOR, kernel


@kernel((VECTOR, VECTOR, VECTOR, VECTOR, VECTOR, VECTOR, VECTOR, FLOAT))
def servo_velocity_bounds(q_ref: np.ndarray, q: np.ndarray, dq: np.ndarray, tau_ff: np.ndarray, kp: np.ndarray,
                          kd: np.ndarray, budget: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds ``lo ≤ v ≤ hi`` on a joint's IK velocity ``v`` for one step of ``dt`` from the
    reference ``q_ref``, such that the servo command it becomes (target ``q_ref + v dt``, velocity
    ``v``, feedforward ``τ_ff``) asks the servo for no more than ``budget`` at the measured ``q``,
    ``dq``. The PD servo's torque is affine in ``v``::

        τ(v) = kp (q_ref + v dt − q) + kd (v − dq) + τ_ff = (kp dt + kd) v + c,
        c = kp (q_ref − q) − kd dq + τ_ff,

    so ``|τ(v)| ≤ budget`` is ``(−budget − c) / (kp dt + kd) ≤ v ≤ (budget − c) / (kp dt + kd)``.
    The interval is never empty; it excludes 0 when the reference has run so far from the joint
    that holding it still would ask for more than the budget, and then moves the reference back
    toward the joint. The IK integrates its own reference, so this is what keeps that reference
    within what the servo can follow: a velocity step ``Δv`` costs ``kd Δv`` of torque at once (a
    task switching on, a joint leaving its soft limit), a lagging joint ``kp × lag``. Arrays are per
    joint; a joint with ``kp dt + kd = 0`` gets no bound (±∞). Compiled: it runs on every tick,
    after the state is read."""
    lo, hi = np.full(q.size, -np.inf), np.full(q.size, np.inf)
    for i in range(q.size):
        slope = kp[i] * dt + kd[i]
        if slope > 0:
            c = kp[i] * (q_ref[i] - q[i]) - kd[i] * dq[i] + tau_ff[i]
            lo[i], hi[i] = (-budget[i] - c) / slope, (budget[i] - c) / slope
    return lo, hi
