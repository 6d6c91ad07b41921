"""The control loop (read, step, write, prepare) that runs controllers on hardware, the pacer
that holds it to deadlines on real servos, and a real robot's start sequence.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "control_loop": ["ControlLoop", "LoopResult", "Tick"],
    "pacer": ["Pacer"],
    "start_sequence": ["StartSequence", "StartParams", "StartRefused", "TrackingFault"],
})
