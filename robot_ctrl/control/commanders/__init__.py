"""Commanders: what steers a controller through its command API at its sample hook (a path,
the walk-and-reach synthesis and its hands, the naive baseline, the crowd's gait coupling).
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "path_commander": ["PathCommander"],
    "path_follower": ["PathFollower", "WalkGoal"],
    "walk_reach_commander": ["WalkReachCommander"],
    "naive_commander": ["NaiveCommander"],
    "coupling_commander": ["CouplingCommander"],
    "drawer_hands": ["DrawerHands"],
    "drawer_targets": ["DrawerTargets"],
    "synthesized_body": ["SynthesizedBody"],
})
