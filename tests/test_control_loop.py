"""The control loop every scenario runs on, the hardware it runs over, and what a user sees of a run."""

import json

import numpy as np
import pytest

from robot_ctrl.backends import open_hardware
from robot_ctrl.cli import main
from robot_ctrl.control.loop.control_loop import ControlLoop
from robot_ctrl.eval.recording.recorders import TimeLimit
from robot_ctrl.hw.types import JointCommand
from robot_ctrl.wpg.params import WalkParams


class HoldPosture:
    """A controller that holds the measured start posture and counts its calls."""

    def __init__(self, robot, state):
        self.robot, self.q = robot, state.q.copy()
        self.calls: list[str] = []

    def prepare(self):
        self.calls.append("prepare")

    def step(self, state):
        self.calls.append("step")
        zero = np.zeros(self.robot.nj)
        return JointCommand(q=self.q, dq=zero, kp=self.robot.kp, kd=self.robot.kd, tau_ff=zero)

    def close(self):
        self.calls.append("close")


class Log:
    def __init__(self):
        self.events: list[tuple] = []

    def on_command(self, tick):
        self.events.append(("command", tick.k, tick.t, tick.states[0].t))

    def on_state(self, tick):
        self.events.append(("state", tick.k, tick.t, tick.states[0].t))

    def begin_tick(self, t):
        self.events.append(("begin", t))


def test_the_loop_steps_writes_prepares_and_reads_in_order(talos):
    with open_hardware("mujoco", talos) as hw:
        hw.configure()
        hw.activate()
        state = hw.read()
        controller, log = HoldPosture(talos, state), Log()
        result = ControlLoop([hw], [controller], 0.005, commanders=[log], recorders=[log],
                             stops=[TimeLimit(0.0199, "four ticks")]).run([state])
        assert hw.report()["interventions"] == {}
    assert result.ticks == 4 and result.states[0].t == pytest.approx(0.02) and "four ticks" in result.stop_reason
    assert controller.calls == ["step", "prepare"] * 4 + ["close"]
    assert log.events[0] == ("begin", 0.0)
    for k in range(4):  # a tick's command is computed from the state at t_k; the read brings t_k + dt
        command, begin, read = log.events[1 + 3 * k: 4 + 3 * k]
        assert command[:2] == ("command", k) and command[2] == pytest.approx(0.005 * k) == command[3]
        assert begin == ("begin", pytest.approx(0.005 * (k + 1)))
        assert read[:2] == ("state", k) and read[3] == pytest.approx(0.005 * (k + 1))


@pytest.mark.realtime
@pytest.mark.parametrize("hw", ["mit-can-emulated", "dynamixel-emulated"])
def test_a_walk_over_an_emulated_servo_bus(hw, tmp_path):
    assert main(["walk", "--distance", "1", "--hw", hw, "--quiet", "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fell"] is False and report["final_position_error_m"] < 0.05
    assert report["zmp_in_support_ratio"] > 0.98 and report["peak_torque_ratio"] < 1.0
    assert report["safety"]["state"] == "active" and "rejected_command" not in report["safety"]["interventions"]
    demanded = report["safety"]["demanded_peak_torque_ratio"]  # before the layer, per joint
    assert len(demanded) == 32 and 0.0 < demanded["leg_left_4_joint"] < 2.0


def test_a_video_of_the_simulated_robot(talos, tmp_path):
    import imageio_ffmpeg

    path = tmp_path / "stand.mp4"
    with open_hardware("mujoco", talos, video=path) as hw:
        hw.configure()
        hw.activate()
        state = hw.read()
        hold = HoldPosture(talos, state)
        ControlLoop([hw], [hold], 0.005, stops=[TimeLimit(0.399, "0.4 s")]).run([state])
    frames = imageio_ffmpeg.read_frames(str(path))
    meta = next(frames)
    images = [np.frombuffer(f, np.uint8).reshape(480, 640, 3) for f in frames]
    assert meta["size"] == (640, 480) and meta["fps"] == 30.0
    assert len(images) == 13  # t = 0, 1/30, ..., 0.4 s
    robot = images[-1][100:400, 220:420].astype(float)  # the robot stands in the middle of the frame
    assert robot.std() > 20.0 and np.abs(images[-1].astype(float) - images[0]).mean() < 5.0  # it stands still


def test_video_and_hardware_options_are_checked(capsys, tmp_path):
    assert main(["walk", "--distance", "1", "--video", str(tmp_path / "walk.avi")]) == 2
    assert "--video" in capsys.readouterr().err
    assert main(["crowd", "walk", "--hw", "mit-can-emulated"]) == 2
    assert "one shared MuJoCo world" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["walk", "--hw", "can"])
    assert "invalid choice" in capsys.readouterr().err


def test_walk_params_derive_the_robot_fields_and_refuse_contradictions():
    measured = dict(com_height=0.88, foot_length=0.21, foot_width=0.13, step_width=0.17)
    assert not WalkParams().resolved
    assert WalkParams().for_robot(**measured).com_height == 0.88
    assert WalkParams(foot_length=0.18).for_robot(**measured).foot_length == 0.18  # a smaller sole: allowed
    with pytest.raises(ValueError, match="WalkParams.com_height = 0.7 m contradicts the robot's start posture"):
        WalkParams(com_height=0.7).for_robot(**measured)
    with pytest.raises(ValueError, match="WalkParams.foot_width = 0.2 m is larger than the robot's sole"):
        WalkParams(foot_width=0.2).for_robot(**measured)


def test_sigterm_closes_the_hardware_and_exits_130(tmp_path):
    """A walk stopped by SIGTERM (as a process manager stops it) closes its hardware on the way out
    (damping, then disable) and says so in one line, no traceback."""
    import signal
    import subprocess
    import sys
    import time

    process = subprocess.Popen([sys.executable, "-m", "robot_ctrl.cli", "walk", "--distance", "60", "--quiet",
                                "--out", str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(6.0)  # into the walk: 60 m take minutes of simulated time, far more than 6 s of wall time anywhere
    assert process.poll() is None, "the walk ended before the signal"
    process.send_signal(signal.SIGTERM)
    out, err = process.communicate(timeout=30)
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == "robot-ctrl: interrupted (SIGTERM)" and "Traceback" not in err
    assert not (tmp_path / "report.json").exists()  # no half-written report


def test_an_interrupt_inside_compiled_code_exits_130_in_one_line(monkeypatch, capsys):
    """A signal that lands while a numba kernel calls back into Python surfaces as a SystemError
    caused by the KeyboardInterrupt (seen with SIGTERM during the IK's KKT solve): still an
    interrupt; any other SystemError is not."""
    from robot_ctrl.cli import robot_runs

    def interrupted_in_a_kernel(args):
        try:
            raise KeyboardInterrupt("SIGTERM")
        except KeyboardInterrupt as interrupt:
            try:
                raise SystemError("<function _numba_unpickle> returned a result with an exception set") from interrupt
            except SystemError as inner:
                raise SystemError("CPUDispatcher(kkt_solution) returned a result with an exception set") from inner

    monkeypatch.setattr(robot_runs, "_walk", interrupted_in_a_kernel)
    assert main(["walk"]) == 130
    assert capsys.readouterr().err == "robot-ctrl: interrupted (SIGTERM)\n"

    def failed(args):
        raise SystemError("a real failure")

    monkeypatch.setattr(robot_runs, "_walk", failed)
    with pytest.raises(SystemError, match="a real failure"):
        main(["walk"])


def test_the_pacers_record_stays_bounded_and_keeps_the_worst_tick():
    """A run of hours must not grow the pacer's record: the latest ticks are kept for the median and
    the 99th percentile, the count and the worst lateness over every tick."""
    from robot_ctrl.control.loop.pacer import LATENESS_WINDOW, Pacer

    clock = {"t": 0.0, "oversleep": 0.002}

    def sleep(s):  # the first sleep wakes 2 ms late, the others on time
        clock["t"] += s + clock["oversleep"]
        clock["oversleep"] = 0.0

    pacer = Pacer(0.005, clock=lambda: clock["t"], sleep=sleep)
    for _ in range(LATENESS_WINDOW + 10):
        pacer.wait()
        clock["t"] += 0.001  # 1 ms of work
    clock["t"] += 0.01
    pacer.wait()  # an overrun
    report = pacer.report()
    assert len(pacer.lateness) == LATENESS_WINDOW and report["ticks"] == LATENESS_WINDOW + 11
    assert report["overruns"] == 1 and report["lateness_ms"]["median"] == 0.0
    assert report["lateness_ms"]["max"] == pytest.approx(2.0)  # long out of the window, still the worst


def test_a_paced_run_keeps_the_garbage_collector_off_what_existed_before_it(talos):
    """On real servos a full collection over the loaded modules and models (tens of ms) would stall
    a tick at a moment nobody chose: the paced loop freezes what exists when it starts, and only for
    the run; a simulated run (no pacer) leaves the collector as it is."""
    import gc

    from robot_ctrl.control.loop.pacer import Pacer

    class FrozenDuringStep(HoldPosture):
        def step(self, state):
            self.frozen = gc.get_freeze_count()
            return super().step(state)

    with open_hardware("mujoco", talos) as hw:
        hw.bring_up()
        for pacer in (None, Pacer(0.005)):
            controller = FrozenDuringStep(talos, hw.read())
            ControlLoop([hw], [controller], 0.005, pacer=pacer, stops=[TimeLimit(0.0099, "two ticks")]).run(
                [hw.read()])
            assert (controller.frozen > 10_000) == (pacer is not None), controller.frozen
            assert gc.get_freeze_count() == 0
