"""Multibody ZMP of a whole-body motion (Pinocchio inverse dynamics).

For a free-floating robot with no external force but the floor contacts, the recursive
Newton-Euler algorithm's free-flyer torque ``τ_base = rnea(q, v, a)[:6]`` is the contact wrench the
floor must supply, expressed in the base joint frame (the free flyer is the model's first joint). Moved to the world origin (force F, moment M),
the ZMP on the floor plane z = 0 is::

    p_x = −M_y / F_z,   p_y = M_x / F_z

(the point about which the contact moment has no horizontal component). For a static posture
(v = a = 0) this is the CoM's ground projection.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def multibody_zmp(model: pin.Model, data: pin.Data, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    """ZMP (2,) [m] on z = 0, world frame, of configuration ``q`` moving with ``v``, ``a``
    (Pinocchio conventions: base velocity in the base frame)."""
    tau = pin.rnea(model, data, q, v, a)
    # The free-flyer's placement straight from q: rnea does not refresh data.oMi.
    wrench = pin.XYZQUATToSE3(q[:7]).act(pin.Force(tau[:6]))
    return np.array([-wrench.angular[1] / wrench.linear[2], wrench.angular[0] / wrench.linear[2]])


def trajectory_zmp(model: pin.Model, data: pin.Data, qs: list[np.ndarray], dt: float) -> np.ndarray:
    """Multibody ZMP (n − 2, 2) at the interior samples of a configuration trajectory sampled every
    ``dt`` seconds, velocities and accelerations by central differences on the configuration manifold."""
    out = np.empty((len(qs) - 2, 2))
    for j in range(1, len(qs) - 1):
        back = pin.difference(model, qs[j - 1], qs[j])
        ahead = pin.difference(model, qs[j], qs[j + 1])
        out[j - 1] = multibody_zmp(model, data, qs[j], (back + ahead) / (2 * dt), (ahead - back) / (dt * dt))
    return out
