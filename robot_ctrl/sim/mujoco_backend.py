"""MuJoCo simulation backend of the hardware interface, stepping the physics in lock-step.

Alone in its world, each ``write()`` applies the servo command and simulates one control period
(``control_dt / timestep`` physics steps) before it returns; run the backend in a
:class:`~robot_ctrl.sim.robot_process.RobotProcess` to compute while the robot moves, as on a real
robot. In a world shared with other robots
(:class:`~robot_ctrl.sim.mujoco_world.MujocoWorld`), ``write()`` only applies the command and the
world steps once all robots have written. ``read()`` returns the state at the current time.
With a command latency of a period or more (``Disturbances.latency``), the next period's command is
already written when a write returns: ``run_ahead()`` simulates that period then (a
``RobotProcess`` calls it while the controller computes) and the next write only queues its
command. The states read are lock-step's, bit for bit; a lifecycle call after a period run ahead
finds the robot that period further on, as a real robot would be.
The robot starts in its half-sitting posture with the lowest point of its feet on the floor.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import mujoco
import numpy as np

from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.robot.joint_map import MujocoJointMap, pin_to_mujoco_qpos
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.sim.disturbances import Disturbances
from robot_ctrl.sim.mujoco_video import Video
from robot_ctrl.sim.mujoco_world import MujocoWorld
from robot_ctrl.sim.prop import Prop


class MujocoBackend(HardwareAdapter):
    """Simulated robot. ``base_xy_yaw`` places the robot's start pose in the world (m, m, rad);
    ``video``: an MP4 of the robot's own world (a shared world takes its own ``video``).

    Without ``world`` the robot gets a world of its own (its cached single-robot scene, with
    ``prop`` in it: e.g. the drawer cabinet of the walk-and-reach task, ``sim/drawer_cabinet.py``).
    With ``world``, ``prefix`` names the robot's copy in that scene (``<prefix>/`` joints and bodies).
    """

    def __init__(self, robot: RobotModel, control_dt: float = 0.005, base_xy_yaw=(0.0, 0.0, 0.0),
                 viewer: bool = False, world: MujocoWorld | None = None, prefix: str | None = None,
                 video: Video | Path | None = None, disturbances: Disturbances = Disturbances(),
                 prop: Prop | None = None):
        super().__init__(robot.nj)
        self.robot = robot
        self._owns_world = world is None
        if prop is not None and world is not None:
            raise ValueError("a prop goes into a robot's own world, not a shared one")
        scene = robot.mjcf_path if prop is None else prop.scene_mjcf(robot)
        self.world = (MujocoWorld(scene, control_dt, viewer, video, disturbances.friction_scale)
                      if world is None else world)
        self.world.attach()
        self.m, self.d = self.world.m, self.world.d
        self.control_dt = self.world.control_dt
        prefix = f"{robot.name if prefix is None else prefix}/"
        self.map = MujocoJointMap.build(self.m, robot.joint_names, prefix, robot.config.base_link)
        self._start = np.asarray(base_xy_yaw, dtype=float)
        if not (self._start.shape == (3,) and np.all(np.isfinite(self._start))):
            raise ValueError(f"base_xy_yaw must be 3 finite numbers (x [m], y [m], yaw [rad]), got {base_xy_yaw}")
        self._floor = self.world.floor
        # A foot is every body welded to the link that carries the sole frame.
        sole_bodies = []
        self._foot_bodies = {}
        robot_bodies = np.flatnonzero(
            np.array([self.m.body(i).name.startswith(prefix) for i in range(self.m.nbody)]))
        self._robot_bodies = set(robot_bodies.tolist())
        foot_weld = {}
        for side, frame in robot.config.feet.items():
            body = self.m.body(prefix + frame).id
            sole_bodies.append(body)
            foot_weld[side] = self.m.body_weldid[body]
            self._foot_bodies[side] = robot_bodies[self.m.body_weldid[robot_bodies] == foot_weld[side]]
        # Per foot, a row that sums its bodies' contact wrenches, and its sole body.
        self._foot_sum = np.zeros((len(self._foot_bodies), self.m.nbody))
        for row, bodies in zip(self._foot_sum, self._foot_bodies.values()):
            row[bodies] = 1.0
        self._sole_bodies = np.array(sole_bodies)
        self._root = int(self.m.body_rootid[self.map.base_body])
        self._base_xyzw = self.map.base_qpos + np.array([4, 5, 6, 3])  # MuJoCo stores w first
        weld = self.m.body_weldid[self.m.geom_bodyid]
        self._geom_side = [next((side for side, foot in foot_weld.items() if w == foot), None) for w in weld]
        # Geoms of this robot outside its feet: their floor contacts are reported (falls).
        self._non_foot_geom = np.array([side is None and b in self._robot_bodies
                                    for side, b in zip(self._geom_side, self.m.geom_bodyid)])
        self._act = self.map.actuator
        if not np.array_equal(self._act, np.arange(self._act[0], self._act[0] + self.nj)):
            raise ValueError("the robot's actuators must be contiguous and in joint order in the MuJoCo model")
        self._acts = slice(int(self._act[0]), int(self._act[0]) + self.nj)  # views, not copies
        self._servo = None  # (kp, kd, kp q_des + kd dq_des + tau_ff) of the last command
        # Columns of the servos' joint position and velocity in the world's physics states; a
        # joint servo's length and velocity are gear × the joint's.
        joints = self.m.actuator_trnid[self._acts, 0]
        if not (np.all(self.m.actuator_trntype[self._acts] == mujoco.mjtTrn.mjTRN_JOINT)
                and np.all(self.m.jnt_type[joints] == mujoco.mjtJoint.mjJNT_HINGE)):
            raise ValueError("the robot's actuators must drive hinge joints directly")
        qpos_at = mujoco.mj_stateSize(self.m, mujoco.mjtState.mjSTATE_TIME)
        qvel_at = mujoco.mj_stateSize(self.m, mujoco.mjtState.mjSTATE_TIME | mujoco.mjtState.mjSTATE_QPOS)
        self._servo_qpos_col = qpos_at + self.m.jnt_qposadr[joints]
        self._servo_qvel_col = qvel_at + self.m.jnt_dofadr[joints]
        self._gyro_col = qvel_at + self.map.base_dof + np.arange(3, 6)
        self._gear = self.m.actuator_gear[self._acts, 0].copy()
        self._joint_order = np.arange(self.nj)
        self.prop = None if prop is None else prop.in_world(self.m, robot, prefix, self._start)
        self._disturb(disturbances)

    def _disturb(self, dist: Disturbances) -> None:
        """Model mismatch (mass), pushes, latency and sensor noise of ``dist`` on this robot."""
        self.disturbances = dist
        if dist.mass_scale != 1.0:
            bodies = np.array(sorted(self._robot_bodies))
            self.m.body_mass[bodies] *= dist.mass_scale
            self.m.body_inertia[bodies] *= dist.mass_scale
            mujoco.mj_setConst(self.m, self.d)
        mass = float(self.m.body_subtreemass[self._root])
        for push in dist.pushes:
            direction = self._start[2] + push.angle
            force = push.impulse * mass / push.duration * np.array([np.cos(direction), np.sin(direction), 0.0])
            self.world.add_push(int(self.map.base_body), push.time, push.duration, force)
        self._delay = deque(maxlen=dist.latency_ticks(self.control_dt) + 1)
        self._ahead = None  # the state after a period run ahead of its write (run_ahead)
        self._handed = None  # that state once its write came: what the next read returns
        self._noise = np.random.default_rng(dist.seed) if dist.sensor_noise else None

    # Lifecycle hooks --------------------------------------------------------------------------
    def _on_configure(self) -> None:
        if self._owns_world:
            mujoco.mj_resetData(self.m, self.d)
        x, y, yaw = self._start
        q = self.robot.q_half_sitting.copy()
        q[:2] = x, y
        q[3:7] = [0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)]
        pin_to_mujoco_qpos(q, self.robot.q_index, self.map, self.d.qpos)
        mujoco.mj_kinematics(self.m, self.d)
        self.d.qpos[self.map.base_qpos + 2] -= self._lowest_foot_point()
        if self.prop is not None:
            self.prop.place(self.d, float(self.d.qpos[self.map.base_qpos + 2]))
        # The servos hold the start posture before the first read's forces are computed: with their
        # targets still zero, the first contact wrenches would carry their pull toward the zero pose.
        self._apply_gains(self.robot.kp, self.robot.kd, np.zeros(self.nj), np.zeros(self.nj))
        self.d.ctrl[self._act] = self.d.qpos[self.map.qpos]
        mujoco.mj_forward(self.m, self.d)
        mujoco.mj_rnePostConstraint(self.m, self.d)  # contact wrenches for the first read

    def _on_activate(self) -> None:
        self._ahead = None  # a period run ahead before a stop has happened; the next write starts a new one
        if self._owns_world:
            self.world.open_viewer()

    def _on_estop(self) -> None:
        # Damping mode: no stiffness, no feedforward, joint damping kept.
        self._apply_gains(np.zeros(self.nj), self.robot.kd, np.zeros(self.nj), np.zeros(self.nj))
        self._servo = None

    def _on_close(self) -> None:
        if self._owns_world:
            self.world.close()

    # Read / write -----------------------------------------------------------------------------
    def _apply_gains(self, kp, kd, dq, tau_ff) -> None:
        a = self._acts
        self.m.actuator_gainprm[a, 0] = kp
        self.m.actuator_biasprm[a, 1] = -kp
        self.m.actuator_biasprm[a, 2] = -kd
        self.m.actuator_biasprm[a, 0] = kd * dq + tau_ff

    def _write(self, cmd: JointCommand) -> None:
        if self._delay.maxlen > 1:  # kept for later periods: the caller may reuse its arrays meanwhile
            cmd = JointCommand(*(np.array(a, dtype=float) for a in (cmd.q, cmd.dq, cmd.kp, cmd.kd, cmd.tau_ff)))
        self._delay.append(cmd)
        if self._ahead is not None:  # this command's period has run already
            self._handed, self._ahead = self._ahead, None
            return
        if len(self._delay) == self._delay.maxlen:  # the command written latency ago reaches the servos
            self._apply(self._delay[0])
        self._period()

    def _run_ahead(self) -> bool:
        """With a latency of L ≥ 1 periods, the next period applies the command written L − 1 writes
        before the last one: that period runs now, and its state is read as its write would read it."""
        latency = self._delay.maxlen - 1
        if not (self._owns_world and latency and self._ahead is None):
            return False
        if len(self._delay) >= latency:
            self._apply(self._delay[len(self._delay) - latency])
        self._period()
        self._ahead = self._measure()
        return True

    def _period(self) -> None:
        """One control period of the world, under the servo command applied last."""
        if self.prop is not None:
            self.prop.before_period(self.d)
        self.world.submit()

    def _apply(self, cmd: JointCommand) -> None:
        self._apply_gains(cmd.kp, cmd.kd, cmd.dq, cmd.tau_ff)
        self.d.ctrl[self._acts] = cmd.q
        # In the servos' own length and velocity (gear × the joint's): the demand record's gains.
        self._servo = (cmd.kp * self._gear, cmd.kd * self._gear, cmd.kp * cmd.q + self.m.actuator_biasprm[self._acts, 0])

    def _peak_demand(self) -> np.ndarray | None:
        """Per joint, the unsaturated servo torque of largest magnitude over the physics steps of
        the last control period: kp q_des + (kd dq_des + tau_ff) − kp q − kd dq, with the q and dq
        MuJoCo computed the servo force from at each step (the state at the step's start)."""
        if self._servo is None:
            return None
        kp, kd, constant = self._servo
        states = self.world.step_states
        demand = constant - kp * states[:, self._servo_qpos_col] - kd * states[:, self._servo_qvel_col]
        return demand[np.abs(demand).argmax(axis=0), self._joint_order]

    def _gyro(self) -> np.ndarray:
        """The base's angular velocity in its own frame (MuJoCo's free joint keeps it body-frame),
        averaged over the physics steps of the last control period as an IMU that integrates its
        gyro at the physics rate reports it (a delta angle over the period, / dt): the velocities
        after each step, those MuJoCo integrated the orientation with. Before any period, the
        present one."""
        d, v = self.d, self.map.base_dof
        now = d.qvel[v + 3: v + 6]
        states = self.world.step_states
        n = len(states)
        if abs(states[0, 0] + n * self.m.opt.timestep - d.time) > 0.5 * self.m.opt.timestep:
            return now.copy()
        return (states[1:, self._gyro_col].sum(axis=0) + now) / n

    def _read(self) -> JointState:
        if self._handed is not None:
            state, self._handed = self._handed, None
            return state
        return self._measure()

    def _measure(self) -> JointState:
        """The state at the present time, as the sensors report it."""
        m, d, mp = self.m, self.d, self.map
        b, v = mp.base_qpos, mp.base_dof
        rot = d.xmat[mp.base_body].reshape(3, 3)
        q, dq = d.qpos[mp.qpos], d.qvel[mp.dof]  # index arrays: copies, not views of the simulation
        state = JointState(
            t=float(d.time),
            q=q,
            dq=dq,
            tau=d.actuator_force[self._acts].copy(),
            base_pos=d.qpos[b : b + 3].copy(),
            base_quat_xyzw=d.qpos[self._base_xyzw],
            base_linvel=d.qvel[v : v + 3].copy(),
            base_angvel=self._gyro(),
            base_linacc=rot.T @ (d.qacc[v : v + 3] - m.opt.gravity),
            foot_wrench=self._foot_wrenches(),
            tau_demand=self._peak_demand(),
            floor_contacts=self._floor_contacts(),
            scene=None if self.prop is None else self.prop.reading(self.d),
        )
        return state if self._noise is None else self._noisy(state)

    def _noisy(self, state: JointState) -> JointState:
        """The state as noisy sensors report it (``Disturbances.noise``): encoders, the IMU's
        attitude (a small random rotation), the feet's force/torque sensors."""
        rng, sigma = self._noise, self.disturbances.noise
        x, y, z, w = state.base_quat_xyzw
        rx, ry, rz = rng.normal(0.0, sigma["base_orientation"], 3) / 2  # q ⊗ (δ/2, 1), first order
        quat = np.array([x + w * rx + y * rz - z * ry, y + w * ry + z * rx - x * rz,
                         z + w * rz + x * ry - y * rx, w - x * rx - y * ry - z * rz])
        wrench = {side: f + np.concatenate([rng.normal(0.0, sigma["foot_force"], 3),
                                            rng.normal(0.0, sigma["foot_torque"], 3)])
                  for side, f in state.foot_wrench.items()}
        return state.replaced(q=state.q + rng.normal(0.0, sigma["joint_position"], self.nj),
                              base_quat_xyzw=quat / np.linalg.norm(quat), foot_wrench=wrench)

    # Contacts -----------------------------------------------------------------------------------
    def _foot_wrenches(self) -> dict[str, np.ndarray]:
        """Contact wrench on each foot (from the floor and anything else it touches), in the sole
        frame about the sole origin, as a force/torque sensor at the sole reads it. MuJoCo's
        ``cfrc_ext`` holds each body's contact wrench ``[torque, force]`` in world axes about the
        subtree CoM ``c`` of the robot's root; about the sole origin ``p`` the torque is
        ``τ + (c − p) × f``, and ``Rᵀ`` (R the sole's orientation) turns both into the sole frame.
        Plain floats: numpy's cost on 3-vectors is its calls, not the arithmetic."""
        d = self.d
        cx, cy, cz = d.subtree_com[self._root].tolist()
        out = {}
        for side, (t0, t1, t2, f0, f1, f2), (px, py, pz), R in zip(
                self._foot_bodies, (self._foot_sum @ d.cfrc_ext).tolist(), d.xpos[self._sole_bodies].tolist(),
                d.xmat[self._sole_bodies].tolist()):
            rx, ry, rz = cx - px, cy - py, cz - pz
            t0, t1, t2 = t0 + ry * f2 - rz * f1, t1 + rz * f0 - rx * f2, t2 + rx * f1 - ry * f0
            out[side] = np.array([f0 * R[0] + f1 * R[3] + f2 * R[6], f0 * R[1] + f1 * R[4] + f2 * R[7],
                                  f0 * R[2] + f1 * R[5] + f2 * R[8], t0 * R[0] + t1 * R[3] + t2 * R[6],
                                  t0 * R[1] + t1 * R[4] + t2 * R[7], t0 * R[2] + t1 * R[5] + t2 * R[8]])
        return out

    def _floor_contacts(self) -> tuple[str, ...]:
        geoms = self.d.contact.geom  # (ncon, 2)
        others = self._non_foot_geom[geoms].any(axis=1)
        if not others.any():  # the usual case: only the feet touch anything
            return ()
        touching = geoms[others & (geoms == self._floor).any(axis=1)]
        if not touching.size:
            return ()
        bodies = {int(self.m.geom_bodyid[g]) for g in touching.ravel() if self._non_foot_geom[g]}
        return tuple(sorted(self.m.body(b).name[len(self.map.prefix):] for b in bodies))

    def _lowest_foot_point(self) -> float:
        """Lowest world z of the feet's collision geometry (corners of each geom's bounding box)."""
        lowest = np.inf
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        for g in range(self.m.ngeom):
            if self.m.geom_contype[g] == 0 and self.m.geom_conaffinity[g] == 0:
                continue
            if self._geom_side[g] is None:
                continue
            center, half = self.m.geom_aabb[g, :3], self.m.geom_aabb[g, 3:]
            local = center + corners * half
            world = self.d.geom_xpos[g] + local @ self.d.geom_xmat[g].reshape(3, 3).T
            lowest = min(lowest, world[:, 2].min())
        return float(lowest)
