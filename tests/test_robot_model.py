"""Robot layer: Talos and G1 in Pinocchio and in the converted MuJoCo scene agree; config errors are clear."""

import dataclasses

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import yaml

from robot_ctrl.cli import main
from robot_ctrl.modes import FilterMode
from robot_ctrl.robot import ConfigError, load_robot, load_robot_config
from robot_ctrl.robot.config_file import CONFIG_DIR, parse_robot_config
from robot_ctrl.robot.description import read_srdf
from robot_ctrl.robot.joint_map import MujocoJointMap, mujoco_to_pin_q, pin_to_mujoco_qpos
from robot_ctrl.robot.mjcf import robot_spec
from robot_ctrl.robot.self_collision import compute_exclusions
from robot_ctrl.wpg.params import WalkParams


@pytest.fixture(scope="module")
def mj(talos):
    m = mujoco.MjModel.from_xml_path(str(talos.mjcf_path))
    return m, mujoco.MjData(m), MujocoJointMap.build(m, talos.joint_names, "talos/", "base_link")


def random_configuration(robot, rng):
    q = pin.randomConfiguration(robot.pin, np.r_[-np.ones(3), -np.ones(4), robot.pin.lowerPositionLimit[7:]],
                                np.r_[np.ones(3), np.ones(4), robot.pin.upperPositionLimit[7:]])
    return q


def test_mass_is_equal(talos, mj):
    m, _, _ = mj
    assert talos.mass == pytest.approx(90.27, abs=0.01)
    # The saved MJCF writes 6 significant digits (torso 17.55011 -> 17.5501 kg): equal to 1e-6.
    assert m.body_subtreemass[0] == pytest.approx(talos.mass, rel=1e-6)


@pytest.mark.parametrize("name", ["talos", "g1"])
def test_com_and_soles_agree_over_random_configurations(name):
    """G1's soles are frames its config adds to the ankle links: Pinocchio and MuJoCo place them alike."""
    robot = load_robot(name)
    m = mujoco.MjModel.from_xml_path(str(robot.mjcf_path))
    d = mujoco.MjData(m)
    prefix = f"{name}/"
    jmap = MujocoJointMap.build(m, robot.joint_names, prefix, robot.config.base_link)
    data = robot.pin.createData()
    rng = np.random.default_rng(0)
    np.random.seed(0)  # pinocchio.randomConfiguration draws from numpy's global generator
    for _ in range(20):
        q = random_configuration(robot, rng)
        pin_to_mujoco_qpos(q, robot.q_index, jmap, d.qpos)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        com_pin = pin.centerOfMass(robot.pin, data, q)
        root = m.body(prefix + robot.config.base_link).id
        assert np.linalg.norm(d.subtree_com[root] - com_pin) < 1e-3
        pin.framesForwardKinematics(robot.pin, data, q)
        for side, frame in robot.config.feet.items():
            sole_mj = m.body(prefix + frame).id
            sole_pin = data.oMf[robot.frame_ids[f"{side}_foot"]]
            assert np.linalg.norm(d.xpos[sole_mj] - sole_pin.translation) < 1e-3
            assert np.allclose(d.xmat[sole_mj].reshape(3, 3), sole_pin.rotation, atol=1e-5)
        assert np.allclose(mujoco_to_pin_q(d.qpos, robot.q_index, jmap, robot.pin.nq), q)


def test_a_sole_box_replaces_the_urdf_feet_and_stands_flat_on_the_floor():
    """G1's URDF feet are four 5 mm spheres: the conversion puts one massless box of the config's sole
    rectangle in their place on the ankle link, its bottom face on the sole frame."""
    g1 = load_robot("g1")
    m = mujoco.MjModel.from_xml_path(str(g1.mjcf_path))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    foot = g1.config.foot
    for side, frame in g1.config.feet.items():
        sole = m.body(f"g1/{frame}").id
        ankle = m.body_parentid[sole]
        assert m.body(ankle).name == f"g1/{side}_ankle_roll_link"
        (box,) = np.flatnonzero(m.geom_bodyid == ankle)  # the spheres are gone
        assert m.geom_type[box] == mujoco.mjtGeom.mjGEOM_BOX and not np.any(m.geom_bodyid == sole)
        np.testing.assert_allclose(m.geom_size[box], [foot.length / 2, foot.width / 2, foot.box_height / 2])
        # In the sole frame: centred on the sole rectangle, its bottom face on the frame's origin.
        local = d.xmat[sole].reshape(3, 3).T @ (d.geom_xpos[box] - d.xpos[sole])
        np.testing.assert_allclose(local, [*foot.center_offset, foot.box_height / 2], atol=1e-9)
        np.testing.assert_allclose(d.geom_xmat[box], d.xmat[sole], atol=1e-9)
    assert m.body_subtreemass[m.body("g1/pelvis").id] == pytest.approx(g1.mass, rel=1e-6)


def test_self_collision_exclusions_are_computed_as_moveit_does():
    """No SRDF: adjacent links, links touching at the default posture and pairs never in collision
    over random configurations go unchecked; pairs that can touch (the two feet, a hand and a knee) stay
    checked; the same seed gives the same pairs."""
    g1 = load_robot("g1")
    spec = robot_spec(g1.config, g1.files, g1.kp, g1.kd, g1.effort, g1.armature)
    posture = dict(zip(g1.joint_names, g1.config.half_sitting))
    found = compute_exclusions(spec, posture, samples=2000)
    assert ("left_hip_roll_link", "left_hip_yaw_link") in found.adjacent
    assert ("left_ankle_pitch_link", "left_ankle_roll_link") in found.adjacent
    assert ("left_hip_pitch_link", "pelvis_contour_link") in found.adjacent  # siblings under the bare pelvis
    assert not found.default and not found.always
    unchecked = set(found.pairs)
    for pair in (("left_ankle_roll_link", "right_ankle_roll_link"), ("left_knee_link", "left_wrist_yaw_link"),
                 ("left_knee_link", "right_knee_link")):
        assert pair not in unchecked
    assert ("head_link", "left_hip_pitch_link") in found.never
    assert compute_exclusions(spec, posture, samples=2000) == found
    # Legs crossed at the default posture: the knees touch there, so they are never checked.
    crossed = compute_exclusions(spec, posture | {"left_hip_roll_joint": -0.4, "right_hip_roll_joint": 0.4},
                                 samples=500)
    assert ("left_knee_link", "right_knee_link") in crossed.default
    # The converted scene carries them as MuJoCo exclusions.
    m = mujoco.MjModel.from_xml_path(str(g1.mjcf_path))
    excluded = {tuple(sorted((m.body(int(s >> 16)).name, m.body(int(s & 0xFFFF)).name))) for s in m.exclude_signature}
    assert ("g1/head_link", "g1/left_hip_pitch_link") in excluded
    assert ("g1/left_ankle_roll_link", "g1/right_ankle_roll_link") not in excluded


def test_mjcf_has_servos_exclusions_and_integrator(talos, mj):
    m, _, jmap = mj
    assert m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert m.opt.timestep == pytest.approx(0.001)
    assert m.nu == talos.nj == 32
    assert m.jnt_type[m.joint("talos/root").id] == mujoco.mjtJoint.mjJNT_FREE
    np.testing.assert_allclose(m.actuator_forcerange[jmap.actuator, 1], talos.effort)
    np.testing.assert_allclose(m.actuator_gainprm[jmap.actuator, 0], 30.0 * talos.effort)
    pairs = read_srdf(talos.files.srdf).disabled_collisions
    assert m.nexclude > 400 and m.nexclude <= len(pairs)
    # Legs 1 and 3 overlap at the zero pose: the SRDF excludes them, and so must the MJCF.
    excluded = {frozenset((m.body(a).name, m.body(b).name)) for a, b in zip(m.exclude_signature >> 16,
                                                                            m.exclude_signature & 0xFFFF)}
    assert frozenset(("talos/leg_left_1_link", "talos/leg_left_3_link")) in excluded


def test_the_gripper_moves_its_fingers_as_the_urdf_couples_them(talos):
    """The reduced URDF fixes Talos's finger joints but keeps their <mimic> tags: in the simulation
    they move with the gripper joint (q = multiplier × q_gripper), so the gripper servo alone closes
    the fingers, and the linkage links the config names collide with nothing."""
    m = mujoco.MjModel.from_xml_path(str(talos.mjcf_path))
    m.opt.gravity[:] = 0.0  # the robot floats where it is; the gripper works against its own friction
    d = mujoco.MjData(m)
    gripper = m.actuator("talos/gripper_left_joint").id
    d.ctrl[gripper] = -1.0
    for _ in range(3000):
        mujoco.mj_step(m, d)
    q = d.qpos[m.joint("talos/gripper_left_joint").qposadr[0]]
    assert q < -0.9  # closed, within its 1 N·m
    for name, multiplier in (("inner_double", 1.0), ("fingertip_1", -1.0), ("inner_single", -1.0),
                             ("fingertip_3", -1.0)):
        assert d.qpos[m.joint(f"talos/gripper_left_{name}_joint").qposadr[0]] == pytest.approx(multiplier * q, abs=2e-3)
    assert m.nu == talos.nj  # the fingers have no servo of their own
    for link in talos.config.links_without_collision:
        body = m.body(f"talos/{link}").id
        geoms = m.geom_bodyid == body
        assert (m.geom_contype[geoms] == 0).all() and (m.geom_conaffinity[geoms] == 0).all()
    tip = m.body("talos/gripper_left_fingertip_1_link").id
    assert (m.geom_contype[m.geom_bodyid == tip] == 1).all()


def test_mjcf_is_cached_and_converted_again_in_a_new_cache(talos, tmp_path, monkeypatch):
    from robot_ctrl.robot import mjcf

    monkeypatch.setenv("ROBOT_CTRL_CACHE", str(tmp_path))
    fresh = load_robot("talos")
    path = fresh.mjcf_path
    assert path.parent == tmp_path and not list(tmp_path.glob("*.tmp"))
    assert path.read_bytes() == talos.mjcf_path.read_bytes()  # same inputs: the same scene, converted again
    # Reused: a second load converts nothing and leaves the file as it was.
    stamp = path.stat().st_mtime_ns
    with monkeypatch.context() as m:
        m.setattr(mjcf, "scene_spec", lambda *a, **k: pytest.fail("the cached scene was converted again"))
        assert load_robot("talos").mjcf_path == path and path.stat().st_mtime_ns == stamp
    # Another input (stiffer servos) is another scene, which carries it.
    stiff = mjcf.cached_scene_mjcf(talos.config, talos.files, 2 * talos.kp, talos.kd, talos.effort, talos.armature)
    assert stiff != path
    gains = [mujoco.MjModel.from_xml_path(str(p)).actuator_gainprm[:, 0] for p in (path, stiff)]
    np.testing.assert_allclose(gains[1], 2 * gains[0])
    np.testing.assert_allclose(gains[0], talos.kp)


def test_unknown_robot_lists_available():
    with pytest.raises(ConfigError, match=r"unknown robot 'asimo'.*available robots: .*talos"):
        load_robot_config("asimo")


def test_missing_frame_lists_existing_frames():
    config = load_robot_config("talos")
    bad = dataclasses.replace(config, feet={"left": "left_toe", "right": "right_sole_link"})
    with pytest.raises(ConfigError, match=r"frame 'left_toe' \(left_foot\) not in the URDF; body frames: .*left_sole_link"):
        load_robot(bad)


def test_missing_joint_lists_urdf_joints():
    raw = yaml.safe_load((CONFIG_DIR / "talos.yaml").read_text())
    raw["half_sitting"]["knee_joint"] = 0.3
    with pytest.raises(ConfigError, match=r"not in the URDF: \['knee_joint'\].*leg_left_4_joint"):
        load_robot(parse_robot_config(raw))


@pytest.mark.parametrize("path,value,message", [
    (("servo", "kp_per_effort"), -1.0, r"servo: field 'kp_per_effort' = -1.0 is outside the allowed range \[0.1, 1000"),
    (("simulation", "timestep"), 0.5, r"field 'timestep' = 0.5 is outside the allowed range"),
    (("foot", "width"), "wide", r"field 'width' must be"),
    (("half_sitting", "leg_left_4_joint"), float("nan"), r"half_sitting.leg_left_4_joint"),
    (("grasp", "hand_rpy"), [0.0, 4.0, 0.0], r"grasp.hand_rpy must be \[roll, pitch, yaw\], each in \[-pi, pi\] rad"),
    (("grasp", "hook"), "yes", r"grasp.hook must be true or false"),
    (("simulation", "links_without_collision"), "gripper_left_inner_double_link",
     r"simulation.links_without_collision must be a list of link names"),
    (("drawer", "handle_grip"), [0.1, 0.2, 0.3], r"drawer.handle_grip and drawer.bar_from_grip go together"),
])
def test_out_of_range_fields_are_named(path, value, message):
    raw = yaml.safe_load((CONFIG_DIR / "talos.yaml").read_text())
    raw.setdefault(path[0], {})[path[1]] = value
    with pytest.raises(ConfigError, match=message):
        parse_robot_config(raw)


@pytest.mark.parametrize("path,value,message", [
    (("walking",), {"step_height": 0.1},
     r"walking.step_height is not a walking parameter a config sets \(allowed: .*swing_apex"),
    (("walking",), {"com_height": 0.6}, r"walking.com_height .*come from the robot itself"),
    (("walking",), {"speed": 2.0}, r"walking: field 'speed' = 2.0 is outside the allowed range \[0.02, 0.5\]"),
    (("added_frames",), {"toe": {"parent": "left_ankle_roll_link", "xyz": [0, 0]}},
     r"added_frames.toe.xyz must be three"),
    (("added_frames",), {"toe": {"parent": "left_toe_link"}}, r"added_frames.toe.parent 'left_toe_link' is not a link"),
    (("servo", "armature"), {"knee": 0.01}, r"servo.armature names joints not in half_sitting: \['knee'\]"),
    (("foot", "box_height"), 0.5, r"field 'box_height' = 0.5 is outside the allowed range"),
    (("joints", "grippers"), {"left": "left_elbow_joint"},
     r"joints.grippers must have exactly the keys 'left' and 'right'"),
    (("stabilizer",), [6.0], r"stabilizer must map stabilizer gains to values"),
])
def test_g1_config_errors_are_named(path, value, message):
    """What a config for a robot unlike Talos adds (sole frames, a sole box, its own walking
    parameters, per-joint rotor inertias) is checked, and each error names its field."""
    raw = yaml.safe_load((CONFIG_DIR / "g1.yaml").read_text())
    if len(path) == 1:
        raw[path[0]] = value
    else:
        raw[path[0]][path[1]] = value
    with pytest.raises((ConfigError, ValueError), match=message):
        config = parse_robot_config(raw)
        WalkParams.of_robot(config.walking)
        load_robot(config)


@pytest.mark.parametrize("command", [["drawer", "--distance", "2"], ["campaign", "--n", "1"], ["synth-demos"],
                                     ["synth", "--distance", "1.5"]])
def test_g1_without_grippers_is_refused_the_walk_and_reach_task_in_one_line(command, capsys, tmp_path):
    out = tmp_path / "out"
    where = ["--out", str(out)] if command[0] == "campaign" else []
    assert main([command[0], "--robot", "g1", *command[1:], *where]) == 2
    assert capsys.readouterr().err.strip().endswith(
        f"{command[0]}: robot g1 names no joints.grippers, joints.shoulders, joints.wrists in its config: the "
        "walk-and-reach task needs a gripper that closes round the drawer's handle")
    assert not out.exists()


def test_a_variant_config_states_only_what_differs_from_the_robot_it_extends():
    """g1_dex3 is g1 with hands: the base's fields hold unless stated again, mappings merge key by key
    (the fingers' rotor inertias join the body's), the hands' joints join the joint order."""
    g1, dex3 = load_robot_config("g1"), load_robot_config("g1_dex3")
    assert dex3.name == "g1_dex3" and dex3.urdf == "urdf/g1_29dof_with_hand_rev_1_0.urdf" and dex3.srdf is None
    assert dex3.joint_names[:29] == g1.joint_names and len(dex3.joint_names) == 43
    assert dex3.half_sitting[:29] == g1.half_sitting
    assert dex3.servo.armature == g1.servo.armature | {n: 0.001 for n in dex3.joint_names[29:]}
    assert (dex3.walking, dex3.stabilizer, dex3.walking_speed, dex3.foot) == \
        (g1.walking, g1.stabilizer, g1.walking_speed, g1.foot)
    assert dex3.hands == {"left": "left_hand_palm_link", "right": "right_hand_palm_link"}
    assert dex3.joint_roles["elbows"] == g1.joint_roles["elbows"] and "grippers" in dex3.joint_roles
    assert dex3.grippers.closing_sign("left") == -1.0 and dex3.grippers.closing_sign("right") == 1.0
    assert g1.grippers.closing_sign("left") == 1.0  # a config without grasp: closes at the upper limit
    assert load_robot("g1_dex3").pin.nq == load_robot("g1").pin.nq + 14
    assert (g1.drawer_dynfilter, dex3.drawer_dynfilter) == (FilterMode.FULL, FilterMode.OFF)


def test_an_unquoted_off_in_a_config_is_the_filter_mode_off(tmp_path):
    path = tmp_path / "g1_off.yaml"
    path.write_text("extends: g1_dex3\ndrawer: {dynfilter: off}\n")  # YAML 1.1 reads it as false
    config = load_robot_config(path)
    assert config.drawer_dynfilter is FilterMode.OFF and config.drawer_scale == 0.7


@pytest.mark.parametrize("text,message", [
    ("extends: asimo\nname: x\n", "extends 'asimo': no such config; available robots: g1, g1_dex3, talos"),
    ("extends: [g1]\n", "field 'extends' must be a robot name or a YAML path"),
    ("extends: self.yaml\nname: x\n", "extends 'self.yaml': a cycle"),
    ("extends: g1\ngrasp: {closes_toward: {left: lower}, opening: 1.0}\n",
     "grasp.closes_toward must map left and right to upper or lower"),
    ("extends: g1\ngrasp: {closes_toward: {left: lower, right: upper}, opening: 9}\n",
     "grasp: field 'opening' = 9 is outside the allowed range [0.05, 3.0]"),
    ("extends: g1\ndrawer: {scale: 0.1}\n", "drawer: field 'scale' = 0.1 is outside the allowed range [0.3, 2.0]"),
    ("extends: g1\ndrawer: {scal: 0.7}\n", "drawer.scal is not a field of drawer (scale, dynfilter, handle_grip, bar_from_grip)"),
    ("extends: g1\ndrawer: {dynfilter: half}\n", "drawer.dynfilter 'half' is not one of off, legs, full"),
    ("extends: g1\nlimits: {ik_ranges: {left_knee_joint: [0.0, 0.5]}}\n",
     "limits.ik_ranges.left_knee_joint must be [lower, upper] rad around its half_sitting angle 0.75"),
])
def test_a_bad_variant_config_is_named(text, message, tmp_path):
    path = tmp_path / "self.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as caught:
        load_robot_config(path)
    assert message in str(caught.value) and "\n" not in str(caught.value)


@pytest.mark.parametrize("section,value,message", [
    ("stabilizer", {"lateral_dcm_rate": -1}, "stabilizer.lateral_dcm_rate = -1 must be a number in (0, 100.0]"),
    ("walking", {"step_height": 0.1}, "walking.step_height is not a walking parameter a config sets"),
])
def test_a_bad_gain_in_a_robot_config_is_one_line_before_anything_runs(section, value, message, capsys, tmp_path):
    raw = yaml.safe_load((CONFIG_DIR / "g1.yaml").read_text())
    raw[section] = value
    path = tmp_path / "g1.yaml"
    path.write_text(yaml.safe_dump(raw))
    out = tmp_path / "out"
    assert main(["balance", "--robot", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err and "--robot g1" in err
    assert not out.exists()


def test_half_sitting_outside_urdf_limits_is_rejected():
    raw = yaml.safe_load((CONFIG_DIR / "talos.yaml").read_text())
    raw["half_sitting"]["leg_left_4_joint"] = -0.5  # knee limit is [0, 2.618]
    with pytest.raises(ConfigError, match=r"outside the URDF limits: \[\('leg_left_4_joint', -0.5\)\]"):
        load_robot(parse_robot_config(raw))


def test_servo_damping_ratio_shows_in_the_simulated_step_response(talos):
    """The scene's servos have the configured closed-loop damping ratio: with the base fixed, no
    gravity and no contacts, the other joints held by their servos at half-sitting, a 0.02 rad step
    of the hip yaw's target (a joint without URDF friction, whose motion barely couples into the
    others) is fitted by the second-order step response of damping ratio ζ and natural frequency ω;
    ζ is the config's damping ratio and ω² the joint's stiffness over its inertia (rotor included),
    each within 10 %. A 0.2 ms step measures the servo rather than the integrator."""
    spec = mujoco.MjSpec.from_file(str(talos.mjcf_path))
    spec.delete(spec.joint("talos/root"))
    spec.option.gravity = [0.0, 0.0, 0.0]
    spec.option.timestep = 2e-4
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    m = spec.compile()
    d = mujoco.MjData(m)
    name, step = "leg_left_1_joint", 0.02
    for n, angle in zip(talos.joint_names, talos.config.half_sitting):
        d.qpos[m.joint(f"talos/{n}").qposadr[0]] = angle
        d.ctrl[m.actuator(f"talos/{n}").id] = angle + (step if n == name else 0.0)
    i, adr = talos.joint_names.index(name), m.joint(f"talos/{name}").qposadr[0]
    t = np.arange(1, 1501) * m.opt.timestep  # 0.3 s
    response = []
    for _ in t:
        mujoco.mj_step(m, d)
        response.append((d.qpos[adr] - talos.config.half_sitting[i]) / step)
    zeta, omega = _fit_second_order(t, np.array(response))
    inertia = np.diag(pin.crba(talos.pin, talos.pin.createData(), talos.q_half_sitting))[talos.v_index][i]
    assert zeta == pytest.approx(talos.config.servo.damping_ratio, rel=0.1)
    assert omega == pytest.approx(np.sqrt(talos.kp[i] / inertia), rel=0.1)


def _fit_second_order(t, x):
    """Least-squares (ζ, ω) of the unit step response x(t) of ẍ + 2ζω ẋ + ω² x = ω²."""
    from scipy.optimize import least_squares
    from scipy.signal import lti, step

    def residual(params):
        zeta, omega = params
        return step(lti([omega**2], [1.0, 2 * zeta * omega, omega**2]), T=t)[1] - x

    return least_squares(residual, [0.5, 50.0], bounds=([0.05, 1.0], [5.0, 1000.0])).x


def test_srdf_rotor_inertia_is_the_armature(talos):
    # 1e-5 kg·m² rotor × gear 100², from the SRDF; the grippers have no rotor parameters there.
    grippers = [i for i, n in enumerate(talos.joint_names) if n.startswith("gripper")]
    np.testing.assert_allclose(np.delete(talos.armature, grippers), 0.1)
    np.testing.assert_allclose(talos.armature[grippers], 0.0)
