"""By-name map between the robot's joint order, Pinocchio's configuration and MuJoCo's.

Conventions: Pinocchio ``q = [p (3), quat (x, y, z, w), joints in Pinocchio order]``;
MuJoCo ``qpos = [p (3), quat (w, x, y, z), joints in MuJoCo order]``. Both place the free
base in the world frame; velocities of the base are world-frame linear in MuJoCo and
body-frame (local) in Pinocchio.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


@dataclass(frozen=True)
class MujocoJointMap:
    """Indices into MuJoCo arrays for each joint of the robot's joint order."""

    prefix: str  # name prefix of the robot in the scene, e.g. "talos/"
    qpos: np.ndarray  # qpos address per joint
    dof: np.ndarray  # qvel / qfrc address per joint
    actuator: np.ndarray  # actuator id per joint
    base_qpos: int  # address of the free joint's 7 qpos
    base_dof: int  # address of the free joint's 6 dofs
    base_body: int

    @classmethod
    def build(cls, m: mujoco.MjModel, joint_names: tuple[str, ...], prefix: str, base_link: str) -> "MujocoJointMap":
        names = [m.joint(i).name for i in range(m.njnt)]
        missing = [prefix + n for n in joint_names if prefix + n not in names]
        if missing:
            raise KeyError(f"joints {missing} not in the MuJoCo model; it has {names}")
        jids = [m.joint(prefix + n).id for n in joint_names]
        acts = [m.actuator(prefix + n).id for n in joint_names]
        root = m.joint(prefix + "root").id
        return cls(
            prefix=prefix,
            qpos=np.array([m.jnt_qposadr[j] for j in jids]),
            dof=np.array([m.jnt_dofadr[j] for j in jids]),
            actuator=np.array(acts),
            base_qpos=int(m.jnt_qposadr[root]),
            base_dof=int(m.jnt_dofadr[root]),
            base_body=m.body(prefix + base_link).id,
        )


def pin_to_mujoco_qpos(q_pin: np.ndarray, pin_q_index: np.ndarray, mj: MujocoJointMap, qpos: np.ndarray) -> None:
    """Write a Pinocchio configuration into MuJoCo's ``qpos`` (in place)."""
    b = mj.base_qpos
    qpos[b : b + 3] = q_pin[:3]
    qpos[b + 3] = q_pin[6]
    qpos[b + 4 : b + 7] = q_pin[3:6]
    qpos[mj.qpos] = q_pin[pin_q_index]


def mujoco_to_pin_q(qpos: np.ndarray, pin_q_index: np.ndarray, mj: MujocoJointMap, nq: int) -> np.ndarray:
    """Pinocchio configuration of the robot whose MuJoCo state is ``qpos``."""
    q = np.zeros(nq)
    b = mj.base_qpos
    q[:3] = qpos[b : b + 3]
    q[3:6] = qpos[b + 4 : b + 7]
    q[6] = qpos[b + 3]
    q[pin_q_index] = qpos[mj.qpos]
    return q
