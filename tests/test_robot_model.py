"""Robot layer: Talos in Pinocchio and in the converted MuJoCo scene agree; config errors are clear."""

import dataclasses

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import yaml

from robot_ctrl.robot import ConfigError, load_robot, load_robot_config
from robot_ctrl.robot.config import CONFIG_DIR, parse_robot_config
from robot_ctrl.robot.description import read_srdf
from robot_ctrl.robot.joint_map import MujocoJointMap, mujoco_to_pin_q, pin_to_mujoco_qpos


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


def test_com_and_soles_agree_over_random_configurations(talos, mj):
    m, d, jmap = mj
    data = talos.pin.createData()
    rng = np.random.default_rng(0)
    np.random.seed(0)  # pinocchio.randomConfiguration draws from numpy's global generator
    for _ in range(20):
        q = random_configuration(talos, rng)
        pin_to_mujoco_qpos(q, talos.q_index, jmap, d.qpos)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        com_pin = pin.centerOfMass(talos.pin, data, q)
        root = m.body("talos/base_link").id
        assert np.linalg.norm(d.subtree_com[root] - com_pin) < 1e-3
        pin.framesForwardKinematics(talos.pin, data, q)
        for side, frame in talos.config.feet.items():
            sole_mj = d.xpos[m.body(f"talos/{frame}").id]
            sole_pin = data.oMf[talos.frame_ids[f"{side}_foot"]].translation
            assert np.linalg.norm(sole_mj - sole_pin) < 1e-3
        assert np.allclose(mujoco_to_pin_q(d.qpos, talos.q_index, jmap, talos.pin.nq), q)


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
])
def test_out_of_range_fields_are_named(path, value, message):
    raw = yaml.safe_load((CONFIG_DIR / "talos.yaml").read_text())
    raw[path[0]][path[1]] = value
    with pytest.raises(ConfigError, match=message):
        parse_robot_config(raw)


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
