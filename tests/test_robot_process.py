"""RobotProcess: a backend in a child process behaves as the backend called directly."""

import functools
import os
import signal

import numpy as np
import pytest

from robot_ctrl.hw import CommandError, JointCommand, JointState, LifecycleError, LifecycleState
from robot_ctrl.hw.adapter import HardwareAdapter
from robot_ctrl.sim.disturbances import Disturbances
from robot_ctrl.sim.mujoco_backend import MujocoBackend
from robot_ctrl.sim.robot_process import RobotProcess
from robot_ctrl.sim.shared_state import SharedState


def hold(robot, q):
    z = np.zeros(robot.nj)
    return JointCommand(q=q, dq=z, kp=robot.kp, kd=robot.kd, tau_ff=z)


def assert_same_state(a: JointState, b: JointState) -> None:
    for name in JointState.__dataclass_fields__:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, dict):
            assert x.keys() == y.keys(), name
            for side in x:
                np.testing.assert_array_equal(x[side], y[side], err_msg=f"{name}[{side}]")
        elif isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=name)
        else:
            assert x == y, name


def test_a_backend_in_its_process_reads_what_it_reads_in_ours(talos):
    """The same commands give the same states, bit for bit, with the simulation in a child process."""
    direct = MujocoBackend(talos)
    remote = RobotProcess(functools.partial(MujocoBackend, talos), talos.nj)
    try:
        for hw in (direct, remote):
            hw.configure()
            hw.activate()
        assert_same_state(direct.read(), remote.read())
        q = direct.read().q.copy()
        knee = talos.joint_names.index("leg_left_4_joint")
        for tick in range(30):
            q[knee] += 0.01
            for hw in (direct, remote):
                hw.write(hold(talos, q))
            if tick % 3 == 0:  # also a write after a write: the second waits for the first period
                assert_same_state(direct.read(), remote.read())
        final = remote.read()
        assert_same_state(direct.read(), final)
        assert final.t == pytest.approx(30 * direct.control_dt)
        assert final.q[knee] - talos.config.half_sitting[knee] > 0.1  # the robot moved
    finally:
        direct.close()
        remote.close()
    with pytest.raises(LifecycleError, match="after close"):
        remote.read()


def test_with_command_latency_the_robot_runs_the_next_period_while_the_controller_computes(talos):
    """With a period of latency (or two) the child simulates each next period as soon as a write has
    returned; the states read are lock-step's, bit for bit, with noisy sensors drawing in the same
    order. A lifecycle call after the last write finds the robot a period further on."""
    for latency in (0.005, 0.010):
        make = functools.partial(MujocoBackend, talos, disturbances=Disturbances(latency=latency, sensor_noise=True))
        direct, remote = make(), RobotProcess(make, talos.nj)
        try:
            for hw in (direct, remote):
                hw.configure()
                hw.activate()
            assert_same_state(direct.read(), remote.read())  # each draws its sensor noise once per read
            q = direct.read().q.copy()
            remote.read()
            knee = talos.joint_names.index("leg_left_4_joint")
            for tick in range(20):
                q[knee] += 0.01
                for hw in (direct, remote):
                    hw.write(hold(talos, q))
                assert_same_state(direct.read(), remote.read())
            final = direct.read()
            assert final.q[knee] - talos.config.half_sitting[knee] > 0.05  # the delayed commands moved it
            remote.deactivate()
            assert remote.read().t == pytest.approx(final.t + direct.control_dt)
        finally:
            direct.close()
            remote.close()


def test_lifecycle_and_bad_commands_as_for_the_backend_itself(talos):
    with pytest.raises(ValueError, match="control_dt = 0.0025 s must be a positive multiple"):
        RobotProcess(functools.partial(MujocoBackend, talos, control_dt=0.0025), talos.nj)
    hw = RobotProcess(functools.partial(MujocoBackend, talos), talos.nj)
    try:
        hw.configure()
        q = hw.read().q
        with pytest.raises(LifecycleError, match="write\\(\\) is not allowed in state 'inactive'"):
            hw.write(hold(talos, q))
        hw.activate()
        bad = q.copy()
        bad[2] = np.inf
        with pytest.raises(CommandError, match=r"JointCommand.q is not finite at joint indices \[2\]"):
            hw.write(hold(talos, bad))
        assert hw.read().t == 0.0  # the rejected command never reached the robot
        hw.write(hold(talos, q))
        hw.estop()  # waits for the period, then damping mode in the child
        assert hw.state is LifecycleState.ESTOP
        assert hw.read().t == pytest.approx(0.005)
        hw.reset()
        hw.activate()
        hw.write(hold(talos, q))
        assert hw.read().t == pytest.approx(0.010)
    finally:
        hw.close()


class _FailingBackend(HardwareAdapter):
    """A backend whose second write fails, as a bus that drops out."""

    def __init__(self, nj: int):
        super().__init__(nj)
        self.writes = 0

    def _on_configure(self) -> None:
        pass

    def _on_estop(self) -> None:
        pass

    def _write(self, command: JointCommand) -> None:
        self.writes += 1
        if self.writes == 2:
            raise OSError("bus dropped out")

    def _read(self) -> JointState:
        z = np.zeros(self.nj)
        return JointState(t=0.001 * self.writes, q=z, dq=z, tau=z)


class _FailingAheadBackend(_FailingBackend):
    """A backend that runs each next period ahead of its write, and whose second such period fails."""

    def _write(self, command: JointCommand) -> None:
        pass  # the period ran ahead

    def _run_ahead(self) -> bool:
        self.writes += 1
        if self.writes == 2:
            raise OSError("the period run ahead failed")
        return True


@pytest.mark.parametrize("backend, message, times, restarted", [
    (_FailingBackend, "bus dropped out", [0.001], 0.003),
    # The period that follows a write's return belongs to the next write: its failure comes with
    # that write's reply, as it would in lock-step; the failed period counts for nothing.
    (_FailingAheadBackend, "the period run ahead failed", [0.0, 0.001], 0.002)])
def test_a_failure_in_the_child_is_raised_by_the_next_call_and_faults_the_adapter(backend, message, times, restarted):
    hw = RobotProcess(functools.partial(backend, 3), 3)
    try:
        hw.configure()
        hw.activate()
        command = JointCommand(*np.zeros((5, 3)))
        for t in times:
            hw.write(command)
            assert hw.read().t == t
        hw.write(command)  # returns: the failure comes with the reply
        with pytest.raises(OSError, match=message):
            hw.read()
        assert hw.state is LifecycleState.FAULT
        hw.reset()
        hw.activate()
        hw.write(command)
        assert hw.read().t == restarted
    finally:
        hw.close()


def test_a_dead_robot_process_is_reported(talos):
    hw = RobotProcess(functools.partial(_FailingBackend, 3), 3, name="doomed")
    hw.configure()
    os.kill(hw._process.pid, signal.SIGKILL)
    hw._process.join(timeout=5.0)
    with pytest.raises(RuntimeError, match="the robot process 'doomed' stopped \\(exit code -9\\)"):
        hw.read()
    hw.close()


def test_shared_state_round_trip_keeps_missing_fields_missing():
    import multiprocessing as mp

    buffer = SharedState.allocate(2, mp.get_context())
    full = JointState(t=1.5, q=np.array([1.0, 2.0]), dq=np.array([3.0, 4.0]), tau=np.array([5.0, 6.0]),
                      base_pos=np.arange(3.0), base_quat_xyzw=np.array([0.0, 0.0, 0.0, 1.0]),
                      base_linvel=np.ones(3), base_angvel=2 * np.ones(3), base_linacc=3 * np.ones(3),
                      foot_wrench={"left": np.arange(6.0)}, tau_demand=np.array([7.0, 8.0]),
                      temperature=np.array([40.0, 41.0]))
    buffer.put(full)
    assert_same_state(buffer.get(("arm_left_7_link",)), JointState(**{**full.__dict__,
                                                                       "floor_contacts": ("arm_left_7_link",)}))
    sparse = JointState(t=2.0, q=np.zeros(2), dq=np.zeros(2), tau=np.zeros(2))
    buffer.put(sparse)
    assert_same_state(buffer.get(), sparse)
    with pytest.raises(ValueError, match="foot_wrench sides \\['front'\\] must be among"):
        buffer.put(JointState(t=0.0, q=np.zeros(2), dq=np.zeros(2), tau=np.zeros(2),
                              foot_wrench={"front": np.zeros(6)}))
