"""The walk-and-reach drawer task end to end in MuJoCo: synthesis → WPG → dynamic filter → IK →
servos, a real drawer on a slide joint, the grasp switched on from measured quantities only."""

import json

import mujoco
import numpy as np
import pytest
import report_page

from robot_ctrl import ROOT
from robot_ctrl.cli import main
from robot_ctrl.eval.campaigns.feasible_demonstrations import demonstration_from_run, touchdowns
from robot_ctrl.geometry import GRAVITY
from robot_ctrl.geometry.drawer_geometry import DRAWER_READINGS, DrawerGeometry
from robot_ctrl.hw.types import JointCommand
from robot_ctrl.robot.model import load_robot
from robot_ctrl.sim.drawer_cabinet import DrawerPlacement
from robot_ctrl.sim.mujoco_backend import MujocoBackend
from robot_ctrl.synthesis.demonstrations import comfort_distance, upper_body_joints


def test_drawer_task_end_to_end(tmp_path):
    status = main(["drawer", "--distance", "1.5", "--slot", "back_left", "--quiet", "--no-html",
                   "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fell"] is False and status == 0
    # The synthesis drove the walk: two normal cycles, the short one, standing; the gait cycles the
    # pelvis walked (measured) match the planned ones.
    assert report["actions"][-2:] == [2, 3] and set(report["actions"][:-2]) == {1}
    assert max(abs(e) for e in report["step_length_errors_m"]) <= 0.010  # every action, thesis Fig. 3.41
    assert abs(report["final_pelvis_to_drawer_m"] - report["comfort_distance_m"]) <= 0.03
    # The left hand took hold of the handle and pulled the drawer open past the back slot's clearance.
    assert report["grasp"] == "weld" and report["hand_to_handle_m"] <= 0.01
    assert report["drawer_opening_m"] >= report["drawer_opening_required_m"] == 0.28
    assert 10.0 < report["drawer_pull_force_peak_n"] < 200.0
    assert report["hand_to_object_m"] <= 0.02
    assert report["zmp_in_support_ratio"] >= 0.95
    assert report["success"] is True
    series = np.load(tmp_path / "timeseries.npz")
    assert series["drawer_opening_m"][0] == 0.0 and series["drawer_opening_m"][-1] >= 0.28
    assert not (tmp_path / "report.html").exists()  # --no-html: the page is rendered on demand
    assert main(["report", str(tmp_path)]) == 0
    page = (tmp_path / "report.html").read_text()
    assert page.count("data:image/png;base64,") == 6 and "Fig. 3.47" in page
    # The run is a feasible demonstration (thesis 3.8.3): its last normal cycle, short cycle and
    # standing, cut at measured touch-downs, with the realized signals.
    talos = load_robot("talos")
    upper = np.array([talos.joint_names.index(n) for n in upper_body_joints(talos)])
    weight = talos.mass * GRAVITY
    demo = demonstration_from_run(dict(series), "back_left", upper, weight)
    steps = touchdowns(series["drawer_t"], series["drawer_grf"], weight)
    first = steps[np.argmin(np.abs(steps - series["action_starts"][-4, 0]))]
    second = steps[np.argmin(np.abs(steps - series["action_starts"][-3, 0]))]
    assert abs((second - first) - demo.bounds[1] * 0.02) <= 0.01 + 1e-9  # the normal cycle: touch-down to touch-down
    stand = series["action_starts"][-2, 0]  # the synthesis's switch to standing: not a touch-down
    at = [series["drawer_base"][np.searchsorted(series["drawer_t"], when - 1e-9), 0] for when in (first, second, stand)]
    np.testing.assert_allclose(demo.lengths[:2], np.diff(at), atol=1e-3)  # the pelvis advance, touch-down to touch-down
    assert abs(demo.lengths[:2].sum() - sum(report["realized_step_lengths_m"][-3:-1])) < 0.02  # the report's cut
    walked = [demo.action(a)[:-1, 0].sum() * 0.02 for a in range(2)]  # the realized forward speed, integrated
    np.testing.assert_allclose(walked, demo.lengths[:2], atol=0.01)
    assert np.isfinite(demo.signals).all() and demo.signals.shape == (demo.bounds[-1] + 1, 3 + len(upper))
    np.testing.assert_allclose(demo.body[:, 3:][:, upper], demo.signals[:, 3:])  # the body holds every joint
    assert (demo.signals[:, 3:] >= talos.lower[upper] - 1e-3).all() and (demo.signals[:, 3:] <= talos.upper[upper] + 1e-3).all()
    assert abs(demo.body[:, 0].mean() - series["base_pos"][:, 2].mean()) < 0.02  # base height, not a joint


def test_the_demo_drawer_task_succeeds(tmp_path):
    # `make demo`, the first command a newcomer runs: it succeeds, and its last action (the pull and
    # the reach) does not move the pelvis (no foot re-stepped to correct a few millimetres). The
    # controller stays inside the servos' limits by itself: no servo is asked for more than its
    # effort (the IK's servo bounds), and the safety layer never steps in.
    status = main(["drawer", "--robot", "talos", "--distance", "2.0", "--slot", "front_left", "--quiet",
                   "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["success"] is True
    assert abs(report["step_length_errors_m"][-1]) <= 0.005 and report["hand_to_object_m"] <= 0.02
    assert report["safety"]["interventions"] == {}
    assert max(report["safety"]["demanded_peak_torque_ratio"].values()) <= 1.0
    # Its page, rendered by the run, says what was done and that it worked, with the command.
    page = (tmp_path / "report.html").read_text()
    assert report_page.title(page) == "Drawer task — Talos, 2.0 m, front-left slot"
    assert report_page.verdict(page)[0] == "ok"
    assert report_page.command(page) == report["command"] == ("robot-ctrl drawer --robot talos --distance 2.0 --slot "
                                                              f"front_left --quiet --out {tmp_path}")
    figures = report_page.key_figures(page)
    opening = f"{report['drawer_opening_m'] * 100:.1f} cm"
    assert figures["drawer_opening_m"] == (opening, "≥ 14 cm (the hand's clearance)", True)


def test_g1_with_hands_opens_its_own_cabinet_and_reaches_the_object(tmp_path):
    """The same task on Unitree G1 with its Dex3 hands, by configuration alone: its cabinet and gait at
    0.7 × Talos's size, its demonstrations, the index finger closing toward its lower limit. The
    config runs it unfiltered (``drawer.dynfilter``); no servo is asked for more than its effort at a
    control tick, the safety layer never steps in, and no arm rolls in against the torso."""
    status = main(["drawer", "--robot", "g1_dex3", "--distance", "2.0", "--slot", "back_right", "--quiet",
                   "--no-html", "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["success"] is True and report["dynfilter"] == "off"
    assert abs(report["final_pelvis_to_drawer_m"] - report["comfort_distance_m"]) <= 0.01
    assert report["grasp"] == "weld" and report["hand_to_handle_m"] <= 0.01
    assert report["drawer_opening_m"] >= report["drawer_opening_required_m"] == pytest.approx(0.28 * 0.7)
    assert report["hand_to_object_m"] <= 0.02 and report["zmp_in_support_ratio"] >= 0.98
    assert report["safety"]["interventions"] == {}
    assert max(report["safety"]["demanded_peak_torque_ratio"].values()) <= 0.95 + 1e-9
    series = np.load(tmp_path / "timeseries.npz")
    g1 = load_robot("g1_dex3")
    roll = [g1.joint_names.index(f"{s}_shoulder_roll_joint") for s in ("left", "right")]
    assert (series["joint_q"][:, roll] * [-1, 1]).max() <= 0.01  # never rolled in (docs/robots.md)


def test_the_drawer_task_succeeds_on_noisy_sensors_and_late_commands(tmp_path):
    """Encoders (1 mrad), IMU attitude (0.5°) and foot force sensors noisy, commands 10 ms late:
    the attitude filter keeps the estimated hands and the task's frame within the grasp's 1 cm
    (without it the robot closed its gripper 1.8 cm beside the handle and never pulled)."""
    status = main(["drawer", "--distance", "3.5", "--slot", "front_right", "--sensor-noise", "--latency-ms", "10",
                   "--quiet", "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["success"] is True and report["grasp"] == "weld"
    assert report["hand_to_object_m"] <= 0.01 and report["disturbances"]["sensor_noise"] is not None
    assert report["disturbances"]["latency_ms"] == 10
    assert report["safety"]["interventions"] == {}  # the IK's servo bounds judge the noisy, late state too


@pytest.mark.parametrize("name", ["talos", "g1_dex3"])
def test_drawer_takes_a_real_force_to_open(name):
    """Pulling the drawer with the grasp welded: the force the hand needs is the runners' friction
    (plus damping), measured through the weld's constraint force. The cabinet is the robot's (G1's
    at 0.7 × Talos's size); the grasp switches on with the gripper at its closing end, which is the
    upper limit for Talos's gripper, the lower for G1's left index finger."""
    robot = load_robot(name)
    geometry = robot.config.drawer
    backend = MujocoBackend(robot, prop=DrawerPlacement(1.2, "front_left"))
    backend.configure()
    backend.activate()
    m, d, cabinet = backend.m, backend.d, backend.prop
    assert m.jnt_range[m.joint("drawer_slide").id].tolist() == pytest.approx([0.0, geometry.travel])
    assert m.body("drawer").mass[0] == pytest.approx(geometry.drawer_mass)
    state = backend.read()
    gripper = robot.config.joint_index("grippers", "left")
    q = state.q.copy()
    open_end = robot.lower[gripper] if robot.config.grippers.closing_sign("left") > 0 else robot.upper[gripper]
    q[gripper] = d.qpos[cabinet.gripper_qpos] = open_end
    # Bring the handle to the open gripper: no grasp; close it there: the measured condition switches it on.
    d.mocap_pos[cabinet.mocap] += d.xpos[cabinet.hand] - d.site_xpos[cabinet.grip_site]
    mujoco.mj_forward(m, d)
    command = JointCommand(q, np.zeros(robot.nj), robot.kp, robot.kd, np.zeros(robot.nj))
    backend.write(command)
    assert dict(zip(DRAWER_READINGS, backend.read().scene))["grasped"] == 0.0
    q[gripper] = d.qpos[cabinet.gripper_qpos] = cabinet.gripper_closed_at
    d.mocap_pos[cabinet.mocap] += d.xpos[cabinet.hand] - d.site_xpos[cabinet.grip_site]
    mujoco.mj_forward(m, d)
    backend.write(command)
    scene = dict(zip(DRAWER_READINGS, backend.read().scene))
    assert scene["grasped"] == 1.0 and scene["left_hand_to_handle_m"] < 1e-3
    # Move the cabinet 10 cm away: the hand holds the drawer, so it slides out (the arm gives a
    # little under the load); the force on it is the runners' dry friction and damping.
    forces = []
    for _ in range(40):
        d.mocap_pos[cabinet.mocap][0] += 0.1 / 40
        backend.write(command)
        forces.append(dict(zip(DRAWER_READINGS, backend.read().scene))["drawer_pull_force_n"])
    scene = dict(zip(DRAWER_READINGS, backend.read().scene))
    assert 0.05 < scene["drawer_opening_m"] < 0.1
    assert geometry.slide_friction * 0.9 < np.median(forces) < geometry.slide_friction * 3, forces
    backend.close()


def test_the_cabinet_is_sized_to_the_robot():
    """Talos's config keeps the cabinet as designed; G1's scales every length by its ``drawer.scale``
    and the drawer's mass and friction by its cube; the demonstrations' comfort distance follows."""
    talos, g1 = load_robot("talos"), load_robot("g1_dex3")
    assert talos.config.drawer == DrawerGeometry()
    g, s = g1.config.drawer, 0.70
    np.testing.assert_allclose(g.handle_grip, np.array(DrawerGeometry().handle_grip) * s)
    assert g.clearance == pytest.approx({"front": 0.14 * s, "back": 0.28 * s})
    assert g.opening("back_left") == pytest.approx(0.32 * s) and g.travel == pytest.approx(0.35 * s)
    assert g.drawer_mass == pytest.approx(3.0 * s**3) and g.slide_friction == pytest.approx(15.0 * s**3)
    assert 0.35 < comfort_distance(g1) < 0.5 < comfort_distance(talos)


@pytest.mark.parametrize("args,message", [
    (["--distance", "0.5"], "--distance = 0.5 m is outside the allowed range"),
    (["--distance", "9"], "--distance = 9.0 m is outside the allowed range"),
    (["--slot", "middle"], "--slot = 'middle' is not one of front_left"),
    (["--goal-jump", "2:1.5"], "--goal-jump distance = 1.5 m must be farther"),
    (["--goal-jump", "x"], "--goal-jump 'x' must be TIME:DISTANCE"),
])
def test_drawer_rejects_bad_arguments(args, message, capsys, tmp_path):
    assert main(["drawer", *args, "--out", str(tmp_path / "run")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def drawer_log(opening=0.18, short_by=0.0):
    """Logged arrays of a drawer task: the pelvis walks 0.4 m (1-3 s), then 0.2 m less ``short_by``
    (3-5 s) and stands at the comfort distance; the drawer opens to ``opening`` from 6 s."""
    t = np.linspace(0.0, 10.0, 2001)
    x = np.interp(t, [0.0, 1.0, 3.0, 5.0, 10.0], [0.0, 0.0, 0.4, 0.6 - short_by, 0.6 - short_by])
    n = len(t)
    return {"t": t, "base": np.column_stack([x, np.zeros(n), np.zeros(n)]),
            "ankle_pitch_torque": np.full((n, 2), 40.0), "grf": np.full((n, 2), 450.0), "gripper_q": np.zeros((n, 2)),
            "drawer_opening_m": np.interp(t, [0.0, 6.0, 8.0], [0.0, 0.0, opening]),
            "drawer_velocity_mps": np.zeros(n), "drawer_pull_force_n": np.full(n, 30.0),
            "grasped": (t > 6.0).astype(float), "left_hand_to_handle_m": np.full(n, 0.004),
            "right_hand_to_object_m": np.full(n, 0.001), "cabinet_distance_m": np.full(n, 0.6 + 0.647)}


def outcome(log):
    from robot_ctrl.eval.recording.drawer_recorder import drawer_outcome

    return drawer_outcome(log, [1.0, 3.0, 5.0, 10.0], [0.4, 0.2, 0.0], lambda xy: float(xy[0]), fell=False,
                          required_opening=0.14, comfort=0.647, ankle_limit=np.array([160.0, 160.0]))


def test_the_drawer_report_judges_the_logged_run():
    good = outcome(drawer_log())
    assert good["success"] and good["realized_step_lengths_m"] == [0.4, 0.2, 0.0]
    assert good["final_pelvis_to_drawer_m"] == 0.647 and good["peak_ankle_pitch_torque_ratio"] == {"left": 0.25,
                                                                                                   "right": 0.25}
    shut = outcome(drawer_log(opening=0.0))  # every other criterion met, the drawer never opened
    assert not shut["success"] and shut["drawer_opening_m"] == 0.0
    short = outcome(drawer_log(short_by=0.02))  # the measured pelvis fell 2 cm short of the second action
    assert short["step_length_errors_m"] == [0.0, -0.02, 0.0] and not short["success"]


def test_every_drawer_report_field_from_a_logged_run():
    """Each figure of the drawer report from logged arrays of a known answer, with its rounding:
    the grasp from the first tick the weld holds (a reading of 0.5 is not a grasp), the hand at the
    handle then, not its closest; the last tick's opening, distance and hand; the ankles' peaks
    each over their own limit; success at the opening's and the object's thresholds exactly."""
    from robot_ctrl.eval.recording.drawer_recorder import drawer_outcome

    log = drawer_log(opening=0.1812345)
    n = len(log["t"])
    log["t"] = log["t"] + 0.0001234  # a clock that did not start on a 5 ms tick
    log["base"][1000, 0] -= 1e-9  # the second action ends a hair short: −0.0 must not reach the report
    log["base"][-1, 0] -= 0.0012345  # and the standing pelvis drifts back by the end
    log["drawer_opening_m"][-2] = 0.3
    log["ankle_pitch_torque"][:, 0] = 40.12345
    log["ankle_pitch_torque"][700, 1] = -80.5
    log["drawer_pull_force_n"][[5, 900]] = [np.nan, 31.23456]
    log["grasped"] = np.where(log["t"] > 6.0123, 1.0, np.where(log["t"] > 5.5, 0.5, 0.0))
    log["left_hand_to_handle_m"] = np.abs(np.linspace(-0.005, 0.011, n)) + 0.001  # closest at 3.1 s
    log["right_hand_to_object_m"][-2:] = [0.5, 0.0123456]
    log["cabinet_distance_m"][-2:] = [9.0, log["base"][-1, 0] + 0.6473456]
    report = drawer_outcome(log, [1.0, 3.0, 5.0, 10.5], [0.4, 0.2, 0.0], lambda xy: float(np.hypot(*xy)),
                            fell=False, required_opening=0.14, comfort=0.64731, ankle_limit=np.array([160.0, 100.0]))
    grasp = int(np.argmax(log["t"] > 6.0123))
    assert report == {
        "success": True, "planned_step_lengths_m": [0.4, 0.2, 0.0], "realized_step_lengths_m": [0.4, 0.2, -0.00123],
        "step_length_errors_m": [0.0, 0.0, -0.00123], "step_length_error_max_m": 0.00123, "comfort_distance_m": 0.6473,
        "final_pelvis_to_drawer_m": 0.6473, "drawer_opening_m": 0.1812, "drawer_opening_required_m": 0.14,
        "drawer_pull_force_peak_n": 31.23, "grasp": "weld", "grasp_time_s": 6.015,
        "hand_to_handle_m": round(float(log["left_hand_to_handle_m"][grasp]), 4), "hand_to_object_m": 0.0123,
        "peak_ankle_pitch_torque_ratio": {"left": 0.2508, "right": 0.805}}
    assert str(report["step_length_errors_m"][1]) == "0.0" and report["hand_to_handle_m"] == 0.0056
    assert log["t"][grasp] == pytest.approx(6.0151234)  # reported to the millisecond
    log["drawer_opening_m"][-1], log["right_hand_to_object_m"][-1] = 0.14, 0.02  # both at their thresholds
    assert outcome(log)["success"]
    log["grasped"][:] = 0.5
    ungrasped = outcome(log)
    assert ungrasped["grasp"] == "none" and ungrasped["grasp_time_s"] is None and ungrasped["hand_to_handle_m"] == 0.001
    no_actions = drawer_outcome(log, [1.0], [], lambda xy: float(xy[0]), fell=False, required_opening=0.14,
                                comfort=0.647, ankle_limit=np.array([160.0, 160.0]))
    assert no_actions["step_length_error_max_m"] is None and not no_actions["success"]


def test_without_position_feedback_the_synthesis_alone_steers_the_walk(tmp_path):
    """The commander's loops off: the synthesizer's own advance still matches its plan (kinematics),
    the measured pelvis does not, by more than with the loops on (test_drawer_task_end_to_end)."""
    status = main(["drawer", "--distance", "1.6", "--slot", "back_left", "--no-position-feedback", "--quiet",
                   "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["position_feedback"] is False and not report["fell"]
    synthesis = max(abs(e) for e in report["synthesis_step_length_errors_m"])
    realized = max(abs(e) for e in report["step_length_errors_m"])
    assert synthesis < 0.001 < realized and abs(report["final_pelvis_to_drawer_m"] - report["comfort_distance_m"]) > 0.01


def test_the_naive_baseline_plays_learned_joint_angles(tmp_path):
    """Thesis 3.8.4's naive method: every joint learned from the feasible runs and played on the
    servos after the walk-in. With enough sources, at a training sequence, the playback is sound:
    it walks the robot to the drawer, and the learned hands, with no hand task and no grasp logic,
    take the handle, pull the drawer open and reach the object as the training run did."""
    status = main(["drawer", "--method", "naive", "--sources", "8+8", "--distance", "1.40", "--slot", "back_right",
                   "--speed", "middle", "--quiet", "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["method"] == "naive" and report["sources"] == "8+8" and not report["fell"]
    assert report["actions"] == [1, 2, 3]
    assert max(abs(e) for e in report["step_length_errors_m"][:2]) < 0.03
    assert abs(report["final_pelvis_to_drawer_m"] - report["comfort_distance_m"]) < 0.03
    assert report["drawer_opening_m"] >= report["drawer_opening_required_m"] and report["hand_to_object_m"] < 0.02


def test_the_naive_baseline_without_a_recorded_set_says_how_to_record_one(capsys, tmp_path):
    """G1 ships no set recorded in physics (the naive baseline learns every joint from one): one line
    naming the command that records it, nothing written."""
    out = tmp_path / "out"
    assert main(["drawer", "--robot", "g1_dex3", "--method", "naive", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and not out.exists()
    assert err.endswith("generate them with: robot-ctrl synth-demos --robot g1_dex3 --from-physics --out "
                        f"{ROOT / 'models' / 'g1_dex3_walk_reach_feasible.npz'}")
