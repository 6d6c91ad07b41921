"""GroupWalk: the settings of robots walking together with coupled gaits, and the coupling they
get once its contraction certificate holds."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from robot_ctrl.crowd.certificates import refuse_violated
from robot_ctrl.crowd.coupling_graph import CouplingGraph
from robot_ctrl.crowd.gait_bridge import GaitBridge
from robot_ctrl.crowd.gait_coupling import GaitCoupling
from robot_ctrl.crowd.gait_profile import GaitProfile


@dataclass(frozen=True)
class GroupWalk:
    n: int = 3
    graph: str = "all"
    k: float = 1.0  # step-phase coupling [1/s]
    m_z: float = 1.0  # step-length coupling [1/m]
    m_psi: float = 0.5  # heading consensus [1/s]
    speed: float = 0.2  # [m/s]
    spacing: float = 1.2  # [m]
    coupled_time: float = 10.0  # [s]
    seed: int = 0
    sync_tolerance: float = 0.1  # [rad]
    allow_unstable: bool = False

    def __post_init__(self):
        for name, (lo, hi) in {"n": (2, 8), "spacing": (0.8, 5.0), "speed": (0.05, 0.3),
                               "coupled_time": (1.0, 120.0)}.items():
            value = getattr(self, name)
            if not (np.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"{name} = {value} is outside the allowed range [{lo}, {hi}]")
        if self.seed < 0:
            raise ValueError(f"seed = {self.seed} must be ≥ 0")


def certified_coupling(robot_name: str, g: GroupWalk, step_period: float, log: Callable[[str], None]):
    """The coupling laws, the gait bridge and the certificate, checked before the group moves (the
    gait frequencies the bridge allows bound ω); refuses a violated certificate unless allowed."""
    coupling = GaitCoupling(CouplingGraph.named(g.graph, g.n), k=g.k, m_z=g.m_z, m_psi=g.m_psi)
    bridge = GaitBridge(step_period, g.speed)
    profile = GaitProfile.load_or_constant(robot_name, bridge.omega0, g.speed)
    lo, hi = bridge.time_scale_range  # each robot's step period may stretch anywhere in it
    conditions = coupling.certify(profile.g, bridge.omega0 / hi, omega_max=bridge.omega0 / lo)
    for c in conditions:
        log(c.line())
    refuse_violated(conditions, g.allow_unstable, log)
    return coupling, bridge, profile, conditions
