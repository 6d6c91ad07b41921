"""JointLimits: position, velocity and acceleration limits as bounds on the IK velocity, at every level."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from robot_ctrl.kernels import FLOAT, INDICES, VECTOR, kernel
from robot_ctrl.robot.model import RobotModel


class LimitViolation(ValueError):
    """The configuration given to the IK lies outside the hard (URDF) joint limits, or holds a NaN or ∞."""


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
    joint with, the rest of its torque left for gravity, friction and the other joints' coupling.
    A reference that changes velocity faster than that is a torque the servo's damping asks for and
    cannot give. A configuration outside the hard URDF limits ``[hard_min, hard_max]``, or one
    holding a NaN or ∞, raises :class:`LimitViolation`.
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
        lo, hi = np.empty(self.q_index.size), np.empty(self.q_index.size)
        a_max, a_brake = self._rates
        within = _velocity_bounds(q, self.q_index, dt, self.hard_min, self.hard_max, tol, self.q_min, self.q_max,
                                  self.v_max, a_brake, a_max, _NO_PREVIOUS if previous is None else previous, lo, hi)
        if within == _NOT_FINITE:
            raise LimitViolation("configuration contains NaN or inf")
        if within == _OUTSIDE:
            qj = q[self.q_index]
            outside = np.flatnonzero((qj < self.hard_min - tol) | (qj > self.hard_max + tol))
            detail = ", ".join(f"{self.names[i]} = {qj[i]:.4f} not in [{self.hard_min[i]:.4f}, {self.hard_max[i]:.4f}]"
                               for i in outside)
            raise LimitViolation(f"configuration outside the joint limits: {detail}")
        return lo, hi

    @cached_property
    def _rates(self) -> tuple[np.ndarray, np.ndarray]:
        """``a_max`` and ``a_brake`` with None spelled as ∞ on every joint, for the compiled bounds."""
        none = np.full(self.q_index.size, np.inf)
        return tuple(none if a is None else np.asarray(a, dtype=float) for a in (self.a_max, self.a_brake))


_NO_PREVIOUS = np.zeros(0)  # no previous velocity: no acceleration bound
_WITHIN, _OUTSIDE, _NOT_FINITE = 0, 1, 2  # what _velocity_bounds found


@kernel((VECTOR, INDICES, FLOAT, VECTOR, VECTOR, FLOAT, VECTOR, VECTOR, VECTOR, VECTOR, VECTOR, VECTOR, VECTOR, VECTOR))
def _velocity_bounds(q, q_index, dt, hard_min, hard_max, tol, q_min, q_max, v_max, a_brake, a_max, previous, lo,
                     hi) -> int:
    """:meth:`JointLimits.bounds` joint by joint into ``lo`` and ``hi``: ``_WITHIN``; or
    ``_NOT_FINITE`` when the configuration ``q`` holds a NaN or ∞, ``_OUTSIDE`` when a joint lies
    outside ``[hard_min − tol, hard_max + tol]``. Compiled: it runs every tick on a few dozen joints,
    where numpy's cost per call outweighs the arithmetic. ∞ in ``a_brake`` or ``a_max``: no such
    bound on that joint; an empty ``previous``: no acceleration bound."""
    for x in q:
        if not np.isfinite(x):
            return _NOT_FINITE
    for j in range(q_index.size):
        qj = q[q_index[j]]
        if not hard_min[j] - tol <= qj <= hard_max[j] + tol:
            return _OUTSIDE
        to_min, to_max = (q_min[j] - qj) / dt, (q_max[j] - qj) / dt
        a = a_brake[j]
        if a < np.inf:
            to_min = max(to_min, -_braking(a, -to_min * dt, dt))
            to_max = min(to_max, _braking(a, to_max * dt, dt))
        low = max(-v_max[j], min(0.0, to_min))
        high = min(v_max[j], max(0.0, to_max))
        if previous.size and a_max[j] < np.inf:
            step = a_max[j] * dt
            low, high = min(max(previous[j] - step, low), high), min(max(previous[j] + step, low), high)
        lo[j], hi[j] = low, high
    return _WITHIN


@kernel()
def _braking(a_max: float, distance: float, dt: float) -> float:
    """``b(d) = a (√(dt²/4 + 2 d / a) − dt/2)``: the velocity that steps of ``dt`` decelerating by
    ``a`` bring to rest within ``d ≥ 0`` (``v²/2a + v dt/2 = d``); 0 at or beyond the limit."""
    return a_max * (np.sqrt(dt * dt / 4.0 + 2.0 * max(0.0, distance) / a_max) - dt / 2.0)
