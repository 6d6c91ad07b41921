"""Contact forces between groups of geoms, measured in the MuJoCo world.

What a prop reports of the robot touching it (a hand round a handle, fingers on an object, an elbow
against a cabinet) is read from the physics' own contacts: each active contact's force
(``mj_contactForce``, in the contact frame) turned into the world frame.
"""

from __future__ import annotations

import mujoco
import numpy as np


def geoms_of_bodies(m: mujoco.MjModel, bodies) -> np.ndarray:
    """A mask over the model's geoms: those of ``bodies`` (body ids)."""
    mask = np.zeros(m.ngeom, dtype=bool)
    mask[np.isin(m.geom_bodyid, np.asarray(list(bodies), dtype=int))] = True
    return mask


def subtree(m: mujoco.MjModel, root: int) -> list[int]:
    """The body ``root`` and every body below it (ids)."""
    return [b for b in range(m.nbody) if _has_ancestor(m, b, root)]


def _has_ancestor(m: mujoco.MjModel, body: int, root: int) -> bool:
    while body != root and body != 0:
        body = int(m.body_parentid[body])
    return body == root


def contact_forces(m: mujoco.MjModel, d: mujoco.MjData, on: np.ndarray, by: np.ndarray) -> np.ndarray:
    """The world-frame forces [N] (k × 3) that geoms in the mask ``by`` exert on geoms in the mask
    ``on``, one row per active contact between the two groups."""
    out, wrench = [], np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        if c.efc_address < 0:
            continue
        g1, g2 = int(c.geom1), int(c.geom2)
        if on[g2] and by[g1]:
            sign = 1.0  # the contact force is geom1's on geom2
        elif on[g1] and by[g2]:
            sign = -1.0
        else:
            continue
        mujoco.mj_contactForce(m, d, i, wrench)
        out.append(sign * (c.frame.reshape(3, 3).T @ wrench[:3]))
    return np.array(out).reshape(-1, 3)
