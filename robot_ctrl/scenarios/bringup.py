"""Bring-up of a robot's servos, one step at a time (docs/hardware.md, "Bring-up"): ``scan`` (every
motor answers), ``read`` (the joints against their limits), ``check`` (scan, and the posture a start
may move from), ``stand`` (the start sequence to half-sitting), ``jog`` (one joint by an angle),
``zero`` (a drive's encoder zero). Each configures the hardware it is given and leaves the rest to
its owner (``open_hardware``: the safety layer's close sends damping, then disables the motors).
A start refused or a tracking fault is a :class:`~robot_ctrl.hw.adapter.HardwareFault`."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from robot_ctrl.control.controllers.static_feedforward import upper_body_gravity
from robot_ctrl.control.loop.control_loop import ControlLoop
from robot_ctrl.control.loop.pacer import Pacer
from robot_ctrl.control.loop.start_sequence import StartParams, StartRefused, StartSequence, TrackingFault
from robot_ctrl.eval.recording.recorders import HeldFor, TimeLimit
from robot_ctrl.hw.adapter import HardwareFault
from robot_ctrl.hw.safety import SafetyLayer
from robot_ctrl.robot.model import RobotModel

HOLD_S = 1.0  # [s] the posture is held after a move before the command ends


def scan(robot: RobotModel, hw: SafetyLayer) -> dict:
    """Enable every motor and read back: a silent one fails ``activate`` with its joint's name. Also
    which drives stop by themselves if the host dies, and which hold their last command."""
    hw.configure()
    hw.activate()
    hw.read()
    hw.deactivate()
    stopping = hw.backend.drive_timeout_joints
    holding = [j for j in robot.joint_names if j not in stopping]
    return {"motors": hw.nj, "answering": hw.nj, "stop_without_host": f"{len(stopping)} of {hw.nj} joints",
            "hold_last_command_without_host": holding,
            **({"enabled_because": hw.backend.without_drive_timeout} if holding else {})}


def read(robot: RobotModel, hw: SafetyLayer) -> list[dict]:
    """The measured joints against their position limits. The motors are enabled for the read (an
    MIT drive answers only in motor mode) and sent nothing stiff."""
    hw.configure()
    hw.activate()
    state = hw.read()
    hw.deactivate()
    rows = []
    for i, name in enumerate(robot.joint_names):
        q, tolerance = float(state.q[i]), StartParams.limit_tolerance  # encoder steps, calibration
        status = ("below lower limit" if q < robot.lower[i] - tolerance else
                  "above upper limit" if q > robot.upper[i] + tolerance else "ok")
        row = {"joint": name, "q_rad": round(q, 4), "lower_rad": round(float(robot.lower[i]), 4),
               "upper_rad": round(float(robot.upper[i]), 4), "status": status}
        if state.temperature is not None:
            row["temperature_c"] = round(float(state.temperature[i]), 1)
        rows.append(row)
    return rows


def check(robot: RobotModel, hw: SafetyLayer, params: StartParams = StartParams()) -> dict:
    """``scan``, then whether the measured posture is one ``stand`` may start from."""
    result = scan(robot, hw)
    state = hw.read()
    try:
        StartSequence(robot, state, params=params)
    except StartRefused as exc:
        raise HardwareFault(f"the start would be refused: {exc}") from exc
    far = np.abs(state.q - np.array(robot.config.half_sitting))
    return result | {"largest_distance_to_start_rad": round(float(far.max()), 4),
                     "farthest_joint": robot.joint_names[int(far.argmax())]}


def move(robot: RobotModel, hw: SafetyLayer, target: Callable[[np.ndarray], np.ndarray] | None = None,
         params: StartParams = StartParams(), pacer: Pacer | None = None, recorders: Sequence = ()) -> dict:
    """The start sequence from the measured posture to ``target(measured q)`` (default
    half-sitting), then ``HOLD_S`` of holding; ``pacer`` on real hardware; ``recorders`` (a tick
    log) see every tick."""
    hw.bring_up()
    state = hw.read()
    try:
        goal = np.array(robot.config.half_sitting) if target is None else target(np.asarray(state.q, dtype=float))
        sequence = StartSequence(robot, state, goal, params, upper_body_gravity(robot, goal))
        done = HeldFor(lambda: sequence.done, HOLD_S, "held the posture")
        loop = ControlLoop([hw], [sequence], params.control_dt, recorders=recorders, stops=[
            done, TimeLimit(params.duration + HOLD_S + 1.0, "did not settle")], pacer=pacer)
        result = loop.run([state])
    except (StartRefused, TrackingFault) as exc:
        hw.estop()
        raise HardwareFault(f"{type(exc).__name__}: {exc}; the servos were sent damping") from exc
    error = np.abs(result.states[0].q - sequence.target)
    report = {"reached": "held the posture" in result.stop_reason, "largest_tracking_error_rad":
              round(sequence.largest_error, 4), "final_error_rad": round(float(error.max()), 4),
              "final_error_joint": robot.joint_names[int(error.argmax())], "safety": hw.report()}
    return report | ({"timing": pacer.report()} if pacer is not None else {})


def jog_target(robot: RobotModel, joint: str, delta: float) -> Callable[[np.ndarray], np.ndarray]:
    """The measured posture (clipped into the limits, as every reference is) with ``joint`` moved by
    ``delta`` [rad]; the start sequence refuses a target outside the limits."""
    if joint not in robot.joint_names:
        raise ValueError(f"jog: {joint!r} is not a joint of {robot.name}")
    if not (np.isfinite(delta) and abs(delta) <= np.pi):
        raise ValueError(f"jog: DELTA = {delta} rad is outside the allowed range [-3.1416, 3.1416]")
    step = np.where(np.array(robot.joint_names) == joint, delta, 0.0)
    return lambda q: np.clip(q, robot.lower, robot.upper) + step


def zero(hw: SafetyLayer, joint: str) -> None:
    """Make ``joint``'s drive take its present position as its encoder zero (MIT drives)."""
    backend = hw.backend
    if not hasattr(backend, "zero_motor"):
        raise ValueError(f"zero: the {type(backend).__name__} cannot set a drive's zero")
    hw.configure()
    backend.zero_motor(joint)
