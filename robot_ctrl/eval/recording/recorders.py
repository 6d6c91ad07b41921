"""Recorders and stop conditions for :class:`robot_ctrl.control.loop.control_loop.ControlLoop`: fall, torque
and GRF metrics per robot, a progress bar, and the usual ways a run ends."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
from tqdm import tqdm

from robot_ctrl.eval.recording.run_metrics import RunMetrics


class MetricsRecorder:
    """One :class:`RunMetrics` per robot, updated from every state read."""

    def __init__(self, metrics: Sequence[RunMetrics]):
        self.metrics = list(metrics)

    def on_command(self, tick) -> None:
        pass

    def on_state(self, tick) -> None:
        for m, state in zip(self.metrics, tick.states):
            m.update(state)


class Fell:
    """Stops when a robot has fallen (:class:`~robot_ctrl.eval.recording.fall.FallCriterion`)."""

    def __init__(self, metrics: Sequence[RunMetrics]):
        self.metrics = list(metrics)

    def reason(self, tick) -> str | None:
        for i, m in enumerate(self.metrics):
            if m.fell:
                who = f"robot {i} " if len(self.metrics) > 1 else ""
                return f"t = {m.fall_time:6.2f} s  {who}FELL: {m.fall_reason}"
        return None


class TimeLimit:
    """Stops once the robots' time passes ``limit`` seconds."""

    def __init__(self, limit: float, what: str = "the run did not end"):
        self.limit, self.what = limit, what

    def reason(self, tick) -> str | None:
        t = tick.states[0].t
        return f"t = {t:6.2f} s  {self.what} within {self.limit:.1f} s" if t > self.limit else None


class HeldFor:
    """Stops once ``condition()`` has held without a break for ``duration`` seconds of robot time."""

    def __init__(self, condition: Callable[[], bool], duration: float, what: str):
        self.condition, self.duration, self.what = condition, duration, what
        self.since: float | None = None

    def held(self, t: float) -> float:
        """How long the condition has held at time ``t`` [s]."""
        return t - self.since if self.since is not None else 0.0

    def reason(self, tick) -> str | None:
        t = tick.states[0].t
        if not self.condition():
            self.since = None
            return None
        self.since = t if self.since is None else self.since
        return f"t = {t:6.2f} s  {self.what}" if t - self.since >= self.duration else None


class ProgressBar:
    """A terminal progress bar over the run's expected duration (robot seconds), shown when
    ``enabled``; print log lines through :func:`tqdm.tqdm.write` so they do not tear it."""

    def __init__(self, expected_s: float, enabled: bool = True, label: str = "simulated"):
        self.bar = tqdm(total=round(expected_s, 2), unit="s", desc=label, disable=not enabled, leave=False,
                        bar_format="{desc}: {n:.1f}/{total:.1f} s |{bar}| {elapsed} elapsed, {rate_fmt}")
        self._shown = 0.0

    def on_command(self, tick) -> None:
        pass

    def on_state(self, tick) -> None:
        t = tick.states[0].t
        if t - self._shown >= 0.1:  # a tenth of a second at a time: tqdm's call costs more than a tick
            self.bar.update(round(min(t, self.bar.total) - self._shown, 2))
            self._shown = min(t, self.bar.total)

    def close(self) -> None:
        self.bar.close()


class BaseEstimateError:
    """How far the base a controller saw (``seen()``, e.g. an ``EstimatedBaseController``'s) was
    from the measured one (the simulator's), tick by tick: horizontal position and velocity."""

    def __init__(self, seen: Callable[[], object]):
        self.seen = seen
        self.position: list[float] = []
        self.velocity: list[float] = []

    def on_command(self, tick) -> None:
        seen, state = self.seen(), tick.states[0]
        self.position.append(float(np.linalg.norm(seen.base_pos[:2] - state.base_pos[:2])))
        self.velocity.append(float(np.linalg.norm(seen.base_linvel[:2] - state.base_linvel[:2])))

    def on_state(self, tick) -> None:
        pass

    def report(self) -> dict:
        """Horizontal errors against the simulator: position max and final [m], velocity RMS and max [m/s]."""
        v = np.array(self.velocity)
        return {"position_error_max_m": round(max(self.position), 4), "position_error_final_m": round(self.position[-1], 4),
                "velocity_error_rms_mps": round(float(np.sqrt(np.mean(v**2))), 4),
                "velocity_error_max_mps": round(float(v.max()), 4)}
