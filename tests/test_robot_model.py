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
    assert talos.mjcf_path.is_file()
    monkeypatch.setenv("ROBOT_CTRL_CACHE", str(tmp_path))
    fresh = load_robot("talos")
    assert fresh.mjcf_path.parent == tmp_path
    assert fresh.mjcf_path.name == talos.mjcf_path.name  # same inputs, same key
    assert not list(tmp_path.glob("*.tmp"))


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


def test_servo_damping_follows_the_damping_ratio(talos):
    data = talos.pin.createData()
    mass_diag = np.diag(pin.crba(talos.pin, data, talos.q_half_sitting))[talos.v_index]
    zeta = talos.kd / (2.0 * np.sqrt(talos.kp * mass_diag))
    np.testing.assert_allclose(zeta, 1.0)
    # 1e-5 kg·m² rotor × gear 100², from the SRDF; the grippers have no rotor parameters there.
    grippers = [i for i, n in enumerate(talos.joint_names) if n.startswith("gripper")]
    np.testing.assert_allclose(np.delete(talos.armature, grippers), 0.1)
    np.testing.assert_allclose(talos.armature[grippers], 0.0)
