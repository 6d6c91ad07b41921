"""Self-collision exclusions for a robot that ships no SRDF, computed as MoveIt's setup assistant does.

MoveIt Setup Assistant ("Self-Collisions" pane, ``compute_default_collisions.cpp``) disables the
checking of a link pair when the pair is

- *adjacent*: one link is the other's parent in the kinematic tree; a link without collision
  geometry counts as no link, so that its parent and children are all adjacent to each other;
- *default*: in collision at the robot's default posture (here the config's standing posture);
- *always*: in collision in at least ``ALWAYS_FRACTION`` of random configurations;
- *never*: in collision in none of ``SAMPLES`` random configurations.

Every other pair stays checked. The configurations are drawn uniformly within the joints' position
limits with a fixed seed, so the result is reproducible; it is computed once per converted scene
and stored in the scene's cache as MuJoCo ``<exclude>`` pairs. Collisions are MuJoCo's own contact
detection on the robot's collision geometry, with no parent filtering and every geom enabled.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

#: Random configurations sampled (MoveIt's default sampling density is 10 000).
SAMPLES = 10_000
#: A pair in collision in at least this share of the samples is always in collision (MoveIt: 95 %).
ALWAYS_FRACTION = 0.95
SEED = 0


@dataclass(frozen=True)
class CollisionExclusions:
    """Body-name pairs whose contacts are never checked, by MoveIt's reason."""

    adjacent: tuple[tuple[str, str], ...]
    default: tuple[tuple[str, str], ...]
    always: tuple[tuple[str, str], ...]
    never: tuple[tuple[str, str], ...]

    @property
    def pairs(self) -> tuple[tuple[str, str], ...]:
        return self.adjacent + self.default + self.always + self.never


def _colliding_pairs(m: mujoco.MjModel, d: mujoco.MjData) -> set[tuple[int, int]]:
    mujoco.mj_kinematics(m, d)
    mujoco.mj_collision(m, d)
    bodies = m.geom_bodyid[d.contact.geom[: d.ncon]] if d.ncon else np.zeros((0, 2), dtype=int)
    return {(min(a, b), max(a, b)) for a, b in bodies.tolist() if a != b}


def _adjacent(m: mujoco.MjModel, has_geoms: set[int]) -> set[tuple[int, int]]:
    """Pairs of bodies with geometry linked in the kinematic tree, a link without geometry between
    them counting as no link (MoveIt's connection graph: such a link's neighbours are each other's)."""
    neighbours = {b: set() for b in range(1, m.nbody)}
    for b in range(1, m.nbody):
        parent = int(m.body_parentid[b])
        if parent != 0:
            neighbours[b].add(parent)
            neighbours[parent].add(b)
    for b in [b for b in neighbours if b not in has_geoms]:
        around = neighbours.pop(b)
        for n in around:
            neighbours[n] |= around - {n}
            neighbours[n].discard(b)
    return {(min(a, b), max(a, b)) for a, around in neighbours.items() for b in around}


def compute_exclusions(spec: mujoco.MjSpec, posture: dict[str, float], samples: int = SAMPLES,
                       seed: int = SEED) -> CollisionExclusions:
    """The pairs of ``spec``'s bodies (a robot alone, no floor) whose collisions need no checking.

    ``posture``: joint name -> angle [rad] of the default (standing) configuration.
    """
    probe = spec.copy()
    for geom in probe.geoms:
        geom.contype, geom.conaffinity = 1, 1
    probe.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_FILTERPARENT
    m = probe.compile()
    d = mujoco.MjData(m)
    with_geoms = sorted({int(b) for b in m.geom_bodyid if b != 0})
    pairs = {(a, b) for i, a in enumerate(with_geoms) for b in with_geoms[i + 1:]}
    adjacent = _adjacent(m, set(with_geoms))
    remaining = pairs - adjacent

    hinges = [j for j in range(m.njnt) if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE]
    adr = m.jnt_qposadr[hinges]
    lo, hi = m.jnt_range[hinges, 0], m.jnt_range[hinges, 1]
    limited = m.jnt_limited[hinges].astype(bool)
    lo, hi = np.where(limited, lo, -np.pi), np.where(limited, hi, np.pi)

    d.qpos[:] = m.qpos0
    for j, a in zip(hinges, adr):
        d.qpos[a] = posture.get(m.joint(j).name, 0.0)
    default = _colliding_pairs(m, d) & remaining
    remaining -= default

    counts = dict.fromkeys(remaining, 0)
    rng = np.random.default_rng(seed)
    for _ in range(samples):
        d.qpos[adr] = rng.uniform(lo, hi)
        for pair in _colliding_pairs(m, d) & remaining:
            counts[pair] += 1
    always = {p for p, n in counts.items() if n >= ALWAYS_FRACTION * samples}
    never = {p for p, n in counts.items() if n == 0}

    def names(group: set[tuple[int, int]]) -> tuple[tuple[str, str], ...]:
        return tuple(sorted(tuple(sorted((m.body(a).name, m.body(b).name))) for a, b in group))

    return CollisionExclusions(names(adjacent), names(default), names(always), names(never))
