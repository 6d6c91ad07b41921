"""RobotModel: the immutable Pinocchio model of a robot with its config, limits and servo gains.

Arrays named per joint (``lower``, ``effort``, ``kp``...) are in the config's joint order, the
order used at the hardware interface. ``q_index``/``v_index`` place those joints in Pinocchio's
configuration and velocity vectors. Mutable computation buffers (``pinocchio.Data``) belong to
the caller: ``model.pin.createData()``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Mapping

import numpy as np
import pinocchio as pin

from robot_ctrl.kernels import INDICES, INT, VECTOR, kernel
from robot_ctrl.robot.config import AddedFrame, ConfigError, RobotConfig
from robot_ctrl.robot.config_file import load_robot_config
from robot_ctrl.robot.description import RobotFiles, read_srdf, robot_files
from robot_ctrl.robot.mjcf import cached_scene_mjcf


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A robot, immutable: its config, its description files, the Pinocchio model (free flyer,
    Pinocchio's joint order), the index of each actuated joint in q and v, the frames of its roles,
    its half-sitting posture, gains and limits, and its cached MuJoCo scene. ``load_robot("talos")``."""

    config: RobotConfig
    files: RobotFiles
    pin: pin.Model  # free-flyer model, armature set from the config
    q_index: np.ndarray  # Pinocchio q index of each joint
    v_index: np.ndarray  # Pinocchio v index of each joint
    frame_ids: dict[str, int]  # role ("left_foot", "right_hand", "torso", ...) -> Pinocchio frame id
    lower: np.ndarray  # URDF position limits [rad]
    upper: np.ndarray
    velocity_limit: np.ndarray  # URDF [rad/s]
    effort: np.ndarray  # URDF effort limit [N·m]
    armature: np.ndarray  # reflected rotor inertia [kg·m²]
    kp: np.ndarray  # default servo stiffness [N·m/rad]
    kd: np.ndarray  # default servo damping [N·m·s/rad]
    joint_inertia: np.ndarray  # each joint's diagonal of the mass matrix at half-sitting, armature included [kg·m²]
    q_half_sitting: np.ndarray  # Pinocchio configuration, base at the world origin

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.config.joint_names

    @property
    def nj(self) -> int:
        return len(self.config.joint_names)

    @cached_property
    def mass(self) -> float:
        return float(sum(inertia.mass for inertia in self.pin.inertias))

    @cached_property
    def mjcf_path(self) -> Path:
        """The cached MuJoCo scene of this robot on the floor (converted on first use)."""
        return cached_scene_mjcf(self.config, self.files, self.kp, self.kd, self.effort, self.armature)

    def group_mjcf_path(self, prefixes: tuple[str, ...]) -> Path:
        """A cached MuJoCo scene with one copy of this robot per name prefix (``<prefix>/``)."""
        return cached_scene_mjcf(self.config, self.files, self.kp, self.kd, self.effort, self.armature, prefixes)

    def joints_from_q(self, q: np.ndarray) -> np.ndarray:
        """Joint angles in the robot's joint order from a Pinocchio configuration."""
        return q[self.q_index]


def load_robot(name_or_config: str | RobotConfig) -> RobotModel:
    """Build the RobotModel for a robot name (``talos``), YAML path or parsed config."""
    config = name_or_config if isinstance(name_or_config, RobotConfig) else load_robot_config(name_or_config)
    files = robot_files(config)
    model = pin.buildModelFromUrdf(str(files.urdf), pin.JointModelFreeFlyer())

    names = list(model.names)
    missing = [n for n in config.joint_names if n not in names]
    if missing:
        raise ConfigError(f"half_sitting names joints not in the URDF: {missing}; the URDF has: {names[2:]}")
    jids = [model.getJointId(n) for n in config.joint_names]
    if any(model.joints[j].nq != 1 for j in jids):
        raise ConfigError("every joint in half_sitting must be a 1-dof revolute or prismatic joint")
    q_index = np.array([model.joints[j].idx_q for j in jids])
    v_index = np.array([model.joints[j].idx_v for j in jids])

    for frame in config.added_frames:
        add_frame(model, frame)
    frame_ids = {}
    for role, frame in config.frames.items():
        if not model.existFrame(frame):
            have = sorted({f.name for f in model.frames if f.type == pin.FrameType.BODY})
            raise ConfigError(f"frame {frame!r} ({role}) not in the URDF; body frames: {have}")
        frame_ids[role] = model.getFrameId(frame)

    if config.servo.armature == "srdf":
        rotor = read_srdf(files.srdf).rotor_armature
        armature = np.array([rotor.get(n, 0.0) for n in config.joint_names])
    elif isinstance(config.servo.armature, Mapping):
        armature = np.array([config.servo.armature.get(n, 0.0) for n in config.joint_names])
    else:
        armature = np.full(len(jids), float(config.servo.armature))
    model.armature[v_index] = armature

    q0 = pin.neutral(model)
    q0[q_index] = config.half_sitting
    # The half-sitting posture must itself respect the URDF limits.
    lower, upper = model.lowerPositionLimit[q_index].copy(), model.upperPositionLimit[q_index].copy()
    bad = [(n, a) for n, a, lo, hi in zip(config.joint_names, config.half_sitting, lower, upper) if not lo <= a <= hi]
    if bad:
        raise ConfigError(f"half_sitting angles outside the URDF limits: {bad}")

    effort = model.effortLimit[v_index].copy()
    kp = config.servo.kp_per_effort * effort
    data = model.createData()
    mass_diag = np.diag(pin.crba(model, data, q0))[v_index]  # crba includes the armature
    kd = 2.0 * config.servo.damping_ratio * np.sqrt(kp * mass_diag)

    return RobotModel(
        config=config, files=files, pin=model, q_index=q_index, v_index=v_index, frame_ids=frame_ids,
        lower=lower, upper=upper, velocity_limit=model.velocityLimit[v_index].copy(), effort=effort,
        armature=armature, kp=kp, kd=kd, joint_inertia=mass_diag, q_half_sitting=q0,
    )


def add_frame(model: pin.Model, frame: AddedFrame) -> None:
    """Add a config's frame to the Pinocchio model, fixed to its parent link."""
    if model.existFrame(frame.name):
        raise ConfigError(f"added_frames.{frame.name}: the URDF already has a frame of that name")
    if not model.existFrame(frame.parent, pin.FrameType.BODY):
        raise ConfigError(f"added_frames.{frame.name}.parent {frame.parent!r} is not a link of the URDF")
    parent_id = model.getFrameId(frame.parent, pin.FrameType.BODY)
    parent = model.frames[parent_id]
    offset = pin.SE3(pin.rpy.rpyToMatrix(*frame.rpy), np.array(frame.xyz))
    model.addFrame(pin.Frame(frame.name, parent.parentJoint, parent_id, parent.placement * offset,
                             pin.FrameType.OP_FRAME))


def measured_configuration(robot: RobotModel, base_pos: np.ndarray, base_quat_xyzw: np.ndarray,
                           base_linvel: np.ndarray, base_angvel: np.ndarray, joints: np.ndarray,
                           joint_velocities: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pinocchio's ``(q, v)`` from a measured state: the base's world position and orientation, its
    linear velocity in the world frame and angular velocity in the base frame (an IMU's gyro), and
    the joints in the robot's order. Pinocchio's free-flyer velocity is in the base frame:
    ``v[:3] = Rᵀ ċ_world``. Compiled: the estimator asks it on every tick."""
    if np.shape(joints) != (robot.nj,) or np.shape(joint_velocities) != (robot.nj,):
        raise ValueError(f"measured_configuration: {np.shape(joints)} joint angles and {np.shape(joint_velocities)} "
                         f"velocities, the robot has ({robot.nj},)")
    return _measured_configuration(robot.q_half_sitting, robot.q_index, robot.v_index, robot.pin.nv,
                                   *(np.asarray(a, dtype=float) for a in (base_pos, base_quat_xyzw, base_linvel,
                                                                          base_angvel, joints, joint_velocities)))


@kernel((VECTOR, INDICES, INDICES, INT, VECTOR, VECTOR, VECTOR, VECTOR, VECTOR, VECTOR))
def _measured_configuration(q_template, q_index, v_index, nv, base_pos, quat, linvel, angvel, joints, velocities):
    q = _configuration(q_template, q_index, base_pos, quat, joints)
    x, y, z, w = q[3], q[4], q[5], q[6]
    # Rᵀ ċ, R the rotation of the unit quaternion (x, y, z, w): its columns are the base's axes
    r00, r10, r20 = 1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + z * w), 2.0 * (x * z - y * w)
    r01, r11, r21 = 2.0 * (x * y - z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + x * w)
    r02, r12, r22 = 2.0 * (x * z + y * w), 2.0 * (y * z - x * w), 1.0 - 2.0 * (x * x + y * y)
    v = np.zeros(nv)
    v[0] = r00 * linvel[0] + r10 * linvel[1] + r20 * linvel[2]
    v[1] = r01 * linvel[0] + r11 * linvel[1] + r21 * linvel[2]
    v[2] = r02 * linvel[0] + r12 * linvel[1] + r22 * linvel[2]
    v[3], v[4], v[5] = angvel[0], angvel[1], angvel[2]
    for i in range(v_index.size):
        v[v_index[i]] = velocities[i]
    return q, v


def configuration(robot: RobotModel, base_pos: np.ndarray, base_quat_xyzw: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """Pinocchio configuration from a world-frame base pose and joint angles in the robot's order."""
    joints = np.asarray(joints, dtype=float)
    if joints.shape != (robot.nj,):
        raise ValueError(f"configuration: {joints.shape} joint angles, the robot has ({robot.nj},)")
    return _configuration(robot.q_half_sitting, robot.q_index, np.asarray(base_pos, dtype=float),
                          np.asarray(base_quat_xyzw, dtype=float), joints)


@kernel((VECTOR, INDICES, VECTOR, VECTOR, VECTOR))
def _configuration(q_template, q_index, base_pos, quat, joints):
    q = q_template.copy()
    norm = math.sqrt(quat[0] ** 2 + quat[1] ** 2 + quat[2] ** 2 + quat[3] ** 2)
    q[0], q[1], q[2] = base_pos[0], base_pos[1], base_pos[2]
    q[3], q[4], q[5], q[6] = quat[0] / norm, quat[1] / norm, quat[2] / norm, quat[3] / norm
    for i in range(q_index.size):
        q[q_index[i]] = joints[i]
    return q
