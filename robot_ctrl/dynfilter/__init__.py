"""Dynamic filter (pipeline step 3): multibody ZMP of the planned whole-body motion and the CoM
correction that cancels its deviation from the walking pattern generator's reference.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "dynamic_filter": ["DynamicFilter"],
    "filter_worker": ["DynamicFilterWorker"],
    "multibody_zmp": ["trajectory_zmp"],
})
