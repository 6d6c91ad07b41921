"""CouplingCommander: walking robots whose gaits are coupled by the crowd control laws.

Every pattern-generator sample, each robot's gait frequency, step-length scale and yaw rate come
from the laws (``crowd.gait_coupling``: step phase k, step length m_z, heading m_ψ) evaluated on the
group's gait phases, planned CoM positions along x and headings, all taken at the start of the tick
(before any robot plans it), and the gait bridge (``crowd.gait_bridge``) turns them into each
pattern generator's time scale and velocity. Before the coupling each robot waits its start delay,
then walks at the nominal speed; the coupling starts once all are stepping and runs for
``coupled_time`` seconds, after which every robot is told to stop.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from robot_ctrl.control.controllers.walking_controller import WalkingController
from robot_ctrl.crowd.gait_bridge import GaitBridge
from robot_ctrl.crowd.gait_coupling import GaitCoupling


class CouplingCommander:
    def __init__(self, controllers: Sequence[WalkingController], coupling: GaitCoupling, bridge: GaitBridge,
                 speed: float, start_delays: np.ndarray, coupled_time: float, log: Callable[[str], None] = print):
        self.controllers, self.coupling, self.bridge = list(controllers), coupling, bridge
        self.speed, self.starts, self.coupled_time, self.log = speed, np.asarray(start_delays), coupled_time, log
        self.coupled_since: float | None = None
        self.stop_time: float | None = None
        self.times: list[float] = []  # ticks with the coupling on, and the group at each:
        self.phases: list[list[float]] = []  # gait phases [rad]
        self.positions: list[np.ndarray] = []  # planned CoM x [m]
        self.saturated = self.decisions = 0
        self._t = 0.0
        for i, controller in enumerate(self.controllers):
            controller.on_sample(lambda sample, i=i: self._command(i))

    def begin_tick(self, t: float) -> None:
        self._t = t
        samples = [c.plan_sample() for c in self.controllers]
        self._phi = [s.gait_phase for s in samples]
        self._z = np.array([s.com_xy[0] for s in samples])
        self._headings = np.array([s.heading for s in samples])
        if self.coupled_since is None and all(p is not None for p in self._phi):
            self.coupled_since = t
            self.log(f"t = {t:6.2f} s  all robots stepping: coupling on")
        if self.coupled_since is not None and self.stop_time is None and t - self.coupled_since >= self.coupled_time:
            self.stop_time = t
            self.log(f"t = {t:6.2f} s  stopping")
        if self.coupled_since is not None and self.stop_time is None:
            self.times.append(t)
            self.phases.append(self._phi)
            self.positions.append(self._z)

    def _command(self, i: int) -> None:
        controller = self.controllers[i]
        if self.stop_time is not None or self._t < self.starts[i]:
            controller.set_velocity(0.0, 0.0, 0.0)
        elif self.coupled_since is None:
            controller.set_velocity(self.speed, 0.0, 0.0)
        else:
            phi = np.array(self._phi)
            omega = self.coupling.phase_rates(phi, self._z, self.bridge.omega0)[i]
            mu = self.coupling.step_length_scales(self._z)[i]
            yaw_rate = self.coupling.heading_rates(self._headings)[i]
            command = self.bridge.command(omega, mu, yaw_rate)
            self.saturated += command.saturated
            self.decisions += 1
            controller.set_time_scale(command.time_scale)
            controller.set_velocity(*command.velocity)

    def stopped_for(self, t: float) -> float | None:
        """Time since the stop command [s], None before it."""
        return None if self.stop_time is None else t - self.stop_time
