"""Coupled gaits of several humanoids: coupling graphs, contraction certificates, crowd simulation.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "coupling_graph": ["CouplingGraph"],
    "certificates": ["CouplingConfig", "certify"],
    "gait_coupling": ["GaitCoupling"],
    "gait_profile": ["GaitProfile"],
    "hopf_network": ["simulate_crowd"],
})
