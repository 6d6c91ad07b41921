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


def robot_contacts(m: mujoco.MjModel, d: mujoco.MjData, robot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The active contacts between a geom in the mask ``robot`` and one outside it: the robot's geom
    of each, the other geom, and the world-frame force [N] the robot exerts on the other (k × 3)."""
    ours, theirs, forces, wrench = [], [], [], np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        g1, g2 = int(c.geom1), int(c.geom2)
        if c.efc_address < 0 or robot[g1] == robot[g2]:
            continue
        mujoco.mj_contactForce(m, d, i, wrench)
        force = c.frame.reshape(3, 3).T @ wrench[:3]  # geom1's on geom2
        ours.append(g1 if robot[g1] else g2)
        theirs.append(g2 if robot[g1] else g1)
        forces.append(force if robot[g1] else -force)
    return np.array(ours, dtype=int), np.array(theirs, dtype=int), np.array(forces).reshape(-1, 3)
