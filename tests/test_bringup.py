"""Bring-up of servos (``robot-ctrl hw``): the start sequence's checks, its move and its tracking
fault, the pacer's deadlines, and the commands against the emulated MIT-CAN bus."""

import re
import time

import numpy as np
import pytest

from robot_ctrl.buses.bus_config import load_bus_config
from robot_ctrl.cli import main
from robot_ctrl.control.loop.pacer import Pacer
from robot_ctrl.control.loop.start_sequence import StartParams, StartRefused, StartSequence
from robot_ctrl.hw.adapter import HardwareAdapter, HardwareFault
from robot_ctrl.hw.safety import SafetyLayer, SafetyLimits
from robot_ctrl.hw.types import JointCommand, JointState
from robot_ctrl.robot.model import load_robot
from robot_ctrl.scenarios import bringup


class KinematicServos(HardwareAdapter):
    """Servos that reach each commanded angle within the tick, except ``stuck`` joints (a blocked
    joint, or one whose direction sign is wrong); counts e-stops."""

    def __init__(self, q: np.ndarray, stuck: tuple[int, ...] = ()):
        super().__init__(len(q))
        self.q, self.t, self.stuck, self.estops = q.copy(), 0.0, list(stuck), 0

    def _on_configure(self) -> None:
        pass

    def _on_estop(self) -> None:
        self.estops += 1

    def _read(self) -> JointState:
        return JointState(t=self.t, q=self.q.copy(), dq=np.zeros(self.nj), tau=np.zeros(self.nj))

    def _write(self, command: JointCommand) -> None:
        moved = command.q.copy()
        moved[self.stuck] = self.q[self.stuck]
        self.q, self.t = moved, self.t + 0.005


def layer(talos, q, stuck=()):
    return SafetyLayer(KinematicServos(q, stuck), SafetyLimits.from_robot(talos, soft_start=0.0), clock=None)


def test_the_start_sequence_refuses_a_posture_outside_the_limits_or_far_from_the_start(talos):
    q = np.array(talos.config.half_sitting)
    state = lambda q: JointState(t=0.0, q=q, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj))  # noqa: E731
    knee = talos.joint_names.index("leg_left_4_joint")
    bent = q.copy()
    bent[knee] = talos.upper[knee] + 0.1
    with pytest.raises(StartRefused, match="leg_left_4_joint outside the position limits"):
        StartSequence(talos, state(bent))
    elbow = talos.joint_names.index("arm_right_4_joint")
    far = q.copy()
    far[elbow] = q[elbow] - 1.5
    with pytest.raises(StartRefused, match="arm_right_4_joint more than 1.0 rad from the start posture"):
        StartSequence(talos, state(far))


def test_the_move_follows_a_minimum_jerk_profile_at_reduced_gains(talos):
    start = np.array(talos.config.half_sitting)
    elbow = talos.joint_names.index("arm_left_4_joint")
    start[elbow] -= 0.6
    hw = layer(talos, start)
    report = bringup.move(talos, hw, params=StartParams(duration=1.0, gain_scale=0.25))
    assert report["reached"] and report["final_error_rad"] < 1e-9 and report["largest_tracking_error_rad"] < 0.02
    sent = hw.backend.q
    np.testing.assert_allclose(sent, np.clip(talos.config.half_sitting, talos.lower, talos.upper), atol=1e-9)
    sequence = StartSequence(talos, JointState(t=0.0, q=start, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj)),
                             params=StartParams(duration=1.0, gain_scale=0.25), feedforward=np.ones(talos.nj))
    commands = [sequence.step(JointState(t=0.0, q=start, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj)))]
    np.testing.assert_allclose(commands[0].kp, 0.25 * talos.kp)
    np.testing.assert_allclose(commands[0].kd, 0.5 * talos.kd)  # √0.25: the full gains' damping ratio
    assert commands[0].tau_ff.max() == 0.0 and commands[0].dq[elbow] == 0.0  # both ramp in from zero


def test_a_stuck_joint_faults_into_damping(talos):
    start = np.array(talos.config.half_sitting)
    elbow = talos.joint_names.index("arm_left_4_joint")
    start[elbow] -= 0.6
    hw = layer(talos, start, stuck=(elbow,))
    with pytest.raises(HardwareFault, match="TrackingFault: arm_left_4_joint 0.15.* rad from the reference"):
        bringup.move(talos, hw, params=StartParams(duration=1.0))
    assert hw.backend.estops == 1 and hw.state.value == "estop"


def test_the_pacer_keeps_absolute_deadlines_and_counts_overruns():
    clock = {"t": 10.0}
    pacer = Pacer(0.005, clock=lambda: clock["t"], sleep=lambda s: clock.update(t=clock["t"] + s))
    work = [0.001, 0.002, 0.004, 0.009, 0.001, 0.001]  # the fourth tick's work overruns its period
    wakes = []
    for w in work:
        pacer.wait()
        wakes.append(clock["t"])
        clock["t"] += w
    np.testing.assert_allclose(np.diff(wakes[:4]), 0.005)  # on the deadlines, whatever the work took
    assert pacer.overruns == 1 and wakes[4] == pytest.approx(wakes[3] + 0.009)  # late, and starting again from there
    assert wakes[5] == pytest.approx(wakes[4] + 0.005)
    assert pacer.report()["overruns"] == 1 and pacer.report()["ticks"] == 6


@pytest.mark.realtime  # wall-clock and CPU time: run apart from the parallel tests
def test_the_pacer_tells_overruns_off_the_cpu_from_work_that_took_too_long():
    pacer = Pacer(0.005)
    pacer.wait()
    end = time.thread_time() + 0.012
    while time.thread_time() < end:  # computing past the deadline
        pass
    pacer.wait()
    time.sleep(0.012)  # held off the CPU past the deadline (a host stall, a blocking call)
    pacer.wait()
    report = pacer.report()
    assert report["overruns"] == 2 and report["overruns_off_cpu"] == 1, report


@pytest.mark.realtime  # emulated buses answer on wall-clock timeouts: a Dynamixel reply came late under -n 2
def test_bring_up_commands_on_the_emulated_bus(capsys, tmp_path):
    assert main(["hw", "read"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("joint ")]
    assert len(rows) == 32 and all(line.endswith("status ok") for line in rows)
    assert main(["hw", "jog", "arm_left_4_joint", "-0.3", "--duration", "1"]) == 0
    out = capsys.readouterr().out
    assert "reached: True" in out and float(re.search(r"final_error_rad: (\S+)", out)[1]) < 0.05
    assert main(["hw", "jog", "arm_left_4_joint", "1.0"]) == 3  # beyond the elbow's upper limit
    assert "arm_left_4_joint would go to" in capsys.readouterr().err
    assert main(["hw", "scan"]) == 0  # the emulated bus's mini-cheetah drives have no CAN timeout
    out = capsys.readouterr().out
    assert "answering: 32" in out and "stop_without_host: 0 of 32 joints" in out and "'head_2_joint']" in out
    assert "enabled_because: emulated bus in a simulation" in out  # the bus config's acknowledgement
    assert main(["hw", "scan", "--hw", "dynamixel-emulated"]) == 0  # every servo's bus watchdog is armed
    out = capsys.readouterr().out
    assert "stop_without_host: 32 of 32 joints" in out and "hold_last_command_without_host: []" in out
    assert main(["hw", "scan", "--hw", "mit-can"]) == 2
    assert "--hw mit-can needs --bus-config" in capsys.readouterr().err
    assert main(["hw", "scan", "--hw", "dynamixel-emulated", "--bus-config", "talos_mit_can"]) == 2  # not its bus
    err = capsys.readouterr().err
    assert "--bus-config talos_mit_can: a mit_can bus config, and --hw dynamixel-emulated needs a dynamixel one" in err
    assert len(err.strip().splitlines()) == 1
    unplugged = tmp_path / "unplugged.yaml"  # a real port whose adapter is not there
    unplugged.write_text(load_bus_config("talos_dynamixel", load_robot("talos").joint_names).path.read_text()
                         .replace("/dev/ttyUSB0", str(tmp_path / "ttyUSB9")))
    assert main(["hw", "scan", "--hw", "dynamixel", "--bus-config", str(unplugged)]) == 2
    err = capsys.readouterr().err
    assert f"no serial device {tmp_path / 'ttyUSB9'} (port port)" in err and len(err.strip().splitlines()) == 1
