"""RunMetrics: falls, torques and ground reaction forces accumulated from what a backend reads."""

from __future__ import annotations

import numpy as np

from robot_ctrl.eval.recording.fall import FallCriterion
from robot_ctrl.hw.types import JointState


class RunMetrics:
    """Accumulates over a run, one :class:`JointState` at a time.

    - fall: first sample where :class:`FallCriterion` holds (time and reason);
    - peak torque ratio per joint: max |servo torque demanded before saturation| / effort limit
      (``tau_demand`` where the backend reports it, else the applied ``tau``), so a saturating
      servo shows a ratio > 1;
    - peak normal ground reaction force per foot [N] (sole-frame fz of the contact wrench).
    """

    def __init__(self, joint_names: tuple[str, ...], effort: np.ndarray, fall: FallCriterion):
        self.joint_names = joint_names
        self.effort = effort
        self.fall = fall
        self.fall_time: float | None = None
        self.fall_reason: str | None = None
        self.peak_torque = np.zeros(len(joint_names))
        self.peak_grf: dict[str, float] = {}
        self.t = 0.0

    def update(self, state: JointState) -> None:
        self.t = state.t
        tau = state.tau_demand if state.tau_demand is not None else state.tau
        np.maximum(self.peak_torque, np.abs(tau), out=self.peak_torque)
        for side, wrench in (state.foot_wrench or {}).items():
            self.peak_grf[side] = max(self.peak_grf.get(side, 0.0), float(wrench[2]))
        if self.fall_time is None:
            reason = self.fall.reason(state)
            if reason is not None:
                self.fall_time, self.fall_reason = state.t, reason

    @property
    def fell(self) -> bool:
        return self.fall_time is not None

    def torque_ratios(self) -> np.ndarray:
        return self.peak_torque / self.effort

    def report(self) -> dict:
        ratios = self.torque_ratios()
        worst = int(np.argmax(ratios))
        return {
            "fell": self.fell,
            "fall_time_s": self.fall_time,
            "fall_reason": self.fall_reason,
            "time_s": round(self.t, 6),
            "peak_torque_ratio": float(ratios[worst]),
            "peak_torque_joint": self.joint_names[worst],
            "peak_torque_nm": {n: round(float(v), 3) for n, v in zip(self.joint_names, self.peak_torque)},
            "torque_limit_nm": {n: round(float(v), 3) for n, v in zip(self.joint_names, self.effort)},
            "peak_grf_n": {side: round(v, 2) for side, v in self.peak_grf.items()},
        }
