"""Conversion of a robot's URDF into a cached MuJoCo scene (MJCF).

The scene is ``sim/floor.xml`` with the robot attached under the name prefix ``<robot>/``:
free-floating base, one position servo per actuated joint, the config's added frames (massless
bodies fixed to their link), sole boxes in place of the feet's URDF collision geometry where the
config asks, self-collision exclusions from the SRDF (computed, when the robot ships none, by
:mod:`robot_ctrl.robot.self_collision`), ``implicitfast`` integrator and the config's physics step.

Linkages: a URDF joint with a ``<mimic>`` tag whose leader is one of the robot's joints moves with
it in the simulation, even where the URDF made it ``fixed`` (a reduced model's gripper fingers): a
hinge on its axis and within its limits, coupled to the leader by a joint equality
``q = offset + multiplier q_leader``. The robot's own mechanism, driven by the leader's one servo;
the planning model (Pinocchio) keeps such joints as the URDF states them. MuJoCo collides a mesh
by its convex hull: where that hull would fill space the real link leaves open (a C-shaped frame),
the config's ``simulation.links_without_collision`` are left without collision.
The result is written
to a cache (``$ROBOT_CTRL_CACHE`` or ``~/.cache/robot_ctrl``) keyed by a hash of everything
that goes into it; nothing generated is ever committed.

Servo model (MuJoCo ``general`` actuator, gain ``fixed``, bias ``affine``)::

    tau = kp * ctrl + b0 - kp * q - kd * dq,   clipped to ±effort limit

with ``ctrl = q_des`` and ``b0 = kd * dq_des + tau_ff`` set by the hardware backend at each
write, which is exactly the servo law ``kp (q_des - q) + kd (dq_des - dq) + tau_ff``. The
velocity term is integrated implicitly by ``implicitfast``.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np

from robot_ctrl import ROOT, __version__
from robot_ctrl.robot import self_collision
from robot_ctrl.robot.config import ConfigError, FootGeometry, RobotConfig
from robot_ctrl.robot.description import RobotFiles, example_robot_data_version, read_srdf, resolve_package_uris
from robot_ctrl.robot.self_collision import compute_exclusions

SCENE = ROOT / "sim" / "floor.xml"
#: [kg·m²] A coupled linkage joint's rotor inertia: its links weigh grams, and without one the equality's
#: stiffness against them is beyond what the physics step integrates.
_LINKAGE_ARMATURE = 1e-4
_COMPILER = '<mujoco><compiler strippath="false" discardvisual="true" fusestatic="false" autolimits="true"/></mujoco>'


def cache_dir() -> Path:
    return Path(os.environ.get("ROBOT_CTRL_CACHE", Path.home() / ".cache" / "robot_ctrl"))


def robot_spec(config: RobotConfig, files: RobotFiles, kp: np.ndarray, kd: np.ndarray,
               effort: np.ndarray, armature: np.ndarray) -> mujoco.MjSpec:
    """The robot alone as an ``MjSpec``: free base, servos, armature, added frames, sole boxes and
    self-collision exclusions.

    ``kp``, ``kd``, ``effort``, ``armature`` are in the config's joint order.
    """
    urdf = resolve_package_uris(files.urdf.read_text())
    head = urdf.index(">", urdf.index("<robot")) + 1
    # fusestatic must stay off: otherwise the root link merges into the world (no floating base).
    spec = mujoco.MjSpec.from_string(urdf[:head] + _COMPILER + urdf[head:])
    root = spec.worldbody.first_body()
    if root.name != config.base_link:
        raise ConfigError(f"description.base_link {config.base_link!r} is not the URDF root (root is {root.name!r})")
    root.add_freejoint(name="root")
    hinges = {j.name: j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_HINGE}
    missing = [n for n in config.joint_names if n not in hinges]
    if missing:
        raise ConfigError(f"half_sitting names joints not in the URDF: {missing}; the URDF has: {sorted(hinges)}")
    for i, name in enumerate(config.joint_names):
        hinges[name].armature = float(armature[i])
        act = spec.add_actuator()
        act.name = name
        act.target = name
        act.trntype = mujoco.mjtTrn.mjTRN_JOINT
        act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        act.gainprm[0] = kp[i]
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.biasprm[0:3] = [0.0, -kp[i], -kd[i]]
        act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        act.forcerange = [-effort[i], effort[i]]
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    _couple_mimic_joints(spec, urdf, set(config.joint_names), config.timestep)
    for frame in config.added_frames:
        parent = spec.body(frame.parent)
        if parent is None:
            raise ConfigError(f"added_frames.{frame.name}.parent {frame.parent!r} is not a link of the URDF")
        parent.add_body(name=frame.name, pos=list(frame.xyz), quat=_quat_wxyz(frame.rpy))
    for link in config.links_without_collision:
        body = spec.body(link)
        if body is None:
            raise ConfigError(f"simulation.links_without_collision: {link!r} is not a link of the URDF")
        for geom in body.geoms:
            geom.contype = geom.conaffinity = 0
    if config.foot.box_height is not None:
        for side, sole in config.feet.items():
            _replace_foot_collision(spec, sole, config.foot)
    if files.srdf is not None:
        pairs = read_srdf(files.srdf).disabled_collisions
    else:
        pairs = compute_exclusions(spec, dict(zip(config.joint_names, config.half_sitting))).pairs
    bodies = {b.name for b in spec.bodies}
    for a, b in pairs:
        if a in bodies and b in bodies:
            ex = spec.add_exclude()
            ex.bodyname1, ex.bodyname2 = a, b
    return spec


def _couple_mimic_joints(spec: mujoco.MjSpec, urdf: str, servoed: set[str], timestep: float) -> None:
    """Each URDF joint that mimics one of the ``servoed`` joints, and has no servo of its own, moves
    coupled to its leader (module docstring): a hinge is added where the URDF made it fixed."""
    for joint in ET.fromstring(urdf).iter("joint"):
        name, mimic = joint.get("name"), joint.find("mimic")
        if mimic is None or mimic.get("joint") not in servoed or name in servoed:
            continue
        if spec.joint(name) is None:
            axis, limit = joint.find("axis"), joint.find("limit")
            hinge = spec.body(joint.find("child").get("link")).add_joint(
                name=name, type=mujoco.mjtJoint.mjJNT_HINGE,
                axis=[float(x) for x in (axis.get("xyz") if axis is not None else "1 0 0").split()])
            if limit is not None:
                hinge.range = [float(limit.get("lower", 0.0)), float(limit.get("upper", 0.0))]
            hinge.armature = _LINKAGE_ARMATURE
        coupling = spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1=name, name2=mimic.get("joint"))
        coupling.data[0:2] = [float(mimic.get("offset", 0.0)), float(mimic.get("multiplier", 1.0))]
        # A linkage is rigid: the constraint as stiff as the physics step integrates (MuJoCo's default
        # time constant, 20 ms, lets a fingertip pushed by a handle swing out of the way).
        coupling.solref = [2 * timestep, 1.0]
        coupling.solimp = [0.95, 0.99, 0.001, 0.5, 2.0]


def _quat_wxyz(rpy: tuple[float, float, float]) -> list[float]:
    quat = np.zeros(4)
    mujoco.mju_euler2Quat(quat, np.asarray(rpy, dtype=float), "XYZ")
    return quat.tolist()


def _replace_foot_collision(spec: mujoco.MjSpec, sole: str, foot: FootGeometry) -> None:
    """The foot link's collision geometry (the sole frame's parent link) replaced by one box: the sole
    rectangle, ``foot.box_height`` tall, its bottom face on the sole frame. The box belongs to the
    foot link, massless (the URDF's inertial data holds the foot's mass): a contact on a massless body
    of its own is numerically softer in MuJoCo, and G1 standing on one foot tipped over on it."""
    body = spec.body(sole)
    link = body.parent
    for geom in list(link.geoms) + list(body.geoms):
        spec.delete(geom)
    half = np.array([foot.length / 2, foot.width / 2, foot.box_height / 2])
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(body.quat, dtype=float))
    centre = np.asarray(body.pos, dtype=float) + rotation.reshape(3, 3) @ [*foot.center_offset, half[2]]
    link.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=half.tolist(), mass=0.0, pos=centre.tolist(),
                  quat=list(body.quat))


def scene_spec(robots: dict[str, mujoco.MjSpec], timestep: float, scene: Path = SCENE) -> mujoco.MjSpec:
    """Attach each robot spec to the scene under the prefix ``<key>/``."""
    spec = mujoco.MjSpec.from_file(str(scene))
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    for prefix, robot in robots.items():
        spec.attach(robot, frame=spec.worldbody.add_frame(), prefix=f"{prefix}/")
    return spec


def cached_scene_mjcf(config: RobotConfig, files: RobotFiles, kp: np.ndarray, kd: np.ndarray,
                      effort: np.ndarray, armature: np.ndarray, prefixes: tuple[str, ...] | None = None) -> Path:
    """Path of the cached scene MJCF, converting it first if the cache lacks it. The scene holds one
    copy of the robot per prefix (default: one, named after the robot)."""
    prefixes = (config.name,) if prefixes is None else tuple(prefixes)
    if not prefixes or len(set(prefixes)) != len(prefixes):
        raise ValueError(f"prefixes {prefixes} must be non-empty and distinct")
    key = hashlib.sha256()
    # The scene names its mesh files by absolute path: where the description lies is part of the key,
    # so two installs (two virtual environments) never share a scene that points into the other.
    # The converter's own code is part of the key: a changed conversion never reuses an old scene.
    for part in (__version__, mujoco.__version__, example_robot_data_version(), repr(config), repr(prefixes),
                 Path(__file__).read_bytes(), Path(self_collision.__file__).read_bytes(),
                 str(files.urdf.resolve()), files.urdf.read_bytes(), files.srdf.read_bytes() if files.srdf else b"",
                 SCENE.read_bytes(), kp.tobytes(), kd.tobytes(), effort.tobytes(), armature.tobytes()):
        key.update(part if isinstance(part, bytes) else part.encode())
    name = config.name if len(prefixes) == 1 else f"{config.name}x{len(prefixes)}"
    path = cache_dir() / f"{name}-{key.hexdigest()[:16]}.xml"
    if path.is_file():
        return path
    spec = scene_spec({prefix: robot_spec(config, files, kp, kd, effort, armature) for prefix in prefixes},
                      config.timestep)
    spec.compile()
    path.parent.mkdir(parents=True, exist_ok=True)
    # Write to a temporary file and rename, so a concurrent or interrupted run never sees half a file.
    with tempfile.NamedTemporaryFile("w", dir=path.parent, suffix=".tmp", delete=False) as tmp:
        tmp.write(spec.to_xml())
    os.replace(tmp.name, path)
    return path
