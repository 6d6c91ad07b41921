"""PushCapture: for each push of a walk, the largest impulse in its direction that the linear
inverted pendulum could still capture from the state the push met (``wpg.capturability``): the DCM
and soles measured at the push's first tick, the sole's size, the walking controller's reach and
``MIN_SWING``. A walk that falls under a push below this bound leaves room to its controller; a
push above it cannot be caught by stepping within the same reach (in the LIP: a hip strategy or a
crossing step would be needed)."""

from __future__ import annotations

import numpy as np

from robot_ctrl.geometry import SIDES, rotation, yaw_of
from robot_ctrl.wpg.capturability import CaptureModel, capture_boxes, largest_capturable_impulse

#: [s] shortest swing: below the shortest single support the robot was seen to walk through
#: (0.4 s; 0.3 s fell, docs/robustness.md), so that the bound stays in the robot's favour.
MIN_SWING = 0.3


class PushCapture:
    """Recorder for :class:`~robot_ctrl.control.loop.ControlLoop`: ``pushes`` (``hw.disturbances.Push``)
    act on the walk of ``controller`` (a ``WalkingController``) whose start frame has yaw ``start_yaw``."""

    def __init__(self, controller, pushes, start_yaw: float):
        self.controller, self.start_yaw = controller, start_yaw
        self.pending = sorted(pushes, key=lambda p: p.time)
        self.bounds: list[dict] = []
        self._phase, self._lift = None, 0.0

    def model(self) -> CaptureModel:
        c = self.controller
        p, foot = c.params, c.robot.config.foot
        return CaptureModel(c.stabilizer.omega, (foot.length, foot.width), p.reach_x,
                            (p.step_width + p.reach_y[0], p.step_width + p.reach_y[1]), MIN_SWING)

    def on_command(self, tick) -> None:
        c, t = self.controller, tick.states[0].t
        ref, est = c.reference, c.estimate
        if ref.phase == "single" and self._phase != "single":
            self._lift = t
        self._phase = ref.phase
        while self.pending and t >= self.pending[0].time - 1e-9:
            push = self.pending.pop(0)
            down = [s for s in SIDES if ref.in_contact[s]]
            yaw = yaw_of(est.soles[down[0]].rotation)
            to_sole = rotation(yaw).T  # world → a frame aligned with the (parallel) soles
            centre = np.asarray(c.robot.config.foot.center_offset, float)
            support = {s: to_sole @ est.soles[s].translation[:2] + centre for s in down}
            wait = max(MIN_SWING - (t - self._lift), 0.0) if len(down) == 1 else MIN_SWING
            model = self.model()
            angle = self.start_yaw + push.angle
            bound = largest_capturable_impulse(model, to_sole @ est.dcm(model.omega),
                                               to_sole @ np.array([np.cos(angle), np.sin(angle)]),
                                               capture_boxes(model, support, wait), push.duration)
            self.bounds.append({"time_s": push.time, "support": "+".join(down),
                                "lip_capturable_ns_per_kg": round(bound, 3)})

    def on_state(self, tick) -> None:
        pass

    def report(self) -> list[dict]:
        """Per push, in time order: the support it met and the LIP's largest capturable impulse."""
        return self.bounds
