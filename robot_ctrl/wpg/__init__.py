"""Walking pattern generator (pipeline step 2): MPC on the linear inverted pendulum with a velocity
reference and automatic footsteps, the plan it gives (queried by time), swing trajectories, capturability.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "generator": ["WalkingPatternGenerator"],
    "mpc": ["WalkingMPC"],
    "params": ["WalkParams"],
    "footstep": ["Footstep"],
    "plan": ["GaitPhase", "PlanPreview", "Touchdown", "WalkReference"],
    "swing": ["SwingTrajectory"],
})
