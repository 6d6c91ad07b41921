"""PushCapture: for each push of a walk, the largest impulse in its direction that the linear
inverted pendulum could still capture from the state the push met (``wpg.capturability``): the DCM
and soles measured at the push's first tick, the sole's size, the walking controller's reach and
``MIN_SWING``. A walk that falls under a push below this bound leaves room to its controller; a
push above it cannot be caught by stepping within the same reach (in the LIP: a hip strategy or a
crossing step would be needed).

A second bound keeps the walk's own step timing: the swing foot lands when the plan says (the
current single support runs to its end; from double support only the trailing foot lifts) and every
later swing lasts the walk's single support. A push between the two bounds needs the step timing
to change (landing early), which the walking controller does not do."""

from __future__ import annotations

import numpy as np

from robot_ctrl.geometry import SIDES, rotation, yaw_of
from robot_ctrl.wpg.capturability import CaptureModel, capture_boxes, largest_capturable_impulse
from robot_ctrl.wpg.plan import GaitPhase

#: [s] shortest swing: below the shortest single support the robot was seen to walk through
#: (0.4 s; 0.3 s fell, docs/robustness.md), so that the bound stays in the robot's favour.
MIN_SWING = 0.3


class PushCapture:
    """Recorder for :class:`~robot_ctrl.control.loop.control_loop.ControlLoop`: ``pushes`` (``hw.disturbances.Push``)
    act on the walk of ``controller`` (a ``WalkingController``) whose start frame has yaw ``start_yaw``."""

    def __init__(self, controller, pushes, start_yaw: float):
        self.controller, self.start_yaw = controller, start_yaw
        self.pending = sorted(pushes, key=lambda p: p.time)
        self.bounds: list[dict] = []
        self._phase, self._lift = None, 0.0

    def model(self, min_swing: float = MIN_SWING) -> CaptureModel:
        c = self.controller
        p, foot = c.params, c.robot.config.foot
        return CaptureModel(c.stabilizer.omega, (foot.length, foot.width), p.reach_x,
                            (p.step_width + p.reach_y[0], p.step_width + p.reach_y[1]), min_swing)

    def on_command(self, tick) -> None:
        c, t = self.controller, tick.states[0].t
        ref, est = c.reference, c.estimate
        if ref.phase is GaitPhase.SINGLE and self._phase is not GaitPhase.SINGLE:
            self._lift = t
        self._phase = ref.phase
        while self.pending and t >= self.pending[0].time - 1e-9:
            push = self.pending.pop(0)
            down = [s for s in SIDES if ref.in_contact[s]]
            yaw = yaw_of(est.soles[down[0]].rotation)
            to_sole = rotation(yaw).T  # world → a frame aligned with the (parallel) soles
            centre = np.asarray(c.robot.config.foot.center_offset, float)
            support = {s: to_sole @ est.soles[s].translation[:2] + centre for s in down}
            model, own = self.model(), self.model(c.params.single_support * c.wpg.time_scale)
            elapsed = t - self._lift if len(down) == 1 else 0.0
            boxes = capture_boxes(model, support, max(MIN_SWING - elapsed, 0.0))
            own_boxes = capture_boxes(own, support, max(own.min_swing - elapsed, 0.0),
                                      stays=c.wpg.stance if len(down) == 2 else None)
            angle = self.start_yaw + push.angle
            dcm, direction = to_sole @ est.dcm(model.omega), to_sole @ np.array([np.cos(angle), np.sin(angle)])
            bound, own_bound = (largest_capturable_impulse(m, dcm, direction, b, push.duration)
                                for m, b in ((model, boxes), (own, own_boxes)))
            self.bounds.append({"time_s": push.time, "support": "+".join(down),
                                "lip_capturable_ns_per_kg": round(bound, 3),
                                "lip_capturable_own_timing_ns_per_kg": round(own_bound, 3)})

    def on_state(self, tick) -> None:
        pass

    def report(self) -> list[dict]:
        """Per push, in time order: the support it met and the LIP's largest capturable impulses, with
        the earliest landing and with the walk's own step timing."""
        return self.bounds
