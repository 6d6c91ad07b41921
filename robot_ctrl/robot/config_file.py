"""Reading a robot's config file (``configs/robots/<name>.yaml``, or a path): ``extends:`` laid
over the config it names, every field checked, the result a
:class:`~robot_ctrl.robot.config.RobotConfig`. A field out of its range is a ``ConfigError`` that
names it and the allowed range.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import yaml

from robot_ctrl import ROOT
from robot_ctrl.modes import FilterMode
from robot_ctrl.robot.config import (
    DEFAULT_GRIPPERS,
    DEFAULT_WALKING_SPEED,
    JOINT_ROLES,
    REACH_ROLES,
    AddedFrame,
    ConfigError,
    FootGeometry,
    GaitSwing,
    Grippers,
    RobotConfig,
    ServoGains,
)

CONFIG_DIR = ROOT / "configs" / "robots"


def available_robots() -> list[str]:
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))


def load_robot_config(name_or_path: str | Path) -> RobotConfig:
    """Load and validate a robot config by robot name (``talos``) or by YAML path."""
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = CONFIG_DIR / f"{name_or_path}.yaml"
        if not path.is_file():
            raise ConfigError(
                f"unknown robot {str(name_or_path)!r}; available robots: {', '.join(available_robots())}"
            )
    return parse_robot_config(_read_extended(path, ()), source=str(path))


def _read_extended(path: Path, seen: tuple[Path, ...]) -> Any:
    """The YAML mapping at ``path``, laid over the robot config its ``extends:`` names (a robot name
    in ``configs/robots``, or a path relative to this file): a variant (the same robot with hands)
    states only what differs. Mappings merge key by key; any other value replaces the base's."""
    try:
        raw = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ConfigError(f"cannot read robot config {path}: {' '.join(str(exc).split())}") from exc
    if not isinstance(raw, Mapping) or "extends" not in raw:
        return raw
    base_name = raw["extends"]
    if not isinstance(base_name, str):
        raise ConfigError(f"{path}: field 'extends' must be a robot name or a YAML path, got {base_name!r}")
    base = Path(base_name)
    base = (path.parent / base) if base.suffix in (".yaml", ".yml") else CONFIG_DIR / f"{base_name}.yaml"
    if not base.is_file() or base.resolve() in seen:
        why = "a cycle" if base.is_file() else "no such config"
        raise ConfigError(f"{path}: extends {base_name!r}: {why}; available robots: {', '.join(available_robots())}")
    merged = _merge(_read_extended(base, seen + (path.resolve(),)), raw)
    merged.pop("extends")
    return merged


def _merge(base: Any, over: Mapping[str, Any]) -> dict:
    if not isinstance(base, Mapping):
        raise ConfigError(f"extends: the base config must be a YAML mapping, got {type(base).__name__}")
    out = dict(base)
    for key, value in over.items():
        out[key] = _merge(base[key], value) if isinstance(value, Mapping) and isinstance(base.get(key), Mapping) \
            else value
    return out


def _field(raw: Mapping[str, Any], key: str, source: str, kind: type | tuple[type, ...] = object) -> Any:
    if not isinstance(raw, Mapping) or key not in raw:
        raise ConfigError(f"{source}: missing field {key!r}")
    value = raw[key]
    if not isinstance(value, kind):
        raise ConfigError(f"{source}: field {key!r} must be {getattr(kind, '__name__', kind)}, got {value!r}")
    return value


def _number(raw: Mapping[str, Any], key: str, source: str, lo: float, hi: float) -> float:
    value = _field(raw, key, source, (int, float))
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"{source}: field {key!r} = {value} is outside the allowed range [{lo}, {hi}]")
    return float(value)


def parse_robot_config(raw: Mapping[str, Any], source: str = "robot config") -> RobotConfig:
    """Validate a parsed YAML mapping into a :class:`RobotConfig`; errors name the offending field."""
    desc = _field(raw, "description", source, Mapping)
    frames = _field(raw, "frames", source, Mapping)
    feet = _field(frames, "feet", f"{source}: frames", Mapping)
    hands = _field(frames, "hands", f"{source}: frames", Mapping)
    for group, sides in (("feet", feet), ("hands", hands)):
        if set(sides) != {"left", "right"}:
            raise ConfigError(f"{source}: frames.{group} must have exactly the keys 'left' and 'right'")
    roles = _field(raw, "joints", source, Mapping)
    unknown = sorted(set(roles) - set(JOINT_ROLES) - set(REACH_ROLES))
    if unknown:
        raise ConfigError(f"{source}: joints.{unknown[0]} is not a joint role ({', '.join(JOINT_ROLES + REACH_ROLES)})")
    for role in JOINT_ROLES + tuple(r for r in REACH_ROLES if r in roles):
        sides = _field(roles, role, f"{source}: joints", Mapping)
        if set(sides) != {"left", "right"}:
            raise ConfigError(f"{source}: joints.{role} must have exactly the keys 'left' and 'right'")
    foot = _field(raw, "foot", source, Mapping)
    offset = _field(foot, "center_offset", f"{source}: foot", list)
    if len(offset) != 2:
        raise ConfigError(f"{source}: foot.center_offset must be [x, y] in metres")
    posture = _field(raw, "half_sitting", source, Mapping)
    if not posture:
        raise ConfigError(f"{source}: half_sitting must list every actuated joint")
    for joint, angle in posture.items():
        if not isinstance(angle, (int, float)) or not math.isfinite(angle) or abs(angle) > 2 * math.pi:
            raise ConfigError(f"{source}: half_sitting.{joint} = {angle!r} must be a finite angle in [-2π, 2π] rad")
    for role in roles:
        for side, joint in roles[role].items():
            if joint not in posture:
                raise ConfigError(f"{source}: joints.{role}.{side} = {joint!r} is not a joint of half_sitting")
    servo = _field(raw, "servo", source, Mapping)
    armature = _armature(servo, posture, source)
    box_height = None if foot.get("box_height") is None else _number(foot, "box_height", f"{source}: foot", 0.001, 0.2)
    added = _added_frames(raw.get("added_frames") or {}, source)
    walking = dict(raw.get("walking") or {})
    if not isinstance(raw.get("walking") or {}, Mapping):
        raise ConfigError(f"{source}: walking must map walking parameters to values")
    speed = (_number(walking, "speed", f"{source}: walking", 0.02, 0.5) if "speed" in walking
             else DEFAULT_WALKING_SPEED)
    walking.pop("speed", None)
    stabilizer = raw.get("stabilizer") or {}
    if not isinstance(stabilizer, Mapping):
        raise ConfigError(f"{source}: stabilizer must map stabilizer gains to values")
    limits = _field(raw, "limits", source, Mapping)
    sim = _field(raw, "simulation", source, Mapping)
    drawer = _section(raw, "drawer", ("scale", "dynfilter", "handle_grip", "bar_from_grip"), source)
    drawer_scale = _number(drawer, "scale", f"{source}: drawer", 0.3, 2.0) if "scale" in drawer else 1.0
    return RobotConfig(
        name=_field(raw, "name", source, str),
        package_dir=_field(desc, "package_dir", f"{source}: description", str),
        urdf=_field(desc, "urdf", f"{source}: description", str),
        srdf=desc.get("srdf"),
        base_link=_field(desc, "base_link", f"{source}: description", str),
        added_frames=added,
        feet=dict(feet),
        hands=dict(hands),
        torso=_field(frames, "torso", f"{source}: frames", str),
        waist=_field(frames, "waist", f"{source}: frames", str),
        joint_roles={role: dict(sides) for role, sides in roles.items()},
        foot=FootGeometry(
            length=_number(foot, "length", f"{source}: foot", 0.01, 1.0),
            width=_number(foot, "width", f"{source}: foot", 0.01, 1.0),
            center_offset=(float(offset[0]), float(offset[1])),
            box_height=box_height,
        ),
        joint_names=tuple(posture),
        half_sitting=tuple(float(a) for a in posture.values()),
        servo=ServoGains(
            kp_per_effort=_number(servo, "kp_per_effort", f"{source}: servo", 0.1, 1000.0),
            damping_ratio=_number(servo, "damping_ratio", f"{source}: servo", 0.0, 10.0),
            armature=armature,
        ),
        position_margin=_number(limits, "position_margin", f"{source}: limits", 0.0, 0.5),
        velocity_fraction=_number(limits, "velocity_fraction", f"{source}: limits", 0.01, 1.0),
        acceleration_fraction=(None if limits.get("acceleration_fraction") is None
                               else _number(limits, "acceleration_fraction", f"{source}: limits", 0.01, 1.0)),
        braking_fraction=(None if limits.get("braking_fraction") is None
                          else _number(limits, "braking_fraction", f"{source}: limits", 0.01, 1.0)),
        max_gain_ratio=_number(limits, "max_gain_ratio", f"{source}: limits", 1.0, 10.0),
        servo_torque_fraction=(None if limits.get("servo_torque_fraction") is None
                               else _number(limits, "servo_torque_fraction", f"{source}: limits", 0.1, 1.0)),
        timestep=_number(sim, "timestep", f"{source}: simulation", 1e-4, 0.01),
        walking=walking,
        stabilizer=dict(stabilizer),
        walking_speed=speed,
        gait_swing=_gait_swing(raw.get("gait_swing") or {}, posture, source),
        grippers=_grippers(raw, source),
        drawer_scale=drawer_scale,
        drawer_grip=_drawer_grip(drawer, source),
        drawer_dynfilter=_filter_mode(drawer.get("dynfilter", FilterMode.FULL.value), source),
        ik_ranges=_ik_ranges(limits.get("ik_ranges") or {}, posture, source),
        links_without_collision=_names(sim.get("links_without_collision") or [],
                                       f"{source}: simulation.links_without_collision"),
    )


def _drawer_grip(drawer: Mapping[str, Any], source: str):
    """``drawer.handle_grip`` and ``drawer.bar_from_grip``, both or neither: [x, y, z] [m], each within 1 m."""
    given = [key for key in ("handle_grip", "bar_from_grip") if key in drawer]
    if not given:
        return None
    if len(given) != 2:
        raise ConfigError(f"{source}: drawer.handle_grip and drawer.bar_from_grip go together ({given[0]} alone)")
    out = []
    for key in ("handle_grip", "bar_from_grip"):
        xyz = drawer[key]
        if not (isinstance(xyz, list) and len(xyz) == 3 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and abs(v) <= 1.0
                for v in xyz)):
            raise ConfigError(f"{source}: drawer.{key} must be [x, y, z] in metres, each within 1 m, got {xyz!r}")
        out.append(tuple(float(v) for v in xyz))
    return tuple(out)


def _names(raw: Any, where: str) -> tuple[str, ...]:
    if not isinstance(raw, list) or not all(isinstance(n, str) for n in raw):
        raise ConfigError(f"{where} must be a list of link names")
    return tuple(raw)


def _ik_ranges(raw: Any, posture: Mapping[str, Any], source: str) -> Mapping[str, tuple[float, float]]:
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{source}: limits.ik_ranges must map joints to [lower, upper] rad")
    out = {}
    for joint, span in raw.items():
        where = f"{source}: limits.ik_ranges.{joint}"
        if joint not in posture:
            raise ConfigError(f"{where}: not a joint of half_sitting")
        if not (isinstance(span, list) and len(span) == 2 and all(isinstance(v, (int, float)) for v in span)
                and span[0] <= posture[joint] <= span[1]):
            raise ConfigError(f"{where} must be [lower, upper] rad around its half_sitting angle "
                              f"{posture[joint]}, got {span!r}")
        out[joint] = (float(span[0]), float(span[1]))
    return out


def _filter_mode(value: Any, source: str) -> FilterMode:
    try:
        return FilterMode("off" if value is False else value)  # YAML reads an unquoted off as false
    except ValueError:
        raise ConfigError(f"{source}: drawer.dynfilter {value!r} is not one of "
                          f"{', '.join(m.value for m in FilterMode)}") from None


def _section(raw: Mapping[str, Any], name: str, keys: tuple[str, ...], source: str) -> Mapping[str, Any]:
    """An optional section of ``keys`` (empty when absent); an unknown key is named."""
    section = raw.get(name) or {}
    if not isinstance(section, Mapping):
        raise ConfigError(f"{source}: {name} must be a mapping of {', '.join(keys)}")
    unknown = sorted(set(section) - set(keys))
    if unknown:
        raise ConfigError(f"{source}: {name}.{unknown[0]} is not a field of {name} ({', '.join(keys)})")
    return section


def _grippers(raw: Mapping[str, Any], source: str) -> Grippers:
    grasp = _section(raw, "grasp", ("closes_toward", "opening", "hand_rpy", "hook"), source)
    if not grasp:
        return DEFAULT_GRIPPERS
    closes = _field(grasp, "closes_toward", f"{source}: grasp", Mapping)
    if set(closes) != {"left", "right"} or not set(closes.values()) <= {"upper", "lower"}:
        raise ConfigError(f"{source}: grasp.closes_toward must map left and right to upper or lower, got {closes!r}")
    rpy = grasp.get("hand_rpy")
    if rpy is not None and not (isinstance(rpy, list) and len(rpy) == 3 and all(
            isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a) and abs(a) <= math.pi
            for a in rpy)):
        raise ConfigError(f"{source}: grasp.hand_rpy must be [roll, pitch, yaw], each in [-pi, pi] rad, got {rpy!r}")
    hook = grasp.get("hook", False)
    if not isinstance(hook, bool):
        raise ConfigError(f"{source}: grasp.hook must be true or false, got {hook!r}")
    return Grippers(dict(closes), _number(grasp, "opening", f"{source}: grasp", 0.05, 3.0),
                    None if rpy is None else tuple(float(a) for a in rpy), hook)


def _gait_swing(raw: Mapping[str, Any], posture: Mapping[str, Any], source: str) -> tuple[GaitSwing, ...]:
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{source}: gait_swing must map joints to [amplitude rad, swing|bob, phase rad]")
    out = []
    for joint, spec in raw.items():
        where = f"{source}: gait_swing.{joint}"
        if joint not in posture:
            raise ConfigError(f"{where}: not a joint of half_sitting")
        if not (isinstance(spec, list) and len(spec) == 3 and spec[1] in ("swing", "bob")
                and all(isinstance(v, (int, float)) and math.isfinite(v) for v in (spec[0], spec[2]))
                and abs(spec[0]) <= 1.0):
            raise ConfigError(f"{where} must be [amplitude in [-1, 1] rad, swing or bob, phase rad], got {spec!r}")
        out.append(GaitSwing(joint, float(spec[0]), spec[1], float(spec[2])))
    return tuple(out)


def _armature(servo: Mapping[str, Any], posture: Mapping[str, Any], source: str) -> str | float | dict[str, float]:
    armature = _field(servo, "armature", f"{source}: servo", (str, int, float, Mapping))
    if isinstance(armature, str):
        if armature != "srdf":
            raise ConfigError(f"{source}: servo.armature must be 'srdf', a number or a joint -> number map [kg·m²], "
                              f"got {armature!r}")
        return armature
    if isinstance(armature, Mapping):
        unknown = sorted(set(armature) - set(posture))
        if unknown:
            raise ConfigError(f"{source}: servo.armature names joints not in half_sitting: {unknown}")
        return {joint: _number(armature, joint, f"{source}: servo.armature", 0.0, 10.0) for joint in armature}
    return _number(servo, "armature", f"{source}: servo", 0.0, 10.0)


def _added_frames(raw: Mapping[str, Any], source: str) -> tuple[AddedFrame, ...]:
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{source}: added_frames must map frame names to {{parent, xyz, rpy}}")
    frames = []
    for name, spec in raw.items():
        where = f"{source}: added_frames.{name}"
        parent = _field(spec, "parent", where, str)
        vectors = []
        for key in ("xyz", "rpy"):
            value = spec.get(key, [0.0, 0.0, 0.0])
            if not (isinstance(value, list) and len(value) == 3
                    and all(isinstance(v, (int, float)) and math.isfinite(v) and abs(v) <= 10.0 for v in value)):
                raise ConfigError(f"{where}.{key} must be three finite numbers in [-10, 10] (m or rad), got {value!r}")
            vectors.append(tuple(float(v) for v in value))
        frames.append(AddedFrame(str(name), parent, *vectors))
    return tuple(frames)
