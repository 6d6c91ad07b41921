"""BaseEstimator: the floating base's pose and velocity from body sensors, as on a real robot.

A walking controller needs the base's position and linear velocity (world frame), which no sensor
measures. This estimator builds them from what a humanoid does measure: the IMU (attitude
estimate, gyro, accelerometer), the joint encoders and the feet's force/torque sensors. It is
the kinematics + IMU complementary filter of Flayols et al., "Experimental evaluation of simple
estimators for humanoid robots", Humanoids 2017 (evaluated there on HRP-2):

- **Contact**: a foot whose normal force exceeds ``contact_share`` of the weight becomes a contact,
  and stays one until its force drops below ``release_share`` (hysteresis against sensor noise).
  Its anchor is its sole's world position (from the current estimate) on the floor plane ``z = 0``,
  averaged over its first ``anchor_samples`` samples (one sample carries the attitude noise times
  the leg's 1 m lever); then the anchor stays put while the foot is a contact.
- **Position** (leg odometry): each contact foot s gives ``p_b = a_s − R p_s^b(q)``, where ``a_s``
  is its anchor, ``R`` the IMU attitude and ``p_s^b`` the sole's position in the base frame from
  the encoders; the feet's values are averaged with weights proportional to their normal forces,
  and the estimate, carried forward by the velocity, follows them with time constant ``τ_p``.
  Without any contact, the position integrates the velocity.
- **Velocity**: each contact foot, standing still, gives ``v_kin = −R (v_s^b + ω × p_s^b)``
  (``ω``: gyro, base frame; ``v_s^b``: the sole's velocity relative to the base from the encoder
  velocities), force-weighted as above. The accelerometer's ``a = R a_imu + g`` carries the high
  frequencies: ``v ← v + a dt``, then ``v ← v + dt / (τ + dt) (v_kin − v)``, a first-order
  complementary filter of time constant ``τ``.
- **Attitude**: the IMU's own attitude estimate, with its yaw referred to the start: the robot's
  world frame is its start pose ``start_xy_yaw`` (the soles on the floor, z = 0).

The contact hysteresis, the anchors' averaging and the position's filter are ours, against sensor
noise. Simplifications (stated in docs/hardware.md): the floor is flat and level (anchors at z = 0);
the IMU's yaw is taken as it comes (a real IMU's drifts; the path follower then follows a slowly
turning frame); a foot slipping while it carries weight is not detected.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robot_ctrl.geometry import GRAVITY, SIDES, yaw_of
from robot_ctrl.hw.types import JointState
from robot_ctrl.robot.model import RobotModel, configuration


@dataclass(frozen=True)
class BaseEstimatorParams:
    contact_share: float = 0.15  # share of the robot's weight on a foot that makes it a contact
    release_share: float = 0.05  # ... and below which it stops being one (hysteresis against sensor noise)
    velocity_time_constant: float = 0.05  # [s] τ_v: kinematics below 1 / (2π τ_v), accelerometer above
    position_time_constant: float = 0.05  # [s] τ_p: leg odometry below 1 / (2π τ_p), the velocity above
    anchor_samples: int = 20  # a new contact's anchor is the mean of its first samples (attitude noise)


class BaseEstimator:
    """Call :meth:`update` with every measured state; it returns the state as the controller should
    see it: ``base_pos``, ``base_quat_xyzw`` and ``base_linvel`` estimated (the measured ones are
    never read), everything else as measured."""

    def __init__(self, robot: RobotModel, start_xy_yaw, params: BaseEstimatorParams = BaseEstimatorParams()):
        self.robot, self.params = robot, params
        self.start = np.asarray(start_xy_yaw, dtype=float)
        self.data = robot.pin.createData()
        self._soles = {s: robot.frame_ids[f"{s}_foot"] for s in SIDES}
        weight = robot.mass * GRAVITY
        self._make, self._release = params.contact_share * weight, params.release_share * weight
        self._yaw_offset: float | None = None
        self._anchors: dict[str, np.ndarray | None] = {s: None for s in SIDES}
        self._samples = {s: 0 for s in SIDES}  # of the anchor's running mean
        self.position = np.zeros(3)
        self.velocity = np.zeros(3)
        self._t: float | None = None

    def update(self, state: JointState) -> JointState:
        if state.base_quat_xyzw is None or state.base_angvel is None or state.foot_wrench is None:
            raise ValueError("the base estimator needs the IMU (attitude and gyro) and the feet's force sensors")
        rot = self._attitude(state.base_quat_xyzw)
        gyro = np.asarray(state.base_angvel, dtype=float)
        soles, sole_velocities = self._sole_kinematics(state)  # base frame
        forces = {s: max(float(state.foot_wrench[s][2]), 0.0) for s in SIDES}
        contacts = [s for s in SIDES if forces[s] > (self._release if self._anchors[s] is not None else self._make)]
        if self._t is None:  # the start: both feet flat on the floor at the start pose
            self.position = np.array([*self.start[:2], -float(np.mean([(rot @ soles[s])[2] for s in SIDES]))])
            contacts = list(SIDES)
        dt = 0.0 if self._t is None else state.t - self._t
        self._t = state.t
        if dt > 0:
            self.position = self.position + dt * self.velocity
            if state.base_linacc is not None:
                self.velocity = self.velocity + dt * (rot @ np.asarray(state.base_linacc, float) - [0.0, 0.0, GRAVITY])
        for side in SIDES:
            if side not in contacts:
                self._anchors[side] = None
            elif self._anchors[side] is None or self._samples[side] < self.params.anchor_samples:
                sole = self.position + rot @ soles[side]
                n = 0 if self._anchors[side] is None else self._samples[side]
                anchor = sole if n == 0 else self._anchors[side] + (sole - self._anchors[side]) / (n + 1)
                anchor[2] = 0.0
                self._anchors[side], self._samples[side] = anchor, n + 1
        if contacts:
            weights = np.array([forces[s] for s in contacts]) + 1e-9
            weights /= weights.sum()
            odometry = sum(w * (self._anchors[s] - rot @ soles[s]) for w, s in zip(weights, contacts))
            kinematic = sum(w * -(rot @ (sole_velocities[s] + np.cross(gyro, soles[s])))
                            for w, s in zip(weights, contacts))
            self.position = self.position + self._gain(dt, self.params.position_time_constant) * (odometry - self.position)
            self.velocity = self.velocity + self._gain(dt, self.params.velocity_time_constant) * (kinematic - self.velocity)
        quat = pin.Quaternion(rot)
        return state.replaced(base_pos=self.position.copy(), base_linvel=self.velocity.copy(),
                              base_quat_xyzw=np.array([quat.x, quat.y, quat.z, quat.w]))

    @property
    def contacts(self) -> tuple[str, ...]:
        """The feet anchored at the last update."""
        return tuple(s for s in SIDES if self._anchors[s] is not None)

    @staticmethod
    def _gain(dt: float, time_constant: float) -> float:
        """Complementary filter's correction gain ``dt / (τ + dt)`` (1 at the first sample)."""
        return 1.0 if dt <= 0 else dt / (time_constant + dt)

    def _attitude(self, quat_xyzw) -> np.ndarray:
        """The IMU's attitude with its yaw referred to the start pose's (world frame)."""
        x, y, z, w = np.asarray(quat_xyzw, dtype=float)
        imu = pin.Quaternion(w, x, y, z).normalized().matrix()
        if self._yaw_offset is None:
            self._yaw_offset = float(self.start[2]) - yaw_of(imu)
        return pin.utils.rpyToMatrix(0.0, 0.0, self._yaw_offset) @ imu

    def _sole_kinematics(self, state: JointState) -> tuple[dict, dict]:
        """Each sole's position [m] and velocity [m/s] relative to the base, in the base frame,
        from the encoders (base fixed at the origin)."""
        r = self.robot
        q = configuration(r, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), state.q)
        v = np.zeros(r.pin.nv)
        v[r.v_index] = state.dq
        pin.forwardKinematics(r.pin, self.data, q, v)
        positions, velocities = {}, {}
        for side, frame in self._soles.items():
            positions[side] = pin.updateFramePlacement(r.pin, self.data, frame).translation.copy()
            velocities[side] = pin.getFrameVelocity(r.pin, self.data, frame, pin.LOCAL_WORLD_ALIGNED).linear.copy()
        return positions, velocities



class EstimatedBaseController:
    """A controller that sees the base through a :class:`BaseEstimator` instead of the measured
    base pose and velocity (which only a simulator has). ``seen``: the state of the last step, as
    the controller saw it."""

    def __init__(self, controller, estimator: BaseEstimator):
        self.controller, self.estimator = controller, estimator
        self.seen: JointState | None = None

    def prepare(self) -> None:
        self.controller.prepare()

    def step(self, state: JointState):
        self.seen = self.estimator.update(state)
        return self.controller.step(self.seen)

    def close(self) -> None:
        self.controller.close()
