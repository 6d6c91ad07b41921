"""Disturbances of the simulated robot: pushes, model mismatch, latency, sensor noise."""

import json
import math

import mujoco
import numpy as np
import pytest

from robot_ctrl.cli import main
from robot_ctrl.hw.types import JointCommand
from robot_ctrl.sim.disturbances import Disturbances, Push
from robot_ctrl.sim.mujoco_backend import MujocoBackend


def hold(robot, state):
    zero = np.zeros(robot.nj)
    return JointCommand(q=state.q.copy(), dq=zero, kp=robot.kp, kd=robot.kd, tau_ff=zero)


def horizontal_momentum(backend) -> np.ndarray:
    m, d = backend.m, backend.d
    mujoco.mj_subtreeVel(m, d)
    root = backend._root
    return m.body_subtreemass[root] * d.subtree_linvel[root][:2]


@pytest.mark.parametrize("angle_deg,yaw", [(0.0, 0.0), (90.0, 0.0), (-135.0, 0.6)])
def test_a_push_changes_the_momentum_by_its_impulse(talos, angle_deg, yaw):
    """In the air (no contact force), the robot's horizontal momentum changes by the push's impulse
    (IMPULSE N·s per kg × mass) in the start frame's direction, within 2 %."""
    push = Push(0.05, math.radians(angle_deg), 0.2)
    backend = MujocoBackend(talos, base_xy_yaw=(0.0, 0.0, yaw), disturbances=Disturbances(pushes=(push,)))
    backend.configure()
    backend.activate()
    backend.d.qpos[backend.map.base_qpos + 2] += 1.5  # lifted well above the floor: free fall
    mujoco.mj_forward(backend.m, backend.d)
    state = backend.read()
    before = horizontal_momentum(backend)
    for _ in range(40):  # 0.2 s: the whole push
        backend.write(hold(talos, state))
    change = horizontal_momentum(backend) - before
    mass = backend.m.body_subtreemass[backend._root]
    expected = 0.2 * mass * np.array([math.cos(yaw + push.angle), math.sin(yaw + push.angle)])
    assert np.linalg.norm(change - expected) < 0.02 * np.linalg.norm(expected)
    backend.close()


def test_mass_friction_latency_and_noise(talos):
    nominal = MujocoBackend(talos)
    heavy = MujocoBackend(talos, disturbances=Disturbances(mass_scale=1.1, friction_scale=0.4))
    assert heavy.m.body_subtreemass[heavy._root] == pytest.approx(1.1 * nominal.m.body_subtreemass[nominal._root])
    np.testing.assert_allclose(heavy.m.geom_friction[:, 0], 0.4 * nominal.m.geom_friction[:, 0])
    weights = []
    for backend in (nominal, heavy):  # standing: the feet carry the (scaled) weight
        backend.configure()
        backend.activate()
        state = backend.read()
        for _ in range(100):
            backend.write(hold(talos, state))
        wrench = backend.read().foot_wrench
        weights.append(wrench["left"][2] + wrench["right"][2])
    assert weights[1] == pytest.approx(1.1 * weights[0], rel=0.01)
    # Latency: a command reaches the servos two periods (10 ms) after it was written.
    moved = {}
    for latency in (0.0, 0.01):
        backend = MujocoBackend(talos, disturbances=Disturbances(latency=latency))
        backend.configure()
        backend.activate()
        state = backend.read()
        elbow = talos.joint_names.index("arm_left_4_joint")
        command = hold(talos, state)
        command.q[elbow] += 0.3
        speeds = []
        for _ in range(4):
            backend.write(command)
            speeds.append(abs(backend.read().dq[elbow]))
        moved[latency] = speeds
    assert moved[0.0][0] > 0.2 and max(moved[0.01][:2]) < 0.05 and moved[0.01][2] > 0.2
    with pytest.raises(ValueError, match="must be a multiple of the control period"):
        MujocoBackend(talos, disturbances=Disturbances(latency=0.007))
    # Sensor noise: encoders scattered by about 1 mrad around the truth, a unit quaternion.
    noisy = MujocoBackend(talos, disturbances=Disturbances(sensor_noise=True))
    noisy.configure()
    samples = np.array([noisy.read().q for _ in range(200)])
    truth = noisy.d.qpos[noisy.map.qpos]
    assert np.std(samples - truth) == pytest.approx(1e-3, rel=0.1)
    assert np.linalg.norm(noisy.read().base_quat_xyzw) == pytest.approx(1.0)


def test_a_disturbed_walk_from_the_command_line(tmp_path):
    args = ["walk", "--distance", "1", "--push", "2.0:90:0.1", "--mass-scale", "1.1", "--friction-scale", "0.6",
            "--latency-ms", "5", "--sensor-noise", "--quiet", "--out", str(tmp_path)]
    assert main(args) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fell"] is False and report["final_position_error_m"] < 0.05
    d = report["disturbances"]
    assert d["pushes"][0]["angle_deg"] == pytest.approx(90.0) and d["mass_scale"] == 1.1 and d["latency_ms"] == 5.0
    assert d["sensor_noise"]["joint_position"] == 1e-3


@pytest.mark.parametrize("option,message", [
    (["--latency-ms", "7"], "--latency-ms: latency = 7 ms must be a multiple of the control period"),
    (["--mass-scale", "3"], r"--mass-scale = 3.0 is outside the allowed range \[0.5, 2.0\]"),
    (["--push", "1:2"], "--push '1:2' must be TIME:ANGLE_DEG:IMPULSE"),
    (["--push", "1:0:5"], r"--push: push impulse = 5.0 N·s/kg is outside the allowed range \[0, 2\]"),
    (["--friction-scale", "nan"], "--friction-scale = nan is outside the allowed range"),
])
def test_bad_disturbances_are_refused(option, message, capsys):
    import re

    assert main(["walk", "--distance", "1", *option]) == 2
    assert re.search(message, capsys.readouterr().err)


def test_a_robot_that_falls_is_reported_as_fallen(tmp_path):
    """The fall detector fires: a 2 N·s/kg push to the right knocks Talos over; the walk reports it
    and exits with status 1."""
    assert main(["walk", "--distance", "1", "--push", "1.0:-90:2", "--quiet", "--out", str(tmp_path)]) == 1
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fell"] is True and 1.0 < report["fall_time_s"] < 4.0
    assert "touching the floor" in report["fall_reason"] or "base height" in report["fall_reason"]
    # It met a single support on the right foot, whose outer edge alone could have caught it: far
    # below the push.
    (capture,) = report["push_capture"]
    assert capture["support"] == "right" and 0.2 < capture["lip_capturable_ns_per_kg"] < 0.6
    # Only the stance sole's edge acts on that side: when the swing foot lands does not matter.
    assert capture["lip_capturable_own_timing_ns_per_kg"] == capture["lip_capturable_ns_per_kg"]
