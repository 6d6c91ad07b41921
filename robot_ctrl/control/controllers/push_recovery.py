"""Push recovery: the walking plan takes up the measured DCM when a push has carried the robot's
DCM away from the plan's, so that the MPC's automatic footstep placement (Herdt et al. 2010) steps
where the robot now goes; the MPC restarts from the perturbed state as in Wieber 2006 ("Trajectory free
linear model predictive control for stable walking in the presence of strong perturbations").

Per MPC sample, world frame, ξ = c + ċ/ω the DCM (measured from the estimator, planned from the
plan's CoM state)::

    e = ξ_meas − ξ_plan
    Δċ_plan = ω (|e| − d) e / |e|     if |e| > d, else 0                                        (1)

which moves the plan's DCM to within d of the measured one. Simplifications, with the reasons:
only the plan's CoM *velocity* moves, not its position, so the IK's CoM target does not jump (a
reset of both, tried, clamped torques at every reset); the dead band d keeps the normal departure
of an unpushed walk (up to 5 cm on the 3 m walk, docs/robustness.md) out of the plan, whose feet
would otherwise chase the tracking error of every step.
"""

from __future__ import annotations

import numpy as np

#: [m] DCM departure from the plan that the plan takes up only beyond this (1): above the largest
#: of an unpushed walk, and the best of 0.045-0.12 m on the 32 pushes of 0.4 N·s/kg (docs/robustness.md).
DEAD_BAND = 0.08


def plan_velocity_change(dcm_measured: np.ndarray, dcm_planned: np.ndarray, omega: float,
                         dead_band: float = DEAD_BAND) -> np.ndarray | None:
    """Δċ (2,) [m/s] of (1) for the plan's CoM, or None within the dead band."""
    e = np.asarray(dcm_measured, float) - np.asarray(dcm_planned, float)
    n = float(np.linalg.norm(e))
    if not n > dead_band:
        return None
    return omega * (n - dead_band) / n * e
