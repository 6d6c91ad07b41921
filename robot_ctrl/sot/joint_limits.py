"""JointLimits: position, velocity and acceleration limits as bounds on the IK velocity, at every level."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from robot_ctrl.robot.model import RobotModel


class LimitViolation(ValueError):
    """The configuration given to the IK lies outside the hard (URDF) joint limits."""


@dataclass(frozen=True)
class JointLimits:
    """Bounds ``lo ≤ v_j ≤ hi`` for the actuated dofs ``v_index`` over one step ``dt``. From the
    position and velocity limits, with the distance in which the joint can still brake::

        lo_p = max(-v_max, min(0, max((q_min - q) / dt, -b(q - q_min))))
        hi_p = min(v_max, max(0, min((q_max - q) / dt, b(q_max - q))))

    with ``b(d) = a_brake (√(dt²/4 + 2 d / a_brake) − dt/2)`` the fastest velocity from which steps
    of ``dt`` decelerating by ``a_brake`` stop within ``d`` (``v²/2a + v dt/2 = d``, the discrete form of
    ``√(2 a d)``); and, given the IK's previous velocity ``v⁻``, from the acceleration limit, inside
    those::

        lo = clip(v⁻ - a_max dt, lo_p, hi_p),  hi = clip(v⁻ + a_max dt, lo_p, hi_p)

    (the joint-space bounds of Flacco, De Luca and Khatib, IEEE T-RO 31(3), 2015, §III, on the
    velocity; where the acceleration limit and the position limit disagree, the position wins).

    The braking distance uses ``a_brake`` (None: none; ∞ on a joint: none on it), which may be set
    without ``a_max``: a joint then accelerates as its tasks ask (within what its servo can give, a
    controller's :func:`~robot_ctrl.sot.servo_bounds.servo_velocity_bounds`) but reaches a soft
    limit slowly enough for its servo to stop it there; stopped at the limit by the position bound
    alone, a joint arriving at speed asks its servo for ``kd × speed``.

    ``[q_min, q_max]`` are the URDF limits shrunk by the config's margin (soft limits): the IK
    never moves a joint into the margin, and a joint already inside it may stay or move out of
    it. ``v_max`` is the URDF velocity limit times the config's fraction. ``a_max`` (None: no
    acceleration limit; ∞ on a joint: none on it) is ``share × effort / M_ii``, the config's share
    of the effort limit over the joint's inertia at half-sitting: what the servo can accelerate the
    joint with, the rest of its torque left for gravity, friction and the other joints' coupling. A reference that changes velocity
    faster than that is a torque the servo's damping asks for and cannot give. A configuration
    outside the hard URDF limits ``[hard_min, hard_max]`` raises :class:`LimitViolation`.
    """

    q_index: np.ndarray
    v_index: np.ndarray
    names: tuple[str, ...]
    hard_min: np.ndarray
    hard_max: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray | None = None
    a_brake: np.ndarray | None = None

    @classmethod
    def from_robot(cls, robot: RobotModel, accelerated: np.ndarray | None = None) -> "JointLimits":
        """``accelerated``: velocity indices of the joints whose acceleration is bounded too (a
        controller's IK, whose velocity the servos follow); None: none (a kinematic planner). Their
        ``a_max`` comes from the config's ``limits.acceleration_fraction``, their braking
        deceleration ``a_brake`` before a soft limit from the smaller of ``limits.braking_fraction``
        and that; both unset: no such bound."""
        c = robot.config
        def share_of_effort(share: float | None) -> np.ndarray | None:
            if accelerated is None or share is None:
                return None
            return np.where(np.isin(robot.v_index, accelerated), share * robot.effort / robot.joint_inertia, np.inf)

        a_max = share_of_effort(c.acceleration_fraction)
        shares = [f for f in (c.braking_fraction, c.acceleration_fraction) if f is not None]
        a_brake = share_of_effort(min(shares) if shares else None)  # never braking harder than accelerating
        soft_min, soft_max = robot.lower + c.position_margin, robot.upper - c.position_margin
        for joint, (lo, hi) in c.ik_ranges.items():  # narrower ranges of the config (an arm kept off the torso)
            i = robot.joint_names.index(joint)
            soft_min[i], soft_max[i] = max(soft_min[i], lo), min(soft_max[i], hi)
        return cls(robot.q_index, robot.v_index, robot.joint_names, robot.lower, robot.upper, soft_min, soft_max,
                   robot.velocity_limit * c.velocity_fraction, a_max, a_brake)

    def bounds(self, q: np.ndarray, dt: float, previous: np.ndarray | None = None,
               tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
        """``previous``: the IK's velocity of the last step on the bounded dofs (None: no
        acceleration bound, as at a start)."""
        qj = q[self.q_index]
        if (qj < self.hard_min - tol).any() or (qj > self.hard_max + tol).any():
            outside = np.flatnonzero((qj < self.hard_min - tol) | (qj > self.hard_max + tol))
            detail = ", ".join(f"{self.names[i]} = {qj[i]:.4f} not in [{self.hard_min[i]:.4f}, {self.hard_max[i]:.4f}]"
                               for i in outside)
            raise LimitViolation(f"configuration outside the joint limits: {detail}")
        to_min, to_max = (self.q_min - qj) / dt, (self.q_max - qj) / dt
        if self.a_brake is not None:
            bounded, a = self._braked
            to_min = np.where(bounded, np.maximum(to_min, -_braking(a, -to_min * dt, dt)), to_min)
            to_max = np.where(bounded, np.minimum(to_max, _braking(a, to_max * dt, dt)), to_max)
        # ufuncs rather than np.clip: this runs every tick on a few dozen joints, where the wrapper costs most.
        lo = np.maximum(-self.v_max, np.minimum(0.0, to_min))
        hi = np.minimum(self.v_max, np.maximum(0.0, to_max))
        if self.a_max is None or previous is None:
            return lo, hi
        step = self.a_max * dt
        return (np.minimum(np.maximum(previous - step, lo), hi),
                np.minimum(np.maximum(previous + step, lo), hi))

    @cached_property
    def _braked(self) -> tuple[np.ndarray, np.ndarray]:
        """The joints with a braking deceleration, and it (1 where there is none)."""
        bounded = np.isfinite(self.a_brake)
        return bounded, np.where(bounded, self.a_brake, 1.0)


def _braking(a_max: np.ndarray, distance: np.ndarray, dt: float) -> np.ndarray:
    """``b(d) = a (√(dt²/4 + 2 d / a) − dt/2)``: the velocity that steps of ``dt`` decelerating by
    ``a`` bring to rest within ``d ≥ 0`` (``v²/2a + v dt/2 = d``); 0 at or beyond the limit."""
    return a_max * (np.sqrt(dt * dt / 4.0 + 2.0 * np.maximum(0.0, distance) / a_max) - dt / 2.0)
