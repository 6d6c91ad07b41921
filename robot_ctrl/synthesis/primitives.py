"""WalkReachPrimitives: everything learned from the demonstrations, immutable.

- the stepwise anechoic model (:mod:`stepwise`): sources, per-channel delays;
- the phase-plane maps of the sources (:class:`SourceMap`) and the delay rotations;
- per action, locally weighted regressions (thesis 3.4.2): length → duration, and
  (length, duration) → mixing weights, non-periodic weights and mean angles. Action 3 (standing)
  has one model per object slot, with the length of the preceding short cycle as its length input
  (the posture of the last action depends on the step that led to it, thesis Fig. 3.38).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robot_ctrl.robot.model import RobotModel
from robot_ctrl.synthesis.demonstrations import SLOTS, DemonstrationSet
from robot_ctrl.synthesis.lwr import LocallyWeightedRegression
from robot_ctrl.synthesis.source_map import SourceMap, delay_rotations
from robot_ctrl.synthesis.step_planning import Action, ActionRanges
from robot_ctrl.synthesis.stepwise import learn_stepwise, quality_table, resample_actions


@dataclass(frozen=True)
class ActionParams:
    """Parameters of one planned action: what the blending morphs."""

    action: Action
    length: float  # planned pelvis advance [m]
    duration: float  # [s]
    means: np.ndarray  # (C,) mean of each channel
    w0: np.ndarray  # (C,) weight of the non-periodic source
    weights: np.ndarray  # (C, K) weights of the periodic sources

    @property
    def omega(self) -> float:
        return 2 * np.pi / self.duration

    def with_mean(self, channel: int, value: float) -> "ActionParams":
        means = self.means.copy()
        means[channel] = value
        return ActionParams(self.action, self.length, self.duration, means, self.w0, self.weights)


@dataclass(frozen=True)
class _ActionModel:
    """The regressions of one action. A query is held inside what was demonstrated (the input at
    the nearest demonstrated length, the duration within the demonstrated ones): a local linear fit
    extrapolates, and a few neighbouring trials of different speeds can tilt it far enough to
    predict a negative duration just outside them."""

    duration: LocallyWeightedRegression  # length -> duration
    params: LocallyWeightedRegression  # (length, duration) -> [means, w0, weights]
    lengths: tuple[float, float]  # demonstrated input range [m]
    durations: tuple[float, float]  # demonstrated durations [s]

    def predict(self, length: float) -> tuple[float, np.ndarray]:
        x = float(np.clip(length, *self.lengths))
        duration = float(np.clip(self.duration(x)[0], *self.durations))
        return duration, self.params([x, duration])


@dataclass(frozen=True)
class WalkReachPrimitives:
    channels: tuple[str, ...]  # "vx", "vy", "wz", then joint names
    comfort_distance: float  # [m]
    source_map: SourceMap
    rotations: np.ndarray  # (C, K) [rad], −2π τ / T
    n_first: int
    ranges: ActionRanges
    lower: np.ndarray  # (C,) clip range of every channel (joint limits; ±inf for the pelvis)
    upper: np.ndarray
    quality: tuple[dict, ...]  # per action, see stepwise.quality_table
    _models: dict

    @classmethod
    def learn(cls, demos: DemonstrationSet, robot: RobotModel, n_first: int = 3, n_extra: int = 2,
              samples: int = 50) -> "WalkReachPrimitives":
        if demos.robot != robot.name:
            raise ValueError(f"demonstrations are for robot {demos.robot!r}, not {robot.name!r}")
        X = resample_actions(demos, samples)
        model = learn_stepwise(X, n_first, n_extra)
        C, K = model.delays.shape
        lengths = np.array([t.lengths for t in demos.trials])
        durations = np.array([t.durations for t in demos.trials])
        slots = np.array([t.slot for t in demos.trials])
        outputs = np.concatenate([model.means, model.w0, model.weights.reshape(3, len(slots), C * K)], axis=2)
        models = {}
        for action in (1, 2):
            models[(action, None)] = _fit(lengths[:, action - 1], durations[:, action - 1], outputs[action - 1])
        for slot in SLOTS:
            rows = slots == slot
            if rows.any():
                models[(3, slot)] = _fit(lengths[rows, 1], durations[rows, 2], outputs[2][rows])
        names = list(robot.joint_names)
        lower = np.array([robot.lower[names.index(c)] if c in names else -np.inf for c in demos.channels])
        upper = np.array([robot.upper[names.index(c)] if c in names else np.inf for c in demos.channels])
        ranges = ActionRanges((lengths[:, 0].min(), lengths[:, 0].max()), (lengths[:, 1].min(), lengths[:, 1].max()))
        return cls(demos.channels, demos.comfort_distance, SourceMap.fit(model.sources),
                   delay_rotations(model.delays, model.T), n_first, ranges, lower, upper,
                   tuple(quality_table(X, model)), models)

    @property
    def sources(self) -> tuple[int, int]:
        """Periodic sources: for action 1, and the extra ones for actions 2 and 3."""
        return self.n_first, self.rotations.shape[1] - self.n_first

    @property
    def slots(self) -> tuple[str, ...]:
        return tuple(key for action, key in self._models if action == 3)

    def action(self, action: int, length: float, slot: str, previous_length: float = 0.0) -> ActionParams:
        """Predicted parameters of an action of the given pelvis advance [m]; action 3 takes the
        length of the short cycle before it as its input."""
        if action == 3 and slot not in self.slots:
            raise ValueError(f"slot = {slot!r} is not one of the learned object slots {self.slots}")
        model = self._models[(action, slot if action == 3 else None)]
        duration, p = model.predict(previous_length if action == 3 else length)
        C, K = self.rotations.shape
        weights = p[2 * C :].reshape(C, K)
        if action == 1:
            weights[:, self.n_first :] = 0.0  # the extra sources belong to actions 2 and 3
        return ActionParams(action, length, duration, p[:C], p[C : 2 * C], weights)


def _fit(length: np.ndarray, duration: np.ndarray, outputs: np.ndarray) -> _ActionModel:
    return _ActionModel(LocallyWeightedRegression.fit(length, duration),
                        LocallyWeightedRegression.fit(np.stack([length, duration], axis=1), outputs),
                        (float(length.min()), float(length.max())), (float(duration.min()), float(duration.max())))
