"""Hardware-adapter lifecycle and the MuJoCo backend (real physics)."""

import mujoco
import numpy as np
import pytest

from robot_ctrl.hw import CommandError, JointCommand, LifecycleError, LifecycleState
from robot_ctrl.sim.mujoco_backend import MujocoBackend


def hold(robot, q):
    z = np.zeros(robot.nj)
    return JointCommand(q=q, dq=z, kp=robot.kp, kd=robot.kd, tau_ff=z)


def test_lifecycle_transitions_and_refusals(talos):
    hw = MujocoBackend(talos)
    assert hw.state is LifecycleState.UNCONFIGURED
    with pytest.raises(LifecycleError, match="read\\(\\) is not allowed in state 'unconfigured'"):
        hw.read()
    hw.configure()
    assert hw.state is LifecycleState.INACTIVE
    q0 = hw.read().q
    with pytest.raises(LifecycleError, match="write\\(\\) is not allowed in state 'inactive'"):
        hw.write(hold(talos, q0))
    hw.activate()
    hw.write(hold(talos, q0))
    hw.deactivate()
    assert hw.state is LifecycleState.INACTIVE
    hw.activate()
    hw.estop()
    hw.estop()  # idempotent
    assert hw.state is LifecycleState.ESTOP
    with pytest.raises(LifecycleError, match="write\\(\\) is not allowed in state 'estop'"):
        hw.write(hold(talos, q0))
    with pytest.raises(LifecycleError, match="activate"):
        hw.activate()  # the e-stop latches
    hw.close()
    with pytest.raises(LifecycleError, match="after close"):
        hw.read()


def test_standing_state_is_consistent(talos):
    hw = MujocoBackend(talos)
    hw.configure()
    hw.activate()
    first = hw.read()
    assert first.q.shape == (talos.nj,) and first.t == 0.0
    np.testing.assert_allclose(first.q, talos.config.half_sitting, atol=1e-12)
    for _ in range(200):  # 1 s
        hw.write(hold(talos, first.q))
    state = hw.read()
    assert state.t == pytest.approx(1.0)
    weight = talos.mass * 9.81
    normal = state.foot_wrench["left"][2] + state.foot_wrench["right"][2]
    assert normal == pytest.approx(weight, rel=0.02)  # the floor carries the robot
    assert state.base_pos[2] > 0.95 * first.base_pos[2]
    assert np.linalg.norm(state.base_linacc - [0, 0, 9.81]) < 0.5  # IMU at rest reads +g
    assert state.floor_contacts == ()
    assert np.all(np.abs(state.tau) <= talos.effort + 1e-9)


def test_bad_command_is_rejected_before_the_actuators(talos):
    hw = MujocoBackend(talos)
    hw.configure()
    hw.activate()
    q = hw.read().q
    ctrl_before = hw.d.ctrl.copy()
    gains_before = hw.m.actuator_gainprm.copy()
    bad_q = q.copy()
    bad_q[3] = np.nan
    with pytest.raises(CommandError, match=r"JointCommand.q is not finite at joint indices \[3\]"):
        hw.write(hold(talos, bad_q))
    with pytest.raises(CommandError, match=r"JointCommand.kp has shape \(3,\), expected \(32,\)"):
        hw.write(JointCommand(q=q, dq=q * 0, kp=np.ones(3), kd=talos.kd, tau_ff=q * 0))
    with pytest.raises(CommandError, match="kd must be >= 0"):
        hw.write(JointCommand(q=q, dq=q * 0, kp=talos.kp, kd=-talos.kd, tau_ff=q * 0))
    np.testing.assert_array_equal(hw.d.ctrl, ctrl_before)  # nothing half-written
    np.testing.assert_array_equal(hw.m.actuator_gainprm, gains_before)
    assert hw.d.time == 0.0
    assert hw.state is LifecycleState.ACTIVE  # a rejected command is not a backend fault


def test_servo_saturation_is_reported_as_demand(talos):
    """A far-off target makes the servo demand more than its effort limit; applied torque is clipped."""
    hw = MujocoBackend(talos)
    hw.configure()
    hw.activate()
    q = hw.read().q.copy()
    q[talos.joint_names.index("arm_right_4_joint")] += 0.5  # kp × 0.5 rad = 15 × effort
    hw.write(hold(talos, q))
    state = hw.read()
    i = talos.joint_names.index("arm_right_4_joint")
    assert abs(state.tau_demand[i]) > 10 * talos.effort[i]
    assert abs(state.tau[i]) <= talos.effort[i] + 1e-9


def test_control_period_is_mj_step_in_a_loop(talos):
    """write() simulates the period in one rollout: the same states, bit for bit, as mj_step called
    in a loop, and the demand record is the servo law at each step's state."""
    hw = MujocoBackend(talos)
    hw.configure()
    hw.activate()
    m, d = hw.m, hw.d
    reference = mujoco.MjData(m)
    mujoco.mj_copyData(reference, m, d)
    q = hw.read().q.copy()
    knee0 = q[(i := talos.joint_names.index("leg_left_4_joint"))]
    assert m.nu == talos.nj  # the robot's servos are the scene's only actuators
    acts = slice(0, talos.nj)
    for _ in range(20):
        q[i] += 0.01  # a knee bending: the state moves every period
        command = hold(talos, q)
        hw.write(command)
        state = hw.read()
        reference.ctrl[:] = d.ctrl  # the same servo command, in the shared model's gains
        demand = []
        for _ in range(hw.world.n_substeps):
            mujoco.mj_step(m, reference)
            demand.append(command.kp * (command.q - reference.actuator_length[acts])
                          - command.kd * reference.actuator_velocity[acts])
        np.testing.assert_array_equal(d.qpos, reference.qpos)
        np.testing.assert_array_equal(d.qvel, reference.qvel)
        np.testing.assert_array_equal(d.qacc_warmstart, reference.qacc_warmstart)
        demand = np.array(demand)
        np.testing.assert_allclose(state.tau_demand, demand[np.abs(demand).argmax(axis=0), np.arange(talos.nj)],
                                   rtol=1e-12, atol=1e-9)
    assert state.q[i] - knee0 > 0.1  # the knee followed the 0.2 rad it was sent


def test_control_period_must_be_a_multiple_of_the_physics_step(talos):
    with pytest.raises(ValueError, match="control_dt = 0.0025 s must be a positive multiple"):
        MujocoBackend(talos, control_dt=0.0025)


def test_the_gyro_reads_the_mean_rate_over_the_period_so_its_turns_compose_to_the_base_rotation(talos):
    """An IMU that integrates its gyro reports a delta angle per period: composing Exp(dt ω̄) over
    a second of the robot swaying on a hip that yaws back and forth gives the base's rotation to
    1e-6 rad (0.17 µrad here); the instantaneous rate at each read, composed by the trapezoid rule,
    is off by 0.5 mrad (the contacts change the rate within a period)."""
    import pinocchio as pin

    hw = MujocoBackend(talos)
    hw.configure()
    hw.activate()
    state = hw.read()
    q = state.q.copy()
    rotation = lambda s: pin.Quaternion(s.base_quat_xyzw[3], *s.base_quat_xyzw[:3]).matrix()  # noqa: E731
    start, dt = rotation(state), 0.005
    mean_turns, trapezoid = np.eye(3), np.eye(3)
    v = hw.map.base_dof
    previous = hw.d.qvel[v + 3: v + 6].copy()
    for k in range(200):
        q[talos.joint_names.index("leg_left_1_joint")] = 0.2 * np.sin(4 * np.pi * k * dt)  # a hip yawing back and forth
        hw.write(hold(talos, q))
        state = hw.read()
        instantaneous = hw.d.qvel[v + 3: v + 6].copy()
        mean_turns = mean_turns @ pin.exp3(dt * state.base_angvel)
        trapezoid = trapezoid @ pin.exp3(0.5 * dt * (previous + instantaneous))
        previous = instantaneous
    turned = start.T @ rotation(state)
    assert np.linalg.norm(pin.log3(turned)) > 0.01  # the base did turn
    assert np.linalg.norm(pin.log3(mean_turns.T @ turned)) < 1e-6
    assert np.linalg.norm(pin.log3(trapezoid.T @ turned)) > 1e-5
