"""Kinematic synthesis (pipeline step 1): a leading Andronov-Hopf oscillator drives learned movement
primitives (anechoic mixtures, step-wise) into the walk-and-reach sequence for a new goal.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "synthesizer": ["Synthesizer", "WalkReachGoal", "GoalJump", "SynthesisError"],
    "primitives": ["WalkReachPrimitives"],
    "learned": ["load_primitives", "load_demonstrations"],
    "step_planning": ["Action"],
})
