"""The walk-and-reach drawer task end to end in MuJoCo: synthesis → WPG → dynamic filter → IK →
servos, a real drawer on a slide joint, pulled by the contacts of the hand's fingers alone."""

import json

import mujoco
import numpy as np
import pinocchio as pin
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
    # The left hand's fingers took the handle and pulled the drawer open to the back slot's clearance.
    assert report["grasp"] == "contact" and report["hand_to_handle_m"] <= 0.03
    assert report["drawer_opening_m"] >= 0.95 * report["drawer_opening_required_m"] == 0.95 * 0.28
    assert 10.0 < report["drawer_pull_force_peak_n"] < 200.0 and report["handle_slip_max_m"] < 0.02
    assert report["hand_to_object_m"] <= 0.02
    assert report["zmp_in_support_ratio"] >= 0.95
    assert report["success"] is True
    series = np.load(tmp_path / "timeseries.npz")
    assert abs(series["drawer_opening_m"][0]) < 1e-4 and series["drawer_opening_m"][-1] >= 0.95 * 0.28
    # The pull force is the contacts' own: while the drawer slides at speed in the hand, it is the
    # runners' dry friction and damping (and the drawer's inertia); with the hand off, none.
    geometry = load_robot("talos").config.drawer
    v, pull = series["drawer_velocity_mps"], series["drawer_pull_force_n"]
    sliding = (v > 0.05) & (series["grasped"] > 0.5)
    assert sliding.sum() > 20
    resisting = np.median(pull[sliding] - geometry.slide_damping * v[sliding])
    assert 0.8 * geometry.slide_friction < resisting < 2.5 * geometry.slide_friction, resisting
    assert (pull[(series["grasped"] < 0.5) & (series["unintended_contacts"] == 0)] == 0.0).all()
    assert not (tmp_path / "report.html").exists()  # --no-html: the page is rendered on demand
    assert main(["report", str(tmp_path)]) == 0
    page = (tmp_path / "report.html").read_text()
    assert page.count("data:image/png;base64,") == 6 and "Fig. 3.47" in page and "contact forces" in page
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
    assert figures["drawer_opening_m"] == (opening, "≥ 95% of 14 cm (the hand's clearance)", True)


def test_g1_with_hands_walks_to_its_own_cabinet_and_reaches_for_the_handle(tmp_path):
    """The same task on Unitree G1 with its Dex3 hands, by configuration alone: its cabinet and gait at
    0.7 × Talos's size, its demonstrations, its own grip on the handle, the index finger closing
    toward its lower limit, run unfiltered (``drawer.dynfilter``). It walks every gait cycle within
    the thesis's 10 mm to its cabinet without falling; no servo is asked for more than its effort at
    a control tick, the safety layer never steps in, and no arm rolls in against the torso. Its hand
    does not yet take the handle (docs/drawer.md): what the report says of the drawer is the
    physics', a closed drawer."""
    status = main(["drawer", "--robot", "g1_dex3", "--distance", "2.0", "--slot", "back_right", "--quiet",
                   "--no-html", "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["fell"] is False and report["dynfilter"] == "off"
    assert max(abs(e) for e in report["step_length_errors_m"][:-2]) <= 0.01
    assert report["drawer_opening_required_m"] == pytest.approx(0.28 * 0.7)
    series = np.load(tmp_path / "timeseries.npz")
    assert report["drawer_opening_m"] == round(float(series["drawer_opening_m"][-1]), 4) < 0.01
    assert report["safety"]["interventions"] == {}
    assert max(report["safety"]["demanded_peak_torque_ratio"].values()) <= 0.95 + 1e-9
    series = np.load(tmp_path / "timeseries.npz")
    g1 = load_robot("g1_dex3")
    roll = [g1.joint_names.index(f"{s}_shoulder_roll_joint") for s in ("left", "right")]
    assert (series["joint_q"][:, roll] * [-1, 1]).max() <= 0.01  # never rolled in (docs/robots.md)


def test_the_drawer_task_succeeds_on_noisy_sensors_and_late_commands(tmp_path):
    """Encoders (1 mrad), IMU attitude (0.5°) and foot force sensors noisy, commands 10 ms late:
    the attitude filter keeps the estimated hands and the task's frame true enough for the fingers
    to find the handle (without it the robot closed its gripper 1.8 cm beside the handle)."""
    status = main(["drawer", "--distance", "3.5", "--slot", "front_right", "--sensor-noise", "--latency-ms", "10",
                   "--quiet", "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["success"] is True and report["grasp"] == "contact"
    assert report["hand_to_object_m"] <= 0.01 and report["disturbances"]["sensor_noise"] is not None
    assert report["disturbances"]["latency_ms"] == 10
    assert report["safety"]["interventions"] == {}  # the IK's servo bounds judge the noisy, late state too


def talos_by_the_drawer(elbow: float = -1.6):
    """Talos standing in its MuJoCo world with the drawer cabinet, its left elbow bent (the hand in
    front of it), after 1 s; the backend, its world and the cabinet in it, and a command holding that."""
    robot = load_robot("talos")
    backend = MujocoBackend(robot, prop=DrawerPlacement(1.5, "front_left"))
    backend.configure()
    backend.activate()
    q = np.array(robot.config.half_sitting)
    q[robot.joint_names.index("arm_left_4_joint")] = elbow
    command = JointCommand(q, np.zeros(robot.nj), robot.kp, robot.kd, np.zeros(robot.nj))
    for _ in range(200):
        backend.write(command)
    return robot, backend, command


def place_cabinet(backend, rotation: np.ndarray) -> None:
    """Turn the cabinet by ``rotation`` (world) and put its handle's grip point at the left gripper base."""
    m, d, cabinet = backend.m, backend.d, backend.prop
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rotation.flatten())
    d.mocap_quat[cabinet.mocap] = quat
    d.mocap_pos[cabinet.mocap] = d.xpos[cabinet.hand] - rotation @ m.site_pos[cabinet.grip_site]
    mujoco.mj_forward(m, d)


def pull_cabinet_away(backend, command, distance: float, periods: int) -> list[dict]:
    """Move the cabinet ``distance`` [m] along its own x (away from the hand that holds its drawer, which
    opens toward -x) over ``periods`` control periods; the drawer's readings of each."""
    m, d, cabinet = backend.m, backend.d, backend.prop
    x = d.xmat[m.body("cabinet").id].reshape(3, 3)[:, 0].copy()
    readings = []
    for _ in range(periods):
        d.mocap_pos[cabinet.mocap] += x * distance / periods
        backend.write(command)
        readings.append(dict(zip(DRAWER_READINGS, backend.read().scene)))
    return readings


def test_the_fingers_hook_the_handle_and_pull_the_drawer_by_contact():
    """The left hand as the task holds the handle (``grasp.hand_rpy``, the bar ``bar_from_grip`` out
    along the open fingers): moving the cabinet away at 0.2 m/s (the task's pull), the fingers catch the
    bar and the drawer slides out of it. The force it takes, from the contacts, is the runners' dry
    friction and damping (MuJoCo's dry friction is a soft constraint: sliding, the runners' 15 N give
    about 8); the fingers touch the handle throughout and the handle barely moves in the hand (their
    open limit, not the 1 N·m gripper servo, takes the pull)."""
    robot, backend, command = talos_by_the_drawer()
    geometry = robot.config.drawer
    hand = backend.d.xmat[backend.prop.hand].reshape(3, 3)
    place_cabinet(backend, hand @ pin.utils.rpyToMatrix(*robot.config.grippers.hand_rpy).T)
    start = dict(zip(DRAWER_READINGS, backend.read().scene))
    assert start["grasped"] == 0.0 and start["left_hand_to_handle_m"] < 1e-4  # free play before the hook
    readings = pull_cabinet_away(backend, command, 0.12, 120)
    opening = np.array([r["drawer_opening_m"] for r in readings])
    assert 0.05 < opening[-1] < 0.12  # less the fingers' free play round the bar and the arm's give
    held = [r for r in readings if r["grasped"] == 1.0 and r["drawer_velocity_mps"] > 0.1]
    assert len(held) > 40
    resisting = np.median([r["drawer_pull_force_n"] - geometry.slide_damping * r["drawer_velocity_mps"] for r in held])
    assert 0.4 * geometry.slide_friction < resisting < 1.5 * geometry.slide_friction, resisting
    assert max(r["handle_slip_m"] for r in readings) < 0.04
    assert all(r["unintended_contacts"] == 0 for r in readings)
    backend.close()


def test_a_hand_at_the_handle_but_not_round_it_does_not_open_the_drawer():
    """The gripper base on the handle's grip point and the gripper closed (what switched a weld on),
    but the hand turned away from the bar: nothing holds the drawer, which stays shut."""
    robot, backend, command = talos_by_the_drawer()
    gripper = robot.config.joint_index("grippers", "left")
    command.q[gripper] = robot.lower[gripper] + robot.config.position_margin
    for _ in range(400):
        backend.write(command)
    hand = backend.d.xmat[backend.prop.hand].reshape(3, 3)
    designed = hand @ pin.utils.rpyToMatrix(*robot.config.grippers.hand_rpy).T
    place_cabinet(backend, designed @ pin.utils.rpyToMatrix(np.pi / 2, 0.0, 0.0))  # the bar beside the fingers
    readings = pull_cabinet_away(backend, command, 0.12, 60)
    assert readings[0]["left_hand_to_handle_m"] < 0.01
    assert max(abs(r["drawer_opening_m"]) for r in readings) < 0.002
    assert all(r["grasped"] == 0.0 and r["drawer_pull_force_n"] == 0.0 for r in readings)
    backend.close()


def test_the_cabinet_collides_with_the_robot_and_nothing_ties_them():
    """Robot and cabinet touch as furniture does: the drawer's front pushed against the pelvis is a
    contact the cabinet reports as unintended, with its force. The world's only equality constraints
    are the robot's own (its grippers' finger linkages), none between the robot and the world."""
    robot, backend, command = talos_by_the_drawer(elbow=-0.525366)
    m, d, cabinet = backend.m, backend.d, backend.prop
    for e in range(m.neq):
        assert m.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT
        assert all(m.joint(int(j)).name.startswith("talos/gripper_") for j in (m.eq_obj1id[e], m.eq_obj2id[e]))
    assert dict(zip(DRAWER_READINGS, backend.read().scene))["unintended_contacts"] == 0.0
    base = d.xpos[m.body("talos/base_link").id]
    d.mocap_quat[cabinet.mocap] = [1.0, 0.0, 0.0, 0.0]
    d.mocap_pos[cabinet.mocap] = [base[0] + 0.12, base[1] - 0.05, base[2]]  # the panel 12 cm ahead of the pelvis
    mujoco.mj_forward(m, d)
    backend.write(command)
    touch = dict(zip(DRAWER_READINGS, backend.read().scene))
    assert touch["unintended_contacts"] > 0 and touch["unintended_force_n"] > 1.0 and touch["grasped"] == 0.0
    backend.close()


def test_the_cabinet_is_sized_to_the_robot():
    """Talos's config keeps the cabinet as designed; G1's scales every length by its ``drawer.scale``
    and the drawer's mass and friction by its cube, but for where its own hand holds the handle
    (``drawer.handle_grip``, ``bar_from_grip``); the demonstrations' comfort distance follows."""
    talos, g1 = load_robot("talos"), load_robot("g1_dex3")
    assert talos.config.drawer == DrawerGeometry()
    g, s = g1.config.drawer, 0.70
    assert g.handle_grip == (-0.091, 0.105, 0.07) and g.bar_from_grip == (0.042, -0.0245, -0.014)
    np.testing.assert_allclose(g.drawer_y, np.array(DrawerGeometry().drawer_y) * s)
    assert g.handle_radius == pytest.approx(0.011 * s) and g.object_mass == pytest.approx(0.3 * s**3)
    assert g.clearance == pytest.approx({"front": 0.14 * s, "back": 0.28 * s})
    assert g.opening("back_left") == pytest.approx(0.30 * s) and g.travel == pytest.approx(0.35 * s)
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
            "grasped": (t > 6.0).astype(float), "grip_force_n": np.where(t > 6.0, 35.0, 0.0),
            "handle_slip_m": np.where(t > 6.0, 0.004, 0.0), "left_hand_to_handle_m": np.full(n, 0.004),
            "right_hand_to_object_m": np.full(n, 0.001), "cabinet_distance_m": np.full(n, 0.6 + 0.647),
            "object_lift_m": np.zeros(n), "object_held": np.zeros(n), "object_grip_force_n": np.zeros(n),
            "unintended_contacts": np.zeros(n), "unintended_force_n": np.zeros(n)}


def outcome(log):
    from robot_ctrl.eval.recording.drawer_recorder import drawer_outcome

    return drawer_outcome(log, [1.0, 3.0, 5.0, 10.0], [0.4, 0.2, 0.0], lambda xy: float(xy[0]), fell=False,
                          required_opening=0.14, comfort=0.647, ankle_limit=np.array([160.0, 160.0]), travel=0.35)


def test_the_drawer_report_judges_the_logged_run():
    good = outcome(drawer_log())
    assert good["success"] and good["realized_step_lengths_m"] == [0.4, 0.2, 0.0]
    assert good["final_pelvis_to_drawer_m"] == 0.647 and good["peak_ankle_pitch_torque_ratio"] == {"left": 0.25,
                                                                                                   "right": 0.25}
    shut = outcome(drawer_log(opening=0.0))  # every other criterion met, the drawer never opened
    assert not shut["success"] and shut["drawer_opening_m"] == 0.0
    ajar = outcome(drawer_log(opening=0.95 * 0.14 - 1e-4))  # just short of 95 % of the clearance
    assert not ajar["success"] and outcome(drawer_log(opening=0.95 * 0.14 + 1e-4))["success"]
    short = outcome(drawer_log(short_by=0.02))  # the measured pelvis fell 2 cm short of the second action
    assert short["step_length_errors_m"] == [0.0, -0.02, 0.0] and not short["success"]


def test_every_drawer_report_field_from_a_logged_run():
    """Each figure of the drawer report from logged arrays of a known answer, with its rounding:
    the grasp from the first tick the fingers touch the handle (a reading of 0.5 is not a touch),
    the hand at the handle then, not its closest; the last tick's opening, distance, hand and object;
    the handle's slip while held; the unintended contacts counted as they begin, their time and peak;
    the ankles' peaks each over their own limit; success at the opening's (95 % of the clearance) and
    the object's thresholds exactly."""
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
    log["grip_force_n"][1500] = 61.2345
    log["handle_slip_m"][[100, 1500]] = [0.5, 0.0123456]  # the first before the grasp: not a slip
    log["object_lift_m"][-2:], log["object_held"][-2:] = [0.2, 0.0567891], [0.0, 1.0]
    log["unintended_contacts"][[10, 11, 12, 20, 1999]] = [1, 3, 1, 2, 1]  # three touches, five ticks
    log["unintended_force_n"][[10, 11, 12, 20, 1999]] = [5.0, 40.56, 7.0, 3.0, 1.0]
    report = drawer_outcome(log, [1.0, 3.0, 5.0, 10.5], [0.4, 0.2, 0.0], lambda xy: float(np.hypot(*xy)),
                            fell=False, required_opening=0.14, comfort=0.64731, ankle_limit=np.array([160.0, 100.0]),
                            travel=0.35)
    grasp = int(np.argmax(log["t"] > 6.0123))
    assert report == {
        "success": True, "planned_step_lengths_m": [0.4, 0.2, 0.0], "realized_step_lengths_m": [0.4, 0.2, -0.00123],
        "step_length_errors_m": [0.0, 0.0, -0.00123], "step_length_error_max_m": 0.00123, "comfort_distance_m": 0.6473,
        "final_pelvis_to_drawer_m": 0.6473, "drawer_opening_m": 0.1812, "drawer_opening_required_m": 0.14,
        "drawer_opening_share": 1.295, "drawer_travel_share": 0.518,
        "drawer_pull_force_peak_n": 31.23, "grip_force_peak_n": 61.23, "handle_slip_max_m": 0.0123,
        "object_lift_m": 0.0568, "object_held": True, "unintended_contacts": 3, "unintended_contact_s": 0.025,
        "unintended_force_peak_n": 40.6, "grasp": "contact", "grasp_time_s": 6.015,
        "hand_to_handle_m": round(float(log["left_hand_to_handle_m"][grasp]), 4), "hand_to_object_m": 0.0123,
        "peak_ankle_pitch_torque_ratio": {"left": 0.2508, "right": 0.805}}
    assert str(report["step_length_errors_m"][1]) == "0.0" and report["hand_to_handle_m"] == 0.0056
    assert log["t"][grasp] == pytest.approx(6.0151234)  # reported to the millisecond
    log["drawer_opening_m"][-1], log["right_hand_to_object_m"][-1] = 0.95 * 0.14, 0.02  # both at their thresholds
    assert outcome(log)["success"]
    log["grasped"][:] = 0.5
    ungrasped = outcome(log)
    assert ungrasped["grasp"] == "none" and ungrasped["grasp_time_s"] is None and ungrasped["hand_to_handle_m"] == 0.001
    no_actions = drawer_outcome(log, [1.0], [], lambda xy: float(xy[0]), fell=False, required_opening=0.14,
                                comfort=0.647, ankle_limit=np.array([160.0, 160.0]), travel=0.35)
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
    servos after the walk-in. With enough sources, at a training sequence, the playback walks the
    robot to the drawer, and the learned left hand, with no hand task and no grasp logic, hooks the
    handle and pulls the drawer open by contact, as the training run did (its right hand misses the
    object, and at other training sequences it falls: docs/evaluation.md)."""
    status = main(["drawer", "--method", "naive", "--sources", "8+8", "--distance", "1.40", "--slot", "back_right",
                   "--speed", "middle", "--quiet", "--out", str(tmp_path)])
    report = json.loads((tmp_path / "report.json").read_text())
    assert status == 0 and report["method"] == "naive" and report["sources"] == "8+8" and not report["fell"]
    assert report["actions"] == [1, 2, 3]
    assert max(abs(e) for e in report["step_length_errors_m"][:2]) < 0.03
    assert abs(report["final_pelvis_to_drawer_m"] - report["comfort_distance_m"]) < 0.03
    assert report["grasp"] == "contact" and report["drawer_opening_m"] >= 0.95 * report["drawer_opening_required_m"]


def test_the_naive_baseline_without_a_recorded_set_says_how_to_record_one(capsys, tmp_path):
    """G1 ships no set recorded in physics (the naive baseline learns every joint from one): one line
    naming the command that records it, nothing written."""
    out = tmp_path / "out"
    assert main(["drawer", "--robot", "g1_dex3", "--method", "naive", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and not out.exists()
    assert err.endswith("generate them with: robot-ctrl synth-demos --robot g1_dex3 --from-physics --out "
                        f"{ROOT / 'models' / 'g1_dex3_walk_reach_feasible.npz'}")
