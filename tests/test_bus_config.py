"""Bus configs (``configs/hw/*.yaml``): each value a user can get wrong is refused with one line
naming the key and what it must be, the values at the ends of each allowed range are taken, and
what is taken is what the drivers get. No bus is opened: a config is only read."""

from __future__ import annotations

import copy

import pytest
import yaml

from robot_ctrl.buses.bus_config import HW_CONFIGS, load_bus_config, shipped_bus_configs
from robot_ctrl.robot.config import ConfigError

LEG = "leg_left_1_joint"
DAMIAO = {"position": [-12.5, 12.5], "velocity": [-20.0, 20.0], "kp": [0.0, 500.0], "kd": [0.0, 5.0],
          "torque": [-10.0, 10.0], "reply": "damiao"}


def shipped(name: str) -> dict:
    return yaml.safe_load((HW_CONFIGS / f"{name}.yaml").read_text())


def load(tmp_path, talos, data: dict):
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return load_bus_config(path, talos.joint_names)


def edited(data: dict, edit) -> dict:
    data = copy.deepcopy(data)
    edit(data)
    return data


def set_key(*keys, value):
    def edit(data):
        node = data
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value
    return edit


def drop_key(*keys):
    def edit(data):
        node = data
        for key in keys[:-1]:
            node = node[key]
        del node[keys[-1]]
    return edit


def both(*edits):
    def edit(data):
        for e in edits:
            e(data)
    return edit


COMMON = [  # (edit, the refusal's text; None: taken)
    (set_key("reply_timeout_s", value=1e-4), None), (set_key("reply_timeout_s", value=1.0), None),
    (set_key("reply_timeout_s", value=0.9e-4), "reply_timeout_s = 9e-05 is outside the allowed range [0.0001, 1] s"),
    (set_key("reply_timeout_s", value=1.01), "reply_timeout_s = 1.01 is outside the allowed range"),
    (set_key("reply_timeout_s", value="fast"), "reply_timeout_s = 'fast' is outside the allowed range"),
    (set_key("max_missed_replies", value=0), None), (set_key("max_missed_replies", value=1000), None),
    (set_key("max_missed_replies", value=-1), "max_missed_replies = -1 is outside the allowed range [0, 1000]"),
    (set_key("max_missed_replies", value=1001), "max_missed_replies = 1001 is outside"),
    (set_key("max_missed_replies", value=1.5), "max_missed_replies = 1.5 is outside"),
    (set_key("max_missed_replies", value=True), "max_missed_replies = True is outside"),
    (set_key("reply_timeout_s", value=True), "reply_timeout_s = True is outside"),
    (set_key("drive_timeout_s", value=float("nan")), "drive_timeout_s = nan is outside"),
    (set_key("drive_timeout_s", value=0.001), None), (set_key("drive_timeout_s", value=10.0), None),
    (set_key("drive_timeout_s", value=0.0009), "drive_timeout_s = 0.0009 is outside the allowed range [0.001, 10] s"),
    (set_key("drive_timeout_s", value=10.5), "drive_timeout_s = 10.5 is outside"),
    (set_key("drive_timeout_s", value=[1]), "drive_timeout_s = [1] is outside"),
    (set_key("body_sensors", value="my_robot.sensors:open_sensors"), None),
    (set_key("body_sensors", value="MyRobot.IMU_v2:Open"), None),
    (set_key("body_sensors", value="open_sensors"), "body_sensors = 'open_sensors' must be module:function"),
    (set_key("without_drive_timeout", value={"why": "bench test only", "joints": [LEG]}), None),
    *((set_key("without_drive_timeout", value=v), "without_drive_timeout must give why (in a few words)")
      for v in ("bench test only", {"why": "bench only", "joints": [LEG]}, {"why": "bench test only"},
                {"why": "bench test only", "joints": LEG}, {"why": "bench test only", "joints": [LEG], "all": True})),
    (set_key("without_drive_timeout", value={"why": "bench test only", "joints": ["tail_joint"]}),
     "without_drive_timeout.joints are not in the robot: ['tail_joint']"),
    (set_key("joints", value="all"), "joints must map joint names to motors"),
    (drop_key("joints", LEG), f"joints missing from the mapping: ['{LEG}']"),
    (set_key("joints", "tail_joint", value={"id": 99}), "joints not in the robot: ['tail_joint']"),
    (set_key("joints", LEG, value=3), f"joints.{LEG} must be a mapping"),
    (set_key("joints", LEG, "model", value="servo9"), f"joints.{LEG}.model 'servo9' is not one of"),
    (set_key("joints", LEG, "direction", value=-1), None),
    (set_key("joints", LEG, "direction", value=0), f"joints.{LEG}.direction must be 1 or -1"),
    (set_key("joints", LEG, "zero_offset", value=float("nan")), f"joints.{LEG}.zero_offset must be a finite number [rad]"),
    (set_key("joints", LEG, "zero_offset", value="0"), f"joints.{LEG}.zero_offset must be a finite number [rad]"),
    (set_key("joints", LEG, "gear_ratio", value=0.0), f"joints.{LEG}.gear_ratio must be a number in [0.1, 1000]"),
    (set_key("joints", LEG, "gear_ratio", value="9"), f"joints.{LEG}.gear_ratio must be a number in [0.1, 1000]"),
    (set_key("joints", LEG, "id", value=0), f"joints.{LEG}.id must be an integer in [1, "),
    (set_key("joints", LEG, "id", value=1.0), f"joints.{LEG}.id must be an integer in [1, "),
    (set_key("joints", LEG, "id", value=True), f"joints.{LEG}.id must be an integer in [1, "),
    (set_key("joints", LEG, "direction", value=True), f"joints.{LEG}.direction must be 1 or -1"),
    (set_key("joints", LEG, "gear_ratio", value=0.1), None), (set_key("joints", LEG, "gear_ratio", value=1000), None),
    *((set_key("joints", LEG, "gear_ratio", value=v), f"joints.{LEG}.gear_ratio must be a number in [0.1, 1000]")
      for v in (float("inf"), 1e-6, 1001.0, True)),
]

MIT_CAN = [
    (set_key("backend", value="ethercat"), "backend must be one of ('mit_can', 'dynamixel'), got 'ethercat'"),
    (set_key("models", value={}), "models must map model names to their ranges"),
    (set_key("buses", value={}), "buses must map bus names to python-can options"),
    (drop_key("buses", "can2", "channel"), "buses.can2 needs interface and channel"),
    (drop_key("buses", "can2", "interface"), "buses.can2 needs interface and channel"),
    (set_key("models", "leg", "kp", value=[0.0, 0.0]), "models.leg.kp must be [low, high], finite numbers with low < high"),
    (set_key("models", "leg", "torque", value=[-1.0, "x"]), "models.leg.torque must be [low, high], finite numbers with low < high"),
    (set_key("models", "leg", "position", value=[-1.0]), "models.leg.position must be [low, high], finite numbers with low < high"),
    (set_key("models", "leg", "position", value=[float("-inf"), float("inf")]),
     "models.leg.position must be [low, high], finite numbers with low < high"),
    (set_key("models", "leg", "velocity", value="fast"), "models.leg.velocity must be [low, high], finite numbers with low < high"),
    (set_key("models", "leg", value="big"), "models.leg.position must be [low, high], finite numbers with low < high"),
    (set_key("models", "leg", "reply", value="mit8"), "models.leg.reply must be one of mit6, cubemars, damiao"),
    (set_key("joints", LEG, "id", value=127), None),
    (set_key("joints", LEG, "id", value=128), f"joints.{LEG}.id must be an integer in [1, 127]"),
    (set_key("joints", LEG, "id", value=2), "joints.leg_left_2_joint: id 2 is used twice on bus can0"),
    (set_key("joints", LEG, "bus", value="can9"), f"joints.{LEG}.bus 'can9' is not one of ['can0', 'can1', 'can2', "),
    (both(set_key("models", "damiao", value=DAMIAO), set_key("joints", "leg_left_2_joint", "model", value="damiao")),
     "joints.leg_left_2_joint: bus can0 mixes reply formats (leg_left_1_joint is mit6, leg_left_2_joint is damiao)"),
    (both(set_key("models", "damiao", value=DAMIAO),
          set_key("buses", "can4", value={"interface": "virtual", "channel": "robot_ctrl_test_can4"}),
          *(set_key("joints", j, value={"bus": "can4", "id": 15 + k, "model": "damiao"})
            for k, j in enumerate(("head_1_joint", "head_2_joint")))),
     "joints.head_2_joint.id must be in [1, 15] for a Damiao drive"),
]

REGISTERS = (("shutdown", 0, 255), ("temperature_limit_c", 0, 100), ("pwm_limit", 0, 885))
DYNAMIXEL = [
    (set_key("port", "baudrate", value=57600), None),
    (drop_key("port", "baudrate"), "port needs device and baudrate"),
    (set_key("ports", value={"a": {"device": "/dev/ttyUSB1", "baudrate": 1000000}}),
     "give either port (one serial port) or ports (name -> port)"),
    (both(drop_key("port"), set_key("ports", value={"a": {"device": "/dev/ttyUSB1"}})),
     "ports.a needs device and baudrate"),
    *((set_key("models", "talos-emulated", key, value=0), f"models.talos-emulated.{key} must be a finite number > 0")
      for key in ("units_per_rev", "velocity_unit", "current_unit", "torque_constant", "kp_unit", "kd_unit")),
    (set_key("models", "talos-emulated", value="x"), "models.talos-emulated.units_per_rev must be a finite number > 0"),
    (drop_key("models", "talos-emulated", "kd_unit"), "models.talos-emulated.kd_unit must be a finite number > 0"),
    (set_key("models", "talos-emulated", "units_per_rev", value=float("inf")),
     "models.talos-emulated.units_per_rev must be a finite number > 0"),
    (set_key("models", "talos-emulated", "fast_sync_read", value="yes"),
     "models.talos-emulated.fast_sync_read must be true or false"),
    *((set_key("models", "talos-emulated", key, value=v), None) for key, lo, hi in REGISTERS for v in (lo, hi)),
    *((set_key("models", "talos-emulated", key, value=v),
       f"models.talos-emulated.{key} = {v!r} must be an integer in [{lo}, {hi}]")
      for key, lo, hi in REGISTERS for v in (lo - 1, hi + 1, float(lo))),
    (set_key("joints", LEG, "id", value=252), None),
    (set_key("joints", LEG, "id", value=253), f"joints.{LEG}.id must be an integer in [1, 252]"),
    (set_key("joints", LEG, "bus", value="port2"), f"joints.{LEG}.bus 'port2' is not one of ['port']"),
]


@pytest.mark.parametrize("base, edit, message", [("talos_mit_can", e, m) for e, m in COMMON + MIT_CAN]
                         + [("talos_dynamixel", e, m) for e, m in COMMON + DYNAMIXEL])
def test_a_bad_value_is_refused_naming_it_and_the_ends_of_each_range_are_taken(tmp_path, talos, base, edit,
                                                                                message):
    data = edited(shipped(base), edit)
    if message is None:
        load(tmp_path, talos, data)
    else:
        with pytest.raises(ConfigError) as refused:
            load(tmp_path, talos, data)
        assert str(refused.value).startswith(f"robot.yaml: {message}")


def test_what_a_config_sets_is_what_the_drivers_get(tmp_path, talos):
    data = edited(shipped("talos_mit_can"), both(
        set_key("reply_timeout_s", value=0.002), set_key("max_missed_replies", value=7),
        set_key("drive_timeout_s", value=0.25), set_key("body_sensors", value="my_robot.sensors:open_sensors"),
        set_key("joints", LEG, value={"bus": "can0", "id": 1, "model": "leg", "direction": -1, "zero_offset": 0.5,
                                      "gear_ratio": 9})))
    config = load(tmp_path, talos, data)
    assert (config.reply_timeout, config.max_missed_replies, config.drive_timeout) == (0.002, 7, 0.25)
    assert config.body_sensors == "my_robot.sensors:open_sensors" and config.backend == "mit_can"
    leg = config.motors[talos.joint_names.index(LEG)]
    assert (leg.bus, leg.id, leg.model, leg.direction, leg.zero_offset, leg.gear_ratio) == \
        ("can0", 1, "leg", -1, 0.5, 9.0)
    assert config.reply_format(leg) == "mit6" and [m.joint for m in config.motors] == list(talos.joint_names)
    waiver = shipped("talos_mit_can")["without_drive_timeout"]
    assert (config.without_drive_timeout.why, config.without_drive_timeout.joints) == (waiver["why"],
                                                                                      tuple(waiver["joints"]))
    unset = both(*(drop_key("joints", LEG, key) for key in ("gear_ratio", "zero_offset", "direction")))
    defaults = load(tmp_path, talos, edited(shipped("talos_dynamixel"), unset))
    leg = defaults.motors[talos.joint_names.index(LEG)]
    assert (leg.gear_ratio, leg.zero_offset, leg.direction, leg.bus) == (1.0, 0.0, 1, "port")
    assert set(defaults.buses) == {"port"} and defaults.without_drive_timeout is None
    assert defaults.reply_timeout == 0.001 and defaults.max_missed_replies == 3 and defaults.drive_timeout == 0.1


def test_a_file_that_is_not_a_bus_config_is_refused_in_one_line(tmp_path, talos):
    path = tmp_path / "robot.yaml"
    for text, message in (("- a\n- list\n", "robot.yaml: the file must be a YAML mapping"),
                          ("backend: [unclosed\n", f"cannot read bus config {path}: while parsing")):
        path.write_text(text)
        with pytest.raises(ConfigError, match="^" + message.replace("[", r"\[")):
            load_bus_config(path, talos.joint_names)
    with pytest.raises(ConfigError, match=r"bus config 'nope' not found; configs/hw has: \['g1_dynamixel', "):
        load_bus_config("nope", talos.joint_names)
    assert shipped_bus_configs() == ("configs/hw/g1_dynamixel.yaml or configs/hw/g1_mit_can.yaml or "
                                     "configs/hw/talos_dynamixel.yaml or configs/hw/talos_mit_can.yaml")
