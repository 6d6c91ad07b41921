"""WalkingController: WPG → stack-of-tasks IK → joint commands, one call per control tick.

Each tick: when the tick reaches the end of the pattern generator's current sample, it solves its
MPC for the next one (samples need not be a whole number of ticks: the gait's time scale can
stretch them) and the dynamic filter corrects the CoM plan for the whole-body dynamics; the plan
is sampled at the tick; the balance stabilizer corrects the CoM reference from the measured state;
the IK (feet, then CoM + waist, then posture) integrates the reference configuration; the command
carries the quasi-static torque feedforward (with the LIP's d'Alembert force) for the planned contact
split. Everything before the stabilizer's correction is :meth:`WalkingController.prepare`, which a
loop can run while the robot executes the previous command.

Simplification: the feedforward is computed in ``prepare``, at the reference configuration
extrapolated over the tick with the last tick's IK velocity, not at the configuration the IK then
integrates, so that its cost leaves the path from the state's measurement to the command. The two
differ by a fraction of a milliradian per joint; ``tests/test_walk.py`` bounds the feedforward's
difference, docs/walking.md gives the measured one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pinocchio as pin

from robot_ctrl.control.controllers.push_recovery import plan_velocity_change
from robot_ctrl.control.controllers.stabilizer import DcmStabilizer, StabilizerGains
from robot_ctrl.control.controllers.static_feedforward import ContactSplit, static_torques, weight_shares
from robot_ctrl.control.estimation.attitude_filter import AttitudeFilter
from robot_ctrl.control.estimation.state_estimator import StateEstimator
from robot_ctrl.dynfilter.dynamic_filter import DynamicFilter
from robot_ctrl.dynfilter.filter_worker import DynamicFilterWorker
from robot_ctrl.geometry import SIDES, PlanarMove, Side, mean_yaw, other, wrap_angle, yaw_of
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.modes import FilterMode
from robot_ctrl.robot.model import RobotModel, configuration
from robot_ctrl.sot.servo_bounds import servo_velocity_bounds
from robot_ctrl.sot.whole_body_ik import WholeBodyIK, upper_body_dofs
from robot_ctrl.wpg.footstep import Footstep
from robot_ctrl.wpg.generator import WalkingPatternGenerator
from robot_ctrl.wpg.params import WalkParams
from robot_ctrl.wpg.plan import Touchdown, WalkReference

MAX_BALANCE_SHIFT = 0.04  # [m] of :meth:`WalkingController.shift_balance`, well inside a sole
MAX_FOOT_FOLLOW = 0.05  # [m] per sample: a larger gap (a push, a slipping foot) is closed over several samples
MAX_YAW_FOLLOW = 0.05  # [rad] per sample, likewise for the stance foot's yaw ...
YAW_DEAD_BAND = 0.02  # [rad] ... beyond this: soles land within tenths of a degree of their plan, slips turn by more
MIN_STANCE_TICKS = 5  # measurements of a stance foot needed to follow it


def sole_footstep(side: Side, pose: pin.SE3) -> Footstep:
    return Footstep(side, float(pose.translation[0]), float(pose.translation[1]), yaw_of(pose.rotation))


@dataclass(frozen=True)
class WalkingOptions:
    """How a :class:`WalkingController` walks (placo's ``HumanoidParameters``, for this pipeline).

    ``params``: pattern-generator settings (step timing, MPC weights; None: the defaults), whose
    robot-dependent fields are derived from the robot's start posture (:meth:`WalkParams.for_robot`);
    ``control_dt`` [s]: the control period; ``stabilize``: DCM/ZMP balance feedback
    (``DcmStabilizer``); ``recover_pushes``: the plan takes up a DCM departure beyond
    ``push_recovery.DEAD_BAND`` at each sample (:mod:`~robot_ctrl.control.controllers.push_recovery`);
    ``dynfilter``: the dynamic filter's :class:`FilterMode`, with ``dynfilter_passes`` per sample, in
    a worker process one WPG sample behind with ``dynfilter_worker`` (``DynamicFilterWorker``);
    ``trunk_weight``, ``balance_with_arms``: how the IK may use the upper body (``WholeBodyIK``)."""

    params: WalkParams | None = None
    control_dt: float = 0.005
    stabilize: bool = True
    recover_pushes: bool = True
    dynfilter: FilterMode = FilterMode.OFF
    dynfilter_passes: int = 2
    dynfilter_worker: bool = False
    trunk_weight: float = 1.0
    balance_with_arms: bool = True

    def walk_params(self, robot: RobotModel) -> WalkParams:
        """``params``, or the robot's own (its config's ``walking:`` over the defaults)."""
        return WalkParams.of_robot(robot.config.walking) if self.params is None else self.params


@dataclass(frozen=True)
class PreparedTick:
    """What :meth:`WalkingController.prepare` leaves for :meth:`~WalkingController.step`: the plan at
    the tick, the CoM target before the stabilizer's correction (world frame) and the torque
    feedforward (the robot's joint order, within the efforts)."""

    reference: WalkReference
    com: np.ndarray  # (2,) [m]
    com_velocity: np.ndarray  # (2,) [m/s]
    tau_ff: np.ndarray  # (nj,) [N·m]


@dataclass
class _StanceSoles:
    """The measured sole of the plan's single stance foot, summed over the ticks it alone touched
    (yaw as unit phasors, so that the mean does not wrap)."""

    side: Side
    xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    heading: complex = 0j
    ticks: int = 0

    def add(self, sole: pin.SE3) -> None:
        self.xy = self.xy + sole.translation[:2]
        self.heading += np.exp(1j * yaw_of(sole.rotation))
        self.ticks += 1


@dataclass(frozen=True)
class PlanSample:
    """What a commander sees at the controller's sample hook: the plan at the start of the sample
    about to be solved (world frame)."""

    t: float  # [s] time of the tick that starts the sample
    com_xy: np.ndarray  # (2,) planned CoM [m]
    heading: float  # [rad] heading of the plan
    gait_phase: float | None  # [rad] π per step since the first single support; None before it
    standing: bool  # the plan stands (no step under way or planned)


class WalkingController:
    """The walking pipeline for one robot. Commands: :meth:`set_velocity`, :meth:`stop_at`,
    :meth:`set_time_scale`, from a hook registered with :meth:`on_sample`, which runs at the start of
    every pattern-generator sample, just before the MPC solves it."""

    def __init__(self, robot: RobotModel, state: JointState, options: WalkingOptions = WalkingOptions(), *,
                 upper_body: Callable[[float], np.ndarray] | None = None):
        """Start standing where ``state`` (the first measured state) says the robot is, walking as
        ``options`` say. ``upper_body(t)``: posture-task target (joint order, rad) at time t, default
        the start posture (:meth:`set_upper_body` changes it). Call :meth:`close` when done (it ends
        the dynamic filter's worker)."""
        dynfilter = FilterMode.parse(options.dynfilter)
        control_dt = options.control_dt
        self.options = options
        self.robot = robot
        self.dt = control_dt
        q0 = configuration(robot, state.base_pos, state.base_quat_xyzw, state.q)
        self.ik = WholeBodyIK(robot, q0, trunk_weight=options.trunk_weight,
                              balance_with_arms=options.balance_with_arms)
        # The upper body's commands stay within their servos' effort by the IK's bounds
        # (servo_velocity_bounds); the legs keep none: the feet must hold exactly.
        share = robot.config.servo_torque_fraction
        self._servo_budget = None if share is None else np.where(
            np.isin(robot.v_index, upper_body_dofs(robot)), share * robot.effort, np.inf)
        feet = {s: self.ik.pose(f"{s}_foot") for s in SIDES}
        self.sole_height = float(np.mean([feet[s].translation[2] for s in SIDES]))
        com = self.ik.com_position()
        self.com_z = float(com[2])
        self.params = options.walk_params(robot).for_robot(
            com_height=self.com_z - self.sole_height, foot_length=robot.config.foot.length,
            foot_width=robot.config.foot.width,
            step_width=float(np.linalg.norm(feet["left"].translation[:2] - feet["right"].translation[:2])))
        self.wpg = WalkingPatternGenerator(self.params, sole_footstep("left", feet["left"]),
                                           sole_footstep("right", feet["right"]), com[:2])
        if control_dt > self.params.sample_time:
            raise ValueError(f"control_dt = {control_dt} s must not exceed WalkParams.sample_time = "
                             f"{self.params.sample_time} s")
        self.stabilizer = DcmStabilizer(self.params.com_height, StabilizerGains.of_robot(robot.config.stabilizer))
        self.stabilizer.enabled = options.stabilize
        self.start_posture = self.ik.posture.target.copy()
        self.upper_body = upper_body if upper_body is not None else (lambda t: self.start_posture)
        worker = options.dynfilter_worker and dynfilter is not FilterMode.OFF
        self.dynfilter = (DynamicFilterWorker if worker else DynamicFilter)(
            robot, self.params.horizon, self.params.com_height, dynfilter, options.dynfilter_passes)
        self.estimator = StateEstimator(robot)
        self.attitude_filter = AttitudeFilter()
        self.attitude_filter.update(state)
        self.estimate = None
        self._statics = robot.pin.createData()
        self.k = 0
        self.reference: WalkReference | None = None
        self._prepared: PreparedTick | None = None
        self._v = np.zeros(robot.pin.nv)  # the IK's velocity at the last tick
        self._sample_hooks: list[Callable[[PlanSample], None]] = []
        self._hands: dict[str, tuple[np.ndarray, np.ndarray] | None] = {s: None for s in SIDES}
        self._hand_rotations: dict[str, np.ndarray | None] = {s: None for s in SIDES}
        self._balance_shift = np.zeros(2)
        self._stance: _StanceSoles | None = None
        self._stance_unmeasured = False  # the last step's estimate is still to be added to _stance
        self.recover_pushes = options.recover_pushes
        self.push_recoveries = 0  # samples at which the plan took up a DCM departure

    # Commands ---------------------------------------------------------------------------------
    def on_sample(self, hook: Callable[[PlanSample], None]) -> None:
        """Call ``hook`` at the start of every pattern-generator sample, before it is solved: the
        commands it gives apply to that sample."""
        self._sample_hooks.append(hook)

    def set_velocity(self, vx: float, vy: float, wz: float) -> None:
        """Reference velocity in the heading frame: vx, vy [m/s], ωz [rad/s]; all zero stops."""
        self.wpg.set_velocity(vx, vy, wz)

    def stop_at(self, left: Footstep, right: Footstep) -> None:
        """Stop with the soles at these footsteps (world frame), as close as the reach allows."""
        self.wpg.stop_at(left, right)

    def set_upper_body(self, posture: Callable[[float], np.ndarray]) -> None:
        """Posture-task target (joint order, rad) as a function of time [s], for now and for the
        dynamic filter's preview over the horizon."""
        self.upper_body = posture

    def set_hand_target(self, side: Side, position: np.ndarray | None, velocity: np.ndarray | None = None,
                        rotation: np.ndarray | None = None) -> None:
        """Hand frame position [m] and velocity [m/s] (world frame) for the IK's hand task of ``side``
        (upper-body level, above the posture); None frees the hand (posture only). ``rotation``: the
        hand frame's orientation to hold (3 × 3, world frame), or None to leave it to the posture."""
        self._hands[side] = None if position is None else (np.asarray(position, float),
                                                           np.zeros(3) if velocity is None else np.asarray(velocity, float))
        self._hand_rotations[side] = None if position is None or rotation is None else np.asarray(rotation, float)

    def shift_balance(self, offset_xy: np.ndarray) -> None:
        """Shift the CoM and ZMP references by ``offset_xy`` [m] (world frame), at most
        ``MAX_BALANCE_SHIFT`` each way: a static lean for a task that moves the CoM against the pelvis
        (arms reaching forward), so that the pelvis, not the CoM, stays where the plan put it."""
        self._balance_shift = np.clip(np.asarray(offset_xy, float), -MAX_BALANCE_SHIFT, MAX_BALANCE_SHIFT)

    def set_time_scale(self, scale: float) -> None:
        """Physical / nominal duration of the gait from the next sample on (step period × scale)."""
        self.wpg.set_time_scale(scale)

    # What the sensors say ---------------------------------------------------------------------
    @property
    def start_pose(self) -> np.ndarray:
        """World (x, y, yaw) of the base at the first measured state, as every reading since tells it
        (:class:`~robot_ctrl.control.estimation.attitude_filter.AttitudeFilter`): the frame a task is stated in."""
        return self.attitude_filter.start_pose

    # What the plan says -----------------------------------------------------------------------
    @property
    def standing(self) -> bool:
        return self.wpg.standing

    @property
    def heading(self) -> float:
        return self.wpg.heading

    @property
    def touchdowns(self) -> list[Touchdown]:
        """Every planned touch-down so far, in order."""
        return self.wpg.touchdowns

    @property
    def filter_fallbacks(self) -> int:
        """Dynamic-filter updates its guard refused (the unfiltered plan used instead)."""
        return self.dynfilter.fallbacks

    @property
    def solve_times(self) -> list[float]:
        """Wall-clock time of each MPC solve [s]."""
        return self.wpg.solve_times

    def reference_configuration(self) -> np.ndarray:
        """The IK's integrated reference configuration, a copy (Pinocchio order: base position,
        quaternion x y z w, joints; world frame)."""
        return self.ik.q.copy()

    def reference_com(self) -> np.ndarray:
        """CoM (3,) [m] of the reference configuration (world frame)."""
        return self.ik.com_position()

    def reference_hand(self, side: Side) -> np.ndarray:
        """Hand frame position (3,) [m] of ``side`` in the reference configuration (world frame)."""
        return self.ik.pose(f"{side}_hand").translation.copy()

    def reference_hand_rotation(self, side: Side) -> np.ndarray:
        """Hand frame orientation (3 × 3) of ``side`` in the reference configuration (world frame)."""
        return self.ik.pose(f"{side}_hand").rotation.copy()

    def footsteps(self) -> dict[Side, Footstep]:
        """The feet's current planned footsteps (world frame)."""
        return dict(self.wpg.feet)

    def plan_sample(self) -> PlanSample:
        wpg = self.wpg
        return PlanSample(self.k * self.dt, np.array([wpg.com_x[0], wpg.com_y[0]]), wpg.heading, self.gait_phase(),
                          wpg.standing)

    def gait_phase(self, t: float | None = None) -> float | None:
        """Gait phase of the plan [rad] at time ``t`` within the current sample (default: the next
        tick); None before the first step."""
        return self.wpg.gait_phase((self.k * self.dt if t is None else t) - self.wpg.sample_start)

    @property
    def sample_due(self) -> bool:
        """The next tick starts a new pattern-generator sample."""
        return self.k * self.dt >= self.wpg.t - 1e-9

    def prepare(self) -> None:
        """The part of the next :meth:`step` that the measured state does not enter: the pattern
        generator's sample (MPC and dynamic filter) when one is due, the plan at the tick, every IK
        target but the CoM's correction, the IK's kinematics and factorization, and the torque
        feedforward. A loop may call it while the robot moves (between ``write`` and ``read``);
        :meth:`step` calls it when the loop did not. It first adds the last step's measured stance
        sole (:meth:`_measure_stance`, for the next sample's plan), which the command does not need."""
        if self._stance_unmeasured:
            self._stance_unmeasured = False
            self._measure_stance(self.reference)
        t = self.k * self.dt
        if self.sample_due:
            self._plan_sample()
        tau = t - self.wpg.sample_start
        ref = self.wpg.sample(tau)
        com, com_velocity = self._set_ik_targets(ref, t, tau)
        self.ik.prepare(self.dt, retargetable=(self.ik.com,))  # the stabilizer moves the CoM target in step
        self._prepared = PreparedTick(ref, com, com_velocity, self._feedforward(ref))

    def _plan_sample(self) -> None:
        """The next pattern-generator sample: the plan moved to the measured feet and DCM, the
        commanders' hooks, the MPC, the dynamic filter on the solved plan."""
        self._follow_the_feet()
        self._take_up_a_push()
        if self._sample_hooks:
            sample = self.plan_sample()
            for hook in self._sample_hooks:
                hook(sample)
        self.wpg.update()
        self.dynfilter.update(self.wpg.preview(), self.ik.q, self.com_z, self.sole_height, self.upper_body)

    def _set_ik_targets(self, ref: WalkReference, t: float, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """The plan at time ``t`` (``tau`` into its sample) → the IK's targets (placo's
        ``update_tasks``): soles, CoM (with the filter's offset and the balance shift), posture,
        hands and waist. Returns the CoM target and its velocity (2,) before the stabilizer's
        correction (world frame)."""
        ik = self.ik
        for side in SIDES:
            sole = ref.feet[side]
            ik.feet[side].set_target(pin.SE3(pin.utils.rpyToMatrix(0.0, 0.0, sole.yaw),
                                             sole.position + [0.0, 0.0, self.sole_height]),
                                     np.concatenate([sole.velocity, [0.0, 0.0, sole.yaw_rate]]))
        offset = self.dynfilter.offset(tau)
        com, com_velocity = ref.com + offset.position + self._balance_shift, ref.com_velocity + offset.velocity
        ik.com.set_target(np.array([*com, self.com_z]), np.array([*com_velocity, 0.0]))
        ik.posture.set_target(self.upper_body(t))
        for side, hand in self._hands.items():
            ik.hands[side].active = hand is not None
            if hand is not None:
                ik.hands[side].set_target(pin.SE3(np.eye(3), hand[0]), np.concatenate([hand[1], np.zeros(3)]))
            rotation = self._hand_rotations[side]
            ik.hand_orientations[side].active = rotation is not None
            if rotation is not None:
                ik.hand_orientations[side].set_target(pin.SE3(rotation, np.zeros(3)))
        waist_yaw = mean_yaw([ref.feet[s].yaw for s in SIDES])
        ik.waist.set_target(pin.SE3(pin.utils.rpyToMatrix(0.0, 0.0, waist_yaw), np.zeros(3)))
        return com, com_velocity

    def _feedforward(self, ref: WalkReference) -> np.ndarray:
        """Quasi-static joint torques (nj, the robot's joint order) for the planned contact split, at
        the reference configuration extrapolated over the tick (module docstring). A servo delivers
        no more than its effort: a feedforward beyond it (a stance ankle holding the ZMP at the toe
        of a small robot's sole) is sent as much as it can give."""
        r = self.robot
        frames, shares = self.contact_split(ref)
        q_ahead = pin.integrate(r.pin, self.ik.q, self._v * self.dt)
        tau_ff, _ = static_torques(r.pin, self._statics, q_ahead, frames, shares,
                                   np.array([*ref.com_acceleration, 0.0]))
        return np.clip(tau_ff[r.v_index], -r.effort, r.effort)

    def _follow_the_feet(self) -> None:
        """Move the plan (and the IK's reference configuration with it) to where the stance foot
        really is, measured over the last sample while it alone carried the robot: without it the
        small error of every landing adds up over a long walk, the measured CoM runs ahead of a plan
        whose feet are elsewhere and the stabilizer's bounded correction ends by not being enough (a
        10 m walk fell). The mean over the sample keeps attitude noise (a leg's 1 m lever) out of the
        plan. The joints' references do not change; the plan's future steps start from the real feet.
        The plan turns about the planned stance foot by the sole's yaw error beyond ``YAW_DEAD_BAND``,
        then moves by its position error, at most ``MAX_YAW_FOLLOW`` and ``MAX_FOOT_FOLLOW`` per
        sample: one jump could come from a foot still settling, and a push or a slip that turned or
        moved the robot by decimetres must not leave the plan (and the path follower, which steers
        the plan) walking elsewhere."""
        stance, self._stance = self._stance, None
        if stance is None or stance.ticks < MIN_STANCE_TICKS:
            return
        planned = self.wpg.feet[stance.side]
        yaw_gap = wrap_angle(np.angle(stance.heading) - planned.yaw)
        turn = float(np.sign(yaw_gap) * min(max(abs(yaw_gap) - YAW_DEAD_BAND, 0.0), MAX_YAW_FOLLOW))
        delta = stance.xy / stance.ticks - planned.xy
        gap = float(np.linalg.norm(delta))
        if gap > MAX_FOOT_FOLLOW:
            delta *= MAX_FOOT_FOLLOW / gap
        move = PlanarMove(delta, turn, planned.xy)
        self.wpg.shift(move)
        q = self.ik.q.copy()
        q[:2] = move.point(q[:2])
        base = pin.Quaternion(pin.utils.rpyToMatrix(0.0, 0.0, turn) @ pin.Quaternion(q[6], *q[3:6]).matrix())
        q[3:7] = base.coeffs()  # x, y, z, w
        self.ik.set_configuration(q)

    def _take_up_a_push(self) -> None:
        """The plan's DCM moves to within the dead band of the measured one (``push_recovery``), so
        that this sample's MPC places the footsteps from where the robot is going."""
        if not self.recover_pushes or self.estimate is None or self.wpg.standing:
            return
        omega = self.stabilizer.omega
        change = plan_velocity_change(self.estimate.dcm(omega), self.wpg.dcm(), omega)
        if change is not None:
            self.wpg.add_com_velocity(change)
            self.push_recoveries += 1

    def _measure_stance(self, ref: WalkReference) -> None:
        """Add this tick's measured sole of the plan's single stance foot, if it alone touches
        (position, and yaw as a unit phasor so that its mean does not wrap)."""
        est = self.estimate
        down = [s for s in SIDES if ref.in_contact[s]]
        if len(down) != 1 or not est.in_contact[down[0]] or est.in_contact[other(down[0])]:
            return
        side = down[0]
        if self._stance is None or self._stance.side != side:
            self._stance = _StanceSoles(side)
        self._stance.add(est.soles[side])

    def step(self, state: JointState) -> JointCommand:
        """The joint command for the tick from the measured ``state``: the balance stabilizer's
        CoM correction completes the prepared IK solve."""
        if self._prepared is None:
            self.prepare()
        prepared, self._prepared = self._prepared, None
        ref = prepared.reference
        self.k += 1
        self.reference = ref
        self.estimate = self.estimator.estimate(self.attitude_filter.update(state))
        self._stance_unmeasured = True
        correction = self.stabilizer.correction(self.estimate, prepared.com, prepared.com_velocity,
                                                ref.zmp + self._balance_shift, self.dt, self.wpg.heading)
        ik = self.ik
        ik.com.set_target(np.array([*(prepared.com + correction), self.com_z]), ik.com.target_velocity)
        r, tau_ff = self.robot, prepared.tau_ff
        within = None
        if self._servo_budget is not None:
            within = servo_velocity_bounds(r.joints_from_q(ik.q), state.q, state.dq, tau_ff, r.kp, r.kd,
                                           self._servo_budget, self.dt)
        v = self._v = ik.finish(retargeted=(ik.com,), tighter=within)
        return JointCommand(q=r.joints_from_q(ik.q), dq=v[r.v_index], kp=r.kp, kd=r.kd, tau_ff=tau_ff)

    def close(self) -> None:
        """Release what the controller holds outside this process (the filter worker)."""
        self.dynfilter.close()

    def contact_split(self, ref: WalkReference) -> ContactSplit:
        """Sole frames in contact and their weight shares, from where the planned ZMP lies between them."""
        ids = self.robot.frame_ids
        down = [s for s in SIDES if ref.in_contact[s]]
        if len(down) == 1:
            return ContactSplit([ids[f"{down[0]}_foot"]], [1.0])
        shares = weight_shares(ref.zmp, ref.feet["left"].position[:2], ref.feet["right"].position[:2])
        return ContactSplit([ids["left_foot"], ids["right_foot"]], list(shares))
