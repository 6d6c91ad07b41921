"""The safety layer's pass over every command (``hw/safety.py``, in the order its docstring gives),
compiled: it runs on every tick between the controller and the servos, where numpy's per-call
cost on a few dozen joints is many times the arithmetic. The rare torque bound that may follow
stays in numpy (``servo_torque.bound_servo_torque``).
"""

from __future__ import annotations

import numpy as np

from robot_ctrl.kernels import FLOAT, VECTOR, kernel

#: Per-joint flags of :func:`filter_command`: what it changed.
GAIN_CLAMPED, POSITION_CLAMPED, POSITION_STEP_LIMITED, VELOCITY_CLAMPED = 1, 2, 4, 8
FLAG_KINDS = ((GAIN_CLAMPED, "gain_clamped"), (POSITION_CLAMPED, "position_clamped"),
              (POSITION_STEP_LIMITED, "position_step_limited"), (VELOCITY_CLAMPED, "velocity_clamped"))


@kernel((*(VECTOR,) * 16, FLOAT, FLOAT, VECTOR))
def filter_command(q_cmd, dq_cmd, kp_cmd, kd_cmd, tau_cmd, q_meas, dq_meas, reference, lower, upper, kp_max,
                   kd_max, step, velocity, effort, derate, ramp, margin, peak):
    """One command (finite, float) through the layer's limits, per joint ``i``:

    - ``peak_i ← max(peak_i, |τ_i|)``, τ the servo torque ``kp (q − q_meas) + kd (dq − dq_meas) + τ_ff``
      the command asks for at the measured state (updated in place);
    - ``kp ≤ kp_max``, ``kd ≤ kd_max``; ``q`` into [lower, upper], then at most ``step`` from
      ``reference`` (the last target), then into [lower, upper] again; ``|dq| ≤ velocity``;
    - soft start and temperature: ``kp ← kp · ramp · derate``, ``τ_ff ← τ_ff · ramp``.

    Returns ``(q, dq, kp, kd, τ_ff, flags, within)``: ``flags`` per joint (``GAIN_CLAMPED`` | ...),
    ``within``: every joint's torque of the result at the measured state, and its τ_ff, within
    ``effort · derate · (1 − margin)`` (no torque bound needed)."""
    n = q_cmd.size
    q, dq, kp, kd, tau = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    flags = np.zeros(n, dtype=np.uint8)
    within = True
    for i in range(n):
        demand = kp_cmd[i] * (q_cmd[i] - q_meas[i]) + kd_cmd[i] * (dq_cmd[i] - dq_meas[i]) + tau_cmd[i]
        peak[i] = max(peak[i], abs(demand))
        kp_i, kd_i = min(kp_cmd[i], kp_max[i]), min(kd_cmd[i], kd_max[i])
        if kp_i != kp_cmd[i] or kd_i != kd_cmd[i]:
            flags[i] |= GAIN_CLAMPED
        q_i = min(max(q_cmd[i], lower[i]), upper[i])
        if q_i != q_cmd[i]:
            flags[i] |= POSITION_CLAMPED
        stepped = reference[i] + min(max(q_i - reference[i], -step[i]), step[i])
        if stepped != q_i:
            flags[i] |= POSITION_STEP_LIMITED
        q[i] = min(max(stepped, lower[i]), upper[i])
        dq[i] = min(max(dq_cmd[i], -velocity[i]), velocity[i])
        if dq[i] != dq_cmd[i]:
            flags[i] |= VELOCITY_CLAMPED
        kp[i], kd[i], tau[i] = kp_i * ramp * derate[i], kd_i, tau_cmd[i] * ramp
        bound = effort[i] * derate[i] * (1.0 - margin)
        torque = kp[i] * (q[i] - q_meas[i]) + kd[i] * (dq[i] - dq_meas[i]) + tau[i]
        if not (abs(torque) <= bound and abs(tau[i]) <= bound):
            within = False
    return q, dq, kp, kd, tau, flags, within
