"""What crosses the hardware interface: the measured JointState and the JointCommand.

Per-joint arrays are in the robot config's joint order (``RobotConfig.joint_names``). SI units:
m, rad, s, N, N·m.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np

from robot_ctrl.kernels import VECTOR, kernel

#: Readings a simulated scene's props may report per tick (``JointState.scene``).
SCENE_CHANNELS = 16


class LifecycleState(enum.Enum):
    """Where a hardware adapter is in its lifecycle: ``UNCONFIGURED`` → ``INACTIVE`` →
    ``ACTIVE``; ``FAULT`` after a hardware fault, ``ESTOP`` after an emergency stop (both need
    ``reset``). Only ``ACTIVE`` accepts commands."""

    UNCONFIGURED = "unconfigured"
    INACTIVE = "inactive"
    ACTIVE = "active"
    FAULT = "fault"
    ESTOP = "estop"


class CommandError(ValueError):
    """A JointCommand was rejected before reaching any actuator. The message names the field."""


@dataclass(frozen=True)
class JointState:
    """One sample of the robot's measured state.

    Optional fields are ``None`` where the backend has no such sensor.

    - ``base_pos`` [m], ``base_quat_xyzw``: pose of the base link in the world frame
      (z up, floor at z = 0).
    - ``base_linvel`` [m/s]: base-link origin velocity in the world frame.
    - ``base_angvel`` [rad/s], ``base_linacc`` [m/s²]: gyro and accelerometer (proper
      acceleration, gravity included) in the base-link frame, as an IMU on the base reads them;
      the gyro as its mean over the control period that ended with the reading (an IMU's delta
      angle over the period, divided by it), so that the rotations read compose to the base's.
    - ``foot_wrench``: per side ("left"/"right"), the contact wrench on the foot (the floor's, and
      that of anything else the foot touches),
      ``[fx, fy, fz, mx, my, mz]`` [N, N·m] expressed in the sole frame about its origin,
      as a force/torque sensor moved to the sole would read it.
    - ``tau``: torque applied by each joint's servo, after saturation [N·m].
    - ``tau_demand``: per joint, the signed servo torque of largest magnitude demanded *before*
      saturation over the last control period [N·m] (simulation backends; shows a saturating servo).
    - ``floor_contacts``: names of bodies other than the feet that touch the floor (simulation).
    - ``temperature``: per joint, the servo's reported temperature [°C] (bus backends).
    - ``scene``: readings of the simulated scene's props, the simulation's ground truth for reports
      (never for control): at most ``SCENE_CHANNELS`` numbers, named by the prop that reports them
      (e.g. ``geometry.drawer_geometry.DRAWER_READINGS``).
    """

    t: float
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    base_pos: np.ndarray | None = None
    base_quat_xyzw: np.ndarray | None = None
    base_linvel: np.ndarray | None = None
    base_angvel: np.ndarray | None = None
    base_linacc: np.ndarray | None = None
    foot_wrench: dict[str, np.ndarray] | None = None
    tau_demand: np.ndarray | None = None
    floor_contacts: tuple[str, ...] = field(default=())
    temperature: np.ndarray | None = None
    scene: np.ndarray | None = None

    def replaced(self, **fields) -> JointState:
        """``dataclasses.replace(self, **fields)`` without running ``__init__`` again (a frozen
        dataclass's sets every field through ``object.__setattr__``): filters replace fields of
        every tick's state between the read and the command."""
        unknown = fields.keys() - self.__dict__.keys()
        if unknown:
            raise TypeError(f"JointState has no fields {sorted(unknown)}")
        state = object.__new__(JointState)
        state.__dict__.update(self.__dict__, **fields)
        return state

    def problem(self, nj: int) -> str | None:
        """Why this sample cannot be trusted (time, joint positions, velocities or temperatures
        that are not ``nj`` finite real numbers; a body sensor's reading, where there is one, not
        finite numbers of its shape), or None."""
        arrays = self._arrays(nj)
        if self._sound(arrays):
            return None
        for name, value, shape in [("t", self.t, ()), *arrays]:
            array = np.asarray(value)
            if array.dtype.kind not in "fiu":
                return f"JointState.{name} is not real numbers (dtype {array.dtype})"
            if array.shape != shape:
                return f"JointState.{name} has shape {array.shape}, expected {shape}"
            if not np.isfinite(array).all():
                return f"JointState.{name} is not finite at {np.flatnonzero(~np.isfinite(array.reshape(-1))).tolist()}"
        return None

    def _arrays(self, nj: int) -> list[tuple[str, object, tuple[int, ...]]]:
        """``(name, value, expected shape)`` of every array field :meth:`problem` checks."""
        arrays = [("q", self.q, (nj,)), ("dq", self.dq, (nj,))]
        for name, shape in (("temperature", (nj,)), ("base_pos", (3,)), ("base_quat_xyzw", (4,)),
                            ("base_linvel", (3,)), ("base_angvel", (3,)), ("base_linacc", (3,))):
            if getattr(self, name) is not None:
                arrays.append((name, getattr(self, name), shape))
        for side, wrench in (self.foot_wrench or {}).items():
            arrays.append((f"foot_wrench[{side!r}]", wrench, (6,)))
        return arrays

    def _sound(self, arrays) -> bool:
        """:meth:`problem`'s usual answer, quickly (one check over every array): the time and every
        array field finite floats of their shape. False sends it to the field-by-field check, which
        names what is wrong."""
        if not isinstance(self.t, (float, int)) or isinstance(self.t, bool) or not math.isfinite(self.t):
            return False
        for _, array, shape in arrays:
            if type(array) is not np.ndarray or array.dtype != np.float64 or array.shape != shape:
                return False
        return bool(np.isfinite(np.concatenate([array for _, array, _ in arrays])).all())

    def body_fields(self) -> dict:
        """The fields measured by body sensors (base pose, IMU, foot F/T, floor contacts), for a
        backend that reads the joints itself and takes the rest from another source."""
        return dict(base_pos=self.base_pos, base_quat_xyzw=self.base_quat_xyzw, base_linvel=self.base_linvel,
                    base_angvel=self.base_angvel, base_linacc=self.base_linacc, foot_wrench=self.foot_wrench,
                    floor_contacts=self.floor_contacts, scene=self.scene)


@dataclass(frozen=True)
class JointCommand:
    """Servo command per joint: ``tau = kp (q - q_meas) + kd (dq - dq_meas) + tau_ff``.

    ``q`` [rad], ``dq`` [rad/s], ``kp`` [N·m/rad], ``kd`` [N·m·s/rad], ``tau_ff`` [N·m].
    """

    q: np.ndarray
    dq: np.ndarray
    kp: np.ndarray
    kd: np.ndarray
    tau_ff: np.ndarray

    def validate(self, nj: int) -> None:
        """Raise CommandError unless every field has ``nj`` finite real entries and gains are ≥ 0."""
        q, dq, kp, kd, tau_ff = self.q, self.dq, self.kp, self.kd, self.tau_ff
        if (type(q) is type(dq) is type(kp) is type(kd) is type(tau_ff) is np.ndarray
                and q.dtype == dq.dtype == kp.dtype == kd.dtype == tau_ff.dtype == np.float64
                and q.shape == dq.shape == kp.shape == kd.shape == tau_ff.shape == (nj,)
                and _sound_command(q, dq, kp, kd, tau_ff)):
            return  # the usual answer, quickly: every command passes here, twice on its way to the servos
        names = ("q", "dq", "kp", "kd", "tau_ff")
        for name in names:
            array = np.asarray(getattr(self, name))
            if array.shape != (nj,):
                raise CommandError(f"JointCommand.{name} has shape {array.shape}, expected ({nj},)")
            if array.dtype.kind not in "fiu":
                raise CommandError(f"JointCommand.{name} is not real numbers (dtype {array.dtype})")
        values = np.array([getattr(self, name) for name in names], dtype=float)  # one check for all fields
        if not np.isfinite(values).all():
            name, bad = next((n, np.flatnonzero(~np.isfinite(v))) for n, v in zip(names, values) if not np.isfinite(v).all())
            raise CommandError(f"JointCommand.{name} is not finite at joint indices {bad.tolist()}")
        if (values[2:4] < 0).any():
            name, bad = next((n, np.flatnonzero(v < 0)) for n, v in zip(names[2:4], values[2:4]) if (v < 0).any())
            raise CommandError(f"JointCommand.{name} must be >= 0; negative at joint indices {bad.tolist()}")


@kernel((VECTOR, VECTOR, VECTOR, VECTOR, VECTOR))
def _sound_command(q, dq, kp, kd, tau_ff) -> bool:
    """Every entry finite, the gains ≥ 0 (float arrays of one length)."""
    for i in range(q.size):
        if not (math.isfinite(q[i]) and math.isfinite(dq[i]) and math.isfinite(tau_ff[i])
                and 0.0 <= kp[i] < math.inf and 0.0 <= kd[i] < math.inf):
            return False
    return True
