"""DynamicFilter: corrects the CoM plan for the dynamics the linear inverted pendulum leaves out
(thesis 3.8.1-3.8.2, after Kajita et al. 2003 and Stasse et al. 2008).

At every pattern-generator sample, for the plan over the horizon (CoM and feet from the WPG's
preview, upper body from its reference), each pass:

1. solves the whole-body motion (``PreviewIK``: the controller's IK tasks as one weighted
   least-squares Newton step per horizon sample), from the controller's current reference
   configuration;
2. computes its multibody ZMP (``multibody_zmp``: Pinocchio inverse dynamics, finite differences);
3. takes the error against the WPG's reference ZMP and updates the CoM offset by preview control
   (``PreviewCorrection``), a Newton-like step (thesis: "a kind of Newton-Raphson iteration").

``passes`` repeats 1-3 with the corrected CoM. Modes: ``off`` (no correction), ``legs`` (the upper
body is frozen at its current reference over the horizon, the thesis's magenta curve) and
``full`` (the planned upper-body motion is included). The controller adds the offset (and its
velocity) to the CoM reference it gives the IK; the reference ZMP is unchanged (it is what the
real ZMP should follow).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import pinocchio as pin

from robot_ctrl.dynfilter.multibody_zmp import trajectory_zmp
from robot_ctrl.dynfilter.preview_correction import PreviewCorrection
from robot_ctrl.dynfilter.preview_ik import PreviewIK
from robot_ctrl.geometry import SIDES, mean_yaw
from robot_ctrl.modes import FilterMode
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.wpg.plan import PlanPreview

DOUBLE_SUPPORT_WEIGHT = 0.1  # of the ZMP error in double-support samples (see PreviewCorrection)
# The guard (a filter that never hurts): an update is refused, and the offset plan led smoothly back
# to zero (the unfiltered plan), when a pass's weighted RMS error exceeds MAX_ZMP_ERROR, when a pass
# more than doubles the first pass's error (the Newton-like iteration diverges), or when the offset
# plan leaves ±MAX_OFFSET. On the 0.25 m/s arm-swing walk the passes stay below 35 mm and the offset
# below 21 mm; at 0.5 m/s without the guard the error grew past 1 m and the robot fell.
MAX_ZMP_ERROR = 0.06  # [m]
MAX_OFFSET = 0.06  # [m]


@dataclass(frozen=True)
class ComOffset:
    """The filter's correction of the planned CoM at one instant (world frame): what the controller
    adds to the plan's CoM and its velocity."""

    position: np.ndarray  # (2,) [m]
    velocity: np.ndarray  # (2,) [m/s]


class DynamicFilter:
    def __init__(self, robot: RobotModel, horizon: int, com_height: float, mode: FilterMode | str = FilterMode.FULL,
                 passes: int = 2):
        self.check_settings(mode, passes)
        self.robot = robot
        self.mode = FilterMode(mode)
        self.passes = passes
        self.correction = PreviewCorrection(horizon, com_height)
        self._data = robot.pin.createData()
        self._ik = PreviewIK(robot)
        self._last_T: float | None = None
        self.last_error: np.ndarray | None = None  # (N − 1, 2) multibody − reference ZMP of the last pass
        self.pass_rms: list[float] = []  # weighted RMS of that error at each pass of the last update [m]
        self.fallbacks = 0  # updates refused by the guard

    @staticmethod
    def check_settings(mode: FilterMode | str, passes: int) -> None:
        FilterMode.parse(mode)
        if not (isinstance(passes, int) and 1 <= passes <= 10):
            raise ValueError(f"dynfilter passes = {passes!r} must be an integer in [1, 10]")

    def update(self, plan: PlanPreview, q_ref: np.ndarray, com_z: float, sole_height: float,
               posture: Callable[[float], np.ndarray]) -> None:
        """Refine the CoM offset for the sample the WPG just solved (``plan``). ``q_ref``: the IK's
        current reference configuration; ``posture(t)``: the upper-body (posture task) target at
        time t; ``com_z``, ``sole_height``: the controller's constants."""
        if self.mode is not FilterMode.OFF:
            self.refine(filter_request(self.mode, plan, q_ref, com_z, sole_height, posture))

    def refine(self, request: FilterRequest) -> None:
        """Carry the offset plan to the request's sample and run the passes on its plan."""
        T, preview = request.plan.sample_duration, request.plan.samples
        if self._last_T is not None:
            self.correction.advance(self._last_T)
        self._last_T = T
        reference = np.array([s.zmp for s in preview])
        weights = np.array([1.0 if s.single_support else DOUBLE_SUPPORT_WEIGHT for s in preview[1:]])
        targets = _sample_targets(preview, request.sole_height, request.postures)
        carried = self.correction.state.copy(), self.correction.jerks.copy()
        self.pass_rms = []
        for _ in range(self.passes):
            offsets = self.correction.offsets(T)
            qs = self._whole_body(preview, offsets, targets, request.q_ref, request.com_z)
            zmp = trajectory_zmp(self.robot.pin, self._data, qs, T)
            error = zmp - reference[1:-1]  # samples 1..N−1
            self.last_error = error
            w = weights[:-1, None]
            self.pass_rms.append(float(np.sqrt(np.sum((w * error) ** 2) / (2 * np.sum(w**2)))))
            if self.pass_rms[-1] > min(MAX_ZMP_ERROR, 2 * self.pass_rms[0] + 1e-3):
                break
            self.correction.newton_step(np.vstack([error, error[-1:]]), T, weights)  # sample N holds N−1's error
        else:
            if np.abs(self.correction.offsets(T)).max() <= MAX_OFFSET:
                return
        self.fallbacks += 1
        self.correction.state, self.correction.jerks = carried
        self.correction.return_to_zero(T)

    def offset(self, tau: float) -> ComOffset:
        """The CoM offset ``tau`` seconds into the current sample."""
        if self.mode is FilterMode.OFF:
            return ComOffset(np.zeros(2), np.zeros(2))
        return ComOffset(*self.correction.at(tau))

    def close(self) -> None:
        """Nothing to release (``DynamicFilterWorker.close`` ends its process)."""

    def _whole_body(self, preview, offsets, targets, q_ref, com_z) -> list[np.ndarray]:
        ik = self._ik
        ik.set_configuration(q_ref)
        qs = []
        for sample, offset, (feet, waist, posture) in zip(preview, offsets, targets):
            com = np.array([*(sample.com + offset), com_z])
            # Sample 0 starts from the controller's reference, which the stabilizer has moved off the
            # plan: converge onto the plan first, so the trajectory does not begin with a jump.
            for _ in range(1 if qs else 3):
                ik.step(feet, com, waist, posture)
            qs.append(ik.q.copy())
        return qs


@dataclass(frozen=True)
class FilterRequest:
    """One filter update's input as plain data (it can cross to a worker process): the WPG's
    plan over the horizon (world frame), the IK reference configuration the preview starts from,
    the CoM height and sole height [m] the controller holds, and the posture target (joint order,
    rad) at each preview sample."""

    plan: PlanPreview
    q_ref: np.ndarray
    com_z: float
    sole_height: float
    postures: np.ndarray  # (N + 1, nj)


def filter_request(mode: FilterMode, plan: PlanPreview, q_ref: np.ndarray, com_z: float, sole_height: float,
                   posture: Callable[[float], np.ndarray]) -> FilterRequest:
    """The request for the solved sample ``plan``; in ``legs`` mode the posture is frozen at its
    value at the sample's start."""
    if mode is FilterMode.FULL:
        postures = np.array([posture(plan.t0 + s.t) for s in plan.samples])
    else:
        postures = np.tile(posture(plan.t0), (len(plan.samples), 1))
    return FilterRequest(plan, np.array(q_ref, dtype=float), com_z, sole_height, postures)


def _sample_targets(preview, sole_height: float, postures) -> list[tuple[list[pin.SE3], np.ndarray, np.ndarray]]:
    """Per preview sample, the IK targets every pass shares: sole poses (left, right; world frame),
    waist rotation (the feet's mean heading) and the posture (joint order)."""
    targets = []
    for sample, posture in zip(preview, postures):
        feet = [pin.SE3(pin.utils.rpyToMatrix(0.0, 0.0, sample.feet[s].yaw),
                        sample.feet[s].position + [0.0, 0.0, sole_height]) for s in SIDES]
        yaw = mean_yaw([sample.feet[s].yaw for s in SIDES])
        targets.append((feet, pin.utils.rpyToMatrix(0.0, 0.0, yaw), posture))
    return targets
