"""Scenarios on real servo interfaces (``--hw mit-can``): the real backend, paced on absolute
deadlines, over python-can to the MIT-CAN emulator standing in for the drives, with the body
sensors from a driver the bus config names. What the run knows of the robot is what a real one
measures; the emulator's simulated robot is the ground truth the test checks it against.

One Python process cannot simulate the robot and control it at 200 Hz of wall-clock time, so the
run keeps a clock six times slower than the wall's (a computer six times faster than this one):
everything that keeps time on real servos (safety layer and its watchdog, backend, pacer, sensor
driver) keeps it on that clock."""

import time
import uuid

import emulated_body_sensors
import numpy as np
import pytest

from robot_ctrl.backends import open_hardware
from robot_ctrl.buses.bus_config import load_bus_config
from robot_ctrl.buses.mit_can_emulator import MitCanEmulator
from robot_ctrl.cli import main
from robot_ctrl.control.commanders.path_follower import WalkGoal
from robot_ctrl.control.loop.pacer import Pacer
from robot_ctrl.control.loop.start_sequence import StartParams
from robot_ctrl.modes import BaseState
from robot_ctrl.scenarios.bringup import HOLD_S
from robot_ctrl.scenarios.walk import WalkSettings, run_walk
from robot_ctrl.sim.mujoco_backend import MujocoBackend

pytestmark = pytest.mark.realtime  # wall-clock timing: run apart from the parallel tests

SLOWER = 6.0  # wall seconds per second of the run's clock


class SlowClock:
    def __call__(self) -> float:
        return time.monotonic() / SLOWER

    @staticmethod
    def sleep(seconds: float) -> None:
        time.sleep(seconds * SLOWER)


@pytest.fixture
def servos(talos, tmp_path):
    """A bus config for the emulated drives on channels of their own, naming the test's body-sensor
    driver; the emulator running behind it."""
    config = load_bus_config("talos_mit_can", talos.joint_names)
    tag = uuid.uuid4().hex[:8]
    text = config.path.read_text()
    for options in config.buses.values():
        text = text.replace(f"channel: {options['channel']}", f"channel: {options['channel']}_{tag}")
    path = tmp_path / "robot.yaml"
    path.write_text(text + "body_sensors: emulated_body_sensors:open_sensors\n")
    emulator = MitCanEmulator(load_bus_config(path, talos.joint_names), MujocoBackend(talos))
    emulator.start()
    emulated_body_sensors.EMULATOR, emulated_body_sensors.CLOCK = emulator, SlowClock()
    try:
        yield path, emulator
    finally:
        emulator.close()
        emulated_body_sensors.EMULATOR, emulated_body_sensors.CLOCK = None, time.monotonic


def test_a_walk_on_real_servos_starts_with_the_start_sequence_and_walks_on_the_estimated_base(talos, servos,
                                                                                             caplog):
    path, emulator = servos
    start = emulator.body_state().base_pos.copy()
    clock, dt = SlowClock(), 0.005
    with open_hardware("mit-can", talos, str(path), clock=clock, allow_drives_without_timeout=True) as hw:
        pacer = Pacer(dt, clock=clock, sleep=clock.sleep)
        lines = []
        report = run_walk(talos, hw, WalkGoal(distance=0.4), WalkSettings(base_state=BaseState.ESTIMATED),
                          log=lines.append, pacer=pacer)
    assert lines[0].startswith("start sequence: held half-sitting")
    assert "if this process dies, 32 joints hold their last command (no drive timeout): leg_left_1_joint, " in caplog.text
    assert report["base_state"] == "estimated" and report["base_ground_truth"] is False
    assert report["base_estimate_error"] is None and not report["fell"]
    # The controller keeps the pace: the median tick starts on time, and a tick overruns by computing
    # too long at most twice. A shared host can also hold the process off the CPU (a CI machine did, 8
    # times in one run); the watchdog must then catch it, so each of its trips follows an overrun, never
    # a tick that kept time nor the end of the run (its report is built with the watchdog disarmed).
    timing, trips = report["timing"], report["safety"]["interventions"].get("watchdog", 0)
    assert timing["ticks"] > 2000 and timing["lateness_ms"]["median"] < 0.5, timing
    assert timing["overruns"] - timing["overruns_off_cpu"] <= 2 and trips <= timing["overruns"], (timing, trips)
    # The start sequence came first, at reduced stiffness (StartParams.gain_scale 0.3), then the walk
    # at the servo gains, but for the walk's soft start, the closing damping and, after each watchdog
    # trip, the damping and the soft start (SafetyLimits.soft_start) the next write resumes with.
    kp = np.array([c.kp for _, c in emulator.received])
    knee = talos.joint_names.index("leg_left_4_joint")
    start_ticks = round((StartParams().duration + HOLD_S) / dt)
    assert np.all(kp[:start_ticks, knee] <= 0.3 * talos.kp[knee] * 1.001)  # MIT frames quantize kp
    walking = np.isclose(kp[start_ticks:, knee], talos.kp[knee], rtol=1e-3)
    resumed = trips * (round(hw.limits.soft_start / dt) + 1)
    assert (~walking).sum() <= 0.05 * walking.size + resumed, (walking.mean(), trips)
    # Where the simulated robot went: 0.4 m forward of where it stood.
    moved = emulator.body_state().base_pos - start
    assert moved[0] == pytest.approx(0.4, abs=0.05) and abs(moved[1]) < 0.05


def test_scenarios_on_real_servos_refuse_what_only_a_simulation_has(talos, servos, capsys):
    path, emulator = servos
    for extra, message in ((["--push", "1:0:0.1"], "act on a simulated robot, not on real servos"),
                           (["--base-state", "simulated"], "has no simulator"),
                           (["--video", "x.mp4"], "show the simulation")):
        assert main(["balance", "--hw", "mit-can", "--bus-config", str(path), *extra]) == 2
        assert message in capsys.readouterr().err
    # Drives with no command timeout of their own, on a real bus: only when the user says so.
    assert main(["balance", "--hw", "mit-can", "--bus-config", str(path)]) == 2
    err = capsys.readouterr().err
    assert "--hw mit-can: 32 drives have no command timeout of their own" in err
    assert "Pass --allow-drives-without-timeout" in err and not emulator.enabled.any()
    missing = path.with_name("missing.yaml")
    missing.write_text(path.read_text().replace("emulated_body_sensors:open_sensors", "emulated_body_sensors:open_missing"))
    assert main(["walk", "--hw", "mit-can", "--bus-config", str(missing), "--distance", "1",
                 "--allow-drives-without-timeout"]) == 3
    assert "the driver did not open (OSError: no such device: /dev/imu0)" in capsys.readouterr().err
    malformed = path.with_name("malformed.yaml")
    malformed.write_text(path.read_text().replace("emulated_body_sensors:open_sensors", "'not a driver'"))
    assert main(["walk", "--hw", "mit-can", "--bus-config", str(malformed)]) == 2
    assert "body_sensors = 'not a driver' must be module:function" in capsys.readouterr().err
