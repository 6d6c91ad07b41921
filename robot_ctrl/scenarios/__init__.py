"""Scenarios: each assembles a robot, its hardware, controllers, commanders and recorders for one
user task and runs the control loop; no control logic of their own.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "walk": ["run_walk", "WalkSettings"],
    "balance": ["run_balance"],
    "drawer": ["run_drawer"],
    "drawer_task": ["DrawerTask"],
    "group_walk": ["run_group_walk"],
    "gait_profile_walk": ["measure_gait_profile"],
})
