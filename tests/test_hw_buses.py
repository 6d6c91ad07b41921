"""Servo buses: protocol packing, the MIT-CAN and Dynamixel emulators (MuJoCo behind them) and the
safety layer's behaviour, checked on the emulator side of the bus."""

import dataclasses
import json
import os
import threading
import time
import uuid

import numpy as np
import pytest

from robot_ctrl.buses import dynamixel_port
from robot_ctrl.buses import dynamixel_protocol as dxl
from robot_ctrl.buses.bus_config import HW_CONFIGS, load_bus_config
from robot_ctrl.buses.dynamixel_backend import DynamixelBackend
from robot_ctrl.buses.dynamixel_emulator import DynamixelEmulator
from robot_ctrl.buses.mit_can_backend import MitCanBackend
from robot_ctrl.buses.mit_can_emulator import MitCanEmulator
from robot_ctrl.buses.mit_protocol import HOST_ID, MitRanges, pack_command, pack_reply, unpack_command, unpack_reply
from robot_ctrl.cli import main
from robot_ctrl.control.controllers.walking_controller import WalkingController
from robot_ctrl.hw.adapter import HardwareFault, LifecycleError
from robot_ctrl.hw.safety import SafetyLayer, SafetyLimits
from robot_ctrl.hw.types import JointCommand, LifecycleState
from robot_ctrl.robot import load_robot
from robot_ctrl.robot.config import ConfigError
from robot_ctrl.sim.mujoco_backend import MujocoBackend

pytestmark = pytest.mark.realtime  # wall-clock timing: run apart from the parallel tests

DT = 0.005


class FakeClock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_mit_frames_round_trip_within_one_quantization_step():
    r = MitRanges((-12.5, 12.5), (-20.0, 20.0), (0.0, 10000.0), (0.0, 300.0), (-320.0, 320.0))
    rng = np.random.default_rng(0)
    for _ in range(500):
        values = [rng.uniform(*getattr(r, f)) for f in ("position", "velocity", "kp", "kd", "torque")]
        decoded = unpack_command(pack_command(*values, r), r)
        for f, x, y in zip(("position", "velocity", "kp", "kd", "torque"), values, decoded):
            assert abs(x - y) <= r.step(f) / 2 + 1e-12
        reply = unpack_reply(pack_reply(7, values[0], values[1], values[4], r), r)
        assert reply.motor_id == 7 and abs(reply.position - values[0]) <= r.step("position") / 2 + 1e-12
        assert abs(reply.velocity - values[1]) <= r.step("velocity") / 2 + 1e-12
        assert abs(reply.torque - values[4]) <= r.step("torque") / 2 + 1e-12
    assert unpack_command(pack_command(99.0, 0, 0, 0, -999.0, r), r)[0] == 12.5  # clamped into the range
    with pytest.raises(ValueError, match="NaN"):
        pack_command(float("nan"), 0, 0, 0, 0, r)


@pytest.mark.parametrize("fmt,length", [("mit6", 6), ("cubemars", 8), ("damiao", 8)])
def test_mit_reply_formats_carry_temperature_and_faults(fmt, length):
    r = MitRanges((-12.5, 12.5), (-20.0, 20.0), (0.0, 500.0), (0.0, 5.0), (-10.0, 10.0))
    data = pack_reply(7, 1.25, -2.0, 3.5, r, fmt, temperature=48.0)
    reply = unpack_reply(data, r, fmt)
    assert len(data) == length and reply.motor_id == 7 and reply.fault is None
    assert abs(reply.position - 1.25) <= r.step("position") / 2 + 1e-12
    assert abs(reply.velocity + 2.0) <= r.step("velocity") / 2 + 1e-12
    assert abs(reply.torque - 3.5) <= r.step("torque") / 2 + 1e-12
    if fmt == "mit6":
        assert reply.temperature is None and reply.enabled is None
        return
    assert reply.temperature == 48.0
    if fmt == "cubemars":  # byte 6: °C + 40, byte 7: fault code
        assert data[6:] == bytes([88, 0])
        assert unpack_reply(pack_reply(7, 0, 0, 0, r, fmt, code=4), r, fmt).fault == "over-current"
    else:  # byte 0: status << 4 | id; bytes 6, 7: MOSFET and rotor °C
        assert data[0] == 0x17 and data[6:] == bytes([48, 48]) and reply.enabled is True
        lost = unpack_reply(pack_reply(7, 0, 0, 0, r, fmt, code=13), r, fmt)
        assert lost.motor_id == 7 and lost.fault.startswith("communication lost") and lost.enabled is False
        disabled = unpack_reply(pack_reply(7, 0, 0, 0, r, fmt, code=0), r, fmt)
        assert disabled.fault is None and disabled.enabled is False


def test_dynamixel_packets_match_the_wire_format():
    # Robotis e-manual, Protocol 2.0 Ping example: ID 1 -> FF FF FD 00 01 03 00 01 19 4E.
    assert dxl.packet(1, dxl.INST_PING) == bytes.fromhex("FFFFFD0001030001194E")
    params = bytes([0x10, 0xFF, 0xFF, 0xFD, 0x20])
    wire = dxl.packet(3, dxl.INST_WRITE, params)
    assert b"\xff\xff\xfd\xfd" in wire[7:]  # stuffed
    assert dxl.parse(bytearray(b"\x00junk" + wire)) == (3, dxl.INST_WRITE, params)
    corrupt = bytearray(wire)
    corrupt[-1] ^= 0xFF
    assert dxl.parse(corrupt) is None
    # Fast Sync Read answer of servos 3 and 7: one packet from the broadcast id, each servo's part
    # ERR ID DATA CRC, the first CRC the running CRC of the packet so far, the last the packet's own.
    fast = dxl.fast_sync_status([(3, bytes([1, 2]), 0), (7, bytes([3, 4]), 0x80)])
    assert fast[:8] == dxl.HEADER + bytes([dxl.BROADCAST, 13, 0, dxl.INST_STATUS])
    assert fast[8:12] == bytes([0, 3, 1, 2]) and int.from_bytes(fast[12:14], "little") == dxl.crc16(fast[:12])
    assert fast[14:18] == bytes([0x80, 7, 3, 4]) and len(fast) == 20
    assert dxl.parse(bytearray(fast)) == (dxl.BROADCAST, dxl.INST_STATUS, fast[8:18])


def test_bus_config_errors_name_the_joint_and_field(talos, tmp_path):
    text = load_bus_config("talos_mit_can", talos.joint_names).path.read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("leg_left_3_joint:      {bus: can0, id:  3, model: leg,     direction: 1",
                                "leg_left_3_joint:      {bus: can0, id:  3, model: leg,     direction: 2"))
    with pytest.raises(ConfigError, match=r"joints.leg_left_3_joint.direction must be 1 or -1"):
        load_bus_config(bad, talos.joint_names)
    bad.write_text("\n".join(line for line in text.splitlines() if not line.strip().startswith("head_2_joint")))
    with pytest.raises(ConfigError, match=r"joints missing from the mapping: \['head_2_joint'\]"):
        load_bus_config(bad, talos.joint_names)
    bad.write_text(text.replace("  wrist:   {position", "  wrist:   {reply: damiao, position"))
    with pytest.raises(ConfigError, match=r"joints.arm_left_5_joint: bus can2 mixes reply formats"):
        load_bus_config(bad, talos.joint_names)
    bad.write_text(text.replace("reply_timeout_s: 0.05", "reply_timeout_s: 0.05\ndrive_timeout_s: 0"))
    with pytest.raises(ConfigError, match=r"drive_timeout_s = 0 is outside the allowed range \[0.001, 10\] s"):
        load_bus_config(bad, talos.joint_names)
    bad.write_text(text.replace("stale_check_every: 20", "stale_check_every: 2.5"))
    with pytest.raises(ConfigError, match=r"stale_check_every = 2.5 is outside the allowed range \[0, 10000\] ticks"):
        load_bus_config(bad, talos.joint_names)
    text = load_bus_config("talos_dynamixel", talos.joint_names).path.read_text()
    bad.write_text(text.replace("kd_unit: 0.02}", "kd_unit: 0.02, fast_sync_read: yes please}"))
    with pytest.raises(ConfigError, match=r"models.talos-emulated.fast_sync_read must be true or false"):
        load_bus_config(bad, talos.joint_names)


def fresh_mit_config(talos, **config_changes):
    """The MIT-CAN bus config on virtual channels of their own (tests never hear each other)."""
    config = load_bus_config("talos_mit_can", talos.joint_names)
    tag = uuid.uuid4().hex[:8]
    return dataclasses.replace(config, buses={k: dict(v, channel=f"{v['channel']}_{tag}") for k, v in config.buses.items()},
                               **config_changes)


def configured_mit(talos, **config_changes):
    """The safety layer over the MIT-CAN backend (configured, not active), the emulator on fresh
    virtual channels, a fake wall clock."""
    config = fresh_mit_config(talos, **config_changes)
    emulator = MitCanEmulator(config, MujocoBackend(talos))
    emulator.start()
    clock = FakeClock()
    hw = SafetyLayer(MitCanBackend(config, talos.kd, body_sensors=emulator.body_state),
                     SafetyLimits.from_robot(talos, soft_start=0.1), clock=clock)
    hw.configure()
    return hw, emulator, clock


@pytest.fixture
def mit(talos):
    hw, emulator, clock = configured_mit(talos)
    hw.activate()
    yield hw, emulator, clock, hw.read()
    hw.close()
    emulator.close()


def test_servos_without_body_sensors_count_their_time_from_configure(talos):
    # A run's time limits count in its states' time: the time since the bus was configured, not the
    # wall clock's (a stand on real servos ended at its first tick when the state's time was the
    # monotonic clock's, hours).
    config = fresh_mit_config(talos)
    emulator = MitCanEmulator(config, MujocoBackend(talos))
    emulator.start()
    backend = MitCanBackend(config, talos.kd)
    try:
        backend.configure()
        backend.activate()
        backend.write(hold(talos, backend.read()))  # the first write's one-time costs (about 0.2 s) out of the wait
        first = backend.read().t
        time.sleep(0.2)
        backend.write(hold(talos, backend.read()))
        assert 0.0 <= first < 1.0 and backend.read().t - first == pytest.approx(0.2, abs=0.1)
    finally:
        backend.close()
        emulator.close()


def hold(talos, state, **change):
    fields = dict(q=state.q.copy(), dq=np.zeros(talos.nj), kp=talos.kp.copy(), kd=talos.kd.copy(),
                  tau_ff=np.zeros(talos.nj))
    fields.update(change)
    return JointCommand(**fields)


def tick(hw, clock, command):
    clock.t += DT
    hw.write(command)
    return hw.read()


def test_nan_and_out_of_limit_commands_never_reach_the_bus(talos, mit):
    hw, emulator, clock, state = mit
    for _ in range(30):  # past the soft start
        state = tick(hw, clock, hold(talos, state))
    before = emulator.received[-1][1]
    bad_q = state.q.copy()
    bad_q[3] = np.nan
    tick(hw, clock, hold(talos, state, q=bad_q))
    assert hw.interventions["rejected_command"] == 1
    np.testing.assert_allclose(emulator.received[-1][1].q, before.q, atol=1e-3)  # the last safe command, held
    far = state.q.copy()
    far[3] = talos.upper[3] + 1.0  # knee far beyond its limit
    for _ in range(5):
        before_last = state
        state = tick(hw, clock, hold(talos, state, q=far))
    sent = np.array([c.q for _, c in emulator.received])
    assert np.all(np.isfinite(sent))
    assert sent[:, 3].max() <= talos.upper[3] + 1e-3
    assert np.abs(np.diff(sent[-6:, 3])).max() <= hw.limits.step_limit[3] + 1e-3  # rate limited
    assert hw.interventions["position_step_limited"] >= 1 and hw.interventions["torque_clamped"] >= 1
    # The servo torque at the state the layer saw stays within the effort limit (+ quantization).
    last = emulator.received[-1][1]
    torque = last.kp * (last.q - before_last.q) + last.kd * (last.dq - before_last.dq) + last.tau_ff
    assert abs(torque[3]) <= talos.effort[3] + 5.0


def test_rejected_commands_in_a_row_fault_into_damping(talos, mit):
    """A controller whose commands stay non-finite for 20 ms (4 ticks at 200 Hz) is not held stiff on
    its last good command: damping, FAULT latched. Fewer in a row are held over."""
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    nan = hold(talos, state, tau_ff=np.full(talos.nj, np.nan))
    for bad in (3, 3):  # interrupted by a good command: no fault
        for _ in range(bad):
            tick(hw, clock, nan)
        assert hw.state is LifecycleState.ACTIVE and emulator.received[-1][1].kp.max() > 0  # held
        state = tick(hw, clock, hold(talos, state))
    for _ in range(4):
        tick(hw, clock, nan)
    assert hw.state is LifecycleState.FAULT and hw.interventions["command_fault"] == 1
    assert hw.interventions["rejected_command"] == 10 and np.all(emulator.received[-1][1].kp == 0)
    with pytest.raises(LifecycleError):
        hw.write(hold(talos, state))


@pytest.mark.parametrize("sensor", ["base_angvel", "base_linacc", "base_quat_xyzw", "foot_wrench"])
def test_a_non_finite_imu_or_force_reading_faults_into_damping(talos, mit, monkeypatch, sensor):
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    value = getattr(state, sensor)
    assert value is not None  # the emulated bus has body sensors
    if sensor == "foot_wrench":
        bad = dataclasses.replace(state, foot_wrench={**value, "left": np.full(6, np.nan)})
    else:
        bad = dataclasses.replace(state, **{sensor: np.full(len(value), np.nan)})
    monkeypatch.setattr(hw.backend, "read", lambda: bad)
    hw.read()
    assert hw.state is LifecycleState.FAULT and hw.interventions["bad_measurement"] == 1
    assert np.all(emulator.received[-1][1].kp == 0)


def test_missed_write_trips_the_watchdog_into_damping(talos, mit):
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    clock.t += 2.5 * DT  # no write for more than two control periods
    hw.read()
    assert hw.mode == "damping" and hw.interventions["watchdog"] == 1
    damping = emulator.received[-1][1]
    assert np.all(damping.kp == 0)
    assert np.abs(damping.tau_ff).max() < 0.1  # zero torque, within half a step of the 12-bit range
    np.testing.assert_allclose(damping.kd, talos.kd, rtol=0.01, atol=0.1)
    state = tick(hw, clock, hold(talos, state))  # the next write resumes with a soft start
    assert hw.mode == "normal" and np.all(emulator.received[-1][1].kp <= 0.06 * talos.kp + 3.0)


def test_feedforward_torque_ramps_in_with_the_stiffness_after_damping(talos, mit):
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    clock.t += 2.5 * DT
    hw.read()  # the watchdog: damping
    assert hw.mode == "damping"
    gravity = np.full(talos.nj, 5.0)  # [N·m]
    tick(hw, clock, hold(talos, state, tau_ff=gravity))
    ramp = DT / hw.limits.soft_start  # the first tick of the soft start
    sent = emulator.received[-1][1]
    assert np.all(sent.tau_ff <= gravity * ramp + 0.1)  # not 5 N·m at once (0.1: the 12-bit range's step)
    for _ in range(30):
        tick(hw, clock, hold(talos, state, tau_ff=gravity))
    strong = talos.effort > 10.0  # the wrists' and grippers' servos cannot give 5 N·m
    np.testing.assert_allclose(emulator.received[-1][1].tau_ff[strong], gravity[strong], atol=0.1)


def test_a_measured_position_beyond_a_limit_is_flagged_once_per_excursion(talos, mit, monkeypatch):
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    knee = talos.joint_names.index("leg_left_4_joint")
    inside = state
    q = state.q.copy()
    q[knee] = talos.upper[knee] + 0.05
    beyond = dataclasses.replace(state, q=q)
    for read, flagged in ((inside, 0), (beyond, 1), (beyond, 1), (inside, 1), (beyond, 2)):
        monkeypatch.setattr(hw.backend, "read", lambda read=read: dataclasses.replace(read, t=clock.t))
        tick(hw, clock, hold(talos, state))
        assert hw.interventions["position_beyond_limit"] == flagged
    assert hw.state is LifecycleState.ACTIVE and hw.mode == "normal"  # flagged, not acted on


def test_stale_state_puts_the_servos_in_damping(talos):
    hw, emulator, clock = configured_mit(talos, max_missed_replies=100)  # the backend holds on: the layer acts
    try:
        hw.activate()
        state = hw.read()
        for _ in range(30):
            state = tick(hw, clock, hold(talos, state))
        emulator.drop_replies = True
        for _ in range(10):
            tick(hw, clock, hold(talos, state))
        assert hw.interventions["stale_state"] == 1 and hw.mode == "damping"
        assert np.all(emulator.received[-1][1].kp == 0)
    finally:
        hw.close()
        emulator.close()


def test_a_silent_motor_fails_activation_and_leaves_every_motor_disabled(talos):
    hw, emulator, clock = configured_mit(talos)
    emulator.silent = {talos.joint_names.index("leg_right_4_joint")}
    try:
        with pytest.raises(HardwareFault, match="no reply from leg_right_4_joint on enable"):
            hw.activate()
        assert hw.state is LifecycleState.FAULT and hw.interventions["backend_fault"] == 1
        assert not emulator.enabled.any()
    finally:
        hw.close()
        emulator.close()


def test_missed_replies_hold_the_last_value_then_fault_into_damping(talos, mit):
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    knee = talos.joint_names.index("leg_left_4_joint")
    emulator.silent = {knee}
    held = state.q[knee]
    for _ in range(3):  # max_missed_replies: 3 in a row are held
        before = state.t
        state = tick(hw, clock, hold(talos, state))
        assert state.t > before and state.q[knee] == held and hw.mode == "normal"
    assert hw.backend.missed[knee] == 3 and hw.backend.missing_replies == 3
    with pytest.raises(HardwareFault, match="leg_left_4_joint missed more than 3 replies in a row"):
        tick(hw, clock, hold(talos, state))
    assert hw.state is LifecycleState.FAULT and np.all(emulator.received[-1][1].kp == 0)  # damping sent
    with pytest.raises(LifecycleError):
        hw.write(hold(talos, state))
    emulator.silent = set()
    hw.reset()
    hw.activate()
    tick(hw, clock, hold(talos, hw.read()))
    assert hw.state is LifecycleState.ACTIVE and hw.backend.missed.max() == 0


def test_the_tick_log_records_missed_replies_and_safety_interventions(talos, mit, tmp_path):
    from robot_ctrl.control.loop.control_loop import Tick
    from robot_ctrl.eval.recording.tick_log import TickLogWriter, log_report, read_tick_log

    hw, emulator, clock, state = mit
    writer = TickLogWriter(tmp_path / "bus.log", talos, hw, DT)
    knee = talos.joint_names.index("leg_left_4_joint")
    for k in range(40):
        emulator.silent = {knee} if k in (20, 21) else set()
        q = state.q.copy()
        q[0] += 0.5 if k == 30 else 0.0  # a step the layer limits
        command = hold(talos, state, q=q)
        writer.on_command(Tick(k, k * DT, [state], [command]))
        state = tick(hw, clock, command)
        writer.on_state(Tick(k, k * DT, [state], [command]))
    writer.close()
    report = log_report(read_tick_log(tmp_path / "bus.log"))
    assert report["ticks"] == 41 and report["base_measured"] is True
    assert report["bus"]["missing_replies"] == 2 and report["bus"]["longest_miss_streak"] == {"leg_left_4_joint": 2}
    assert report["safety"]["interventions"] == dict(hw.interventions) and "position_step_limited" in hw.interventions


def test_a_late_reply_is_dropped_not_read_as_the_next_ticks(talos, mit):
    import can

    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    emulator.silent = set(range(talos.nj))  # nothing answers any more ...
    motor = hw.backend.config.motors[0]
    stale = pack_reply(motor.id, 1.0, 0.0, 0.0, hw.backend.ranges[0])  # ... but an old reply is still queued
    with can.Bus(**hw.backend.config.buses[motor.bus]) as injector:
        injector.send(can.Message(arbitration_id=0, data=stale, is_extended_id=False))
        threading.Event().wait(0.01)
        tick(hw, clock, hold(talos, state))
    assert hw.backend.late_replies == 1 and hw.backend.missed[0] == 1  # dropped, and counted as missed
    assert abs(hw.read().q[0] - state.q[0]) < 1e-3  # the joint kept its last value, not the stale 1.0 rad


def send_before_each_reply_of(monkeypatch, emulator, i, sender, position):
    """Another node sends, from CAN id ``sender`` on motor ``i``'s bus just before each of its
    replies, a frame shaped like that reply at ``position`` (motor side) [rad]."""
    import can

    m, reply = emulator.config.motors[i], emulator._reply
    data = pack_reply(m.id, position, 0.0, 0.0, emulator.ranges[i], emulator.formats[i], 30.0, None)

    def with_a_frame_first(j):
        if j == i:
            emulator._buses[m.bus].send(can.Message(arbitration_id=sender, data=data, is_extended_id=False))
        reply(j)

    monkeypatch.setattr(emulator, "_reply", with_a_frame_first)


def test_a_foreign_frame_shaped_like_a_reply_is_counted_not_read(talos, mit, monkeypatch):
    """Another node's frame (id 0x123) whose bytes look like the hip's reply at 7 rad must not be
    taken as the hip's state: replies come to the host's id."""
    hw, emulator, clock, state = mit
    for _ in range(10):
        state = tick(hw, clock, hold(talos, state))
    hip = talos.joint_names.index("leg_left_2_joint")
    send_before_each_reply_of(monkeypatch, emulator, hip, 0x123, 7.0)
    for _ in range(5):
        state = tick(hw, clock, hold(talos, state))
        assert abs(state.q[hip] - emulator.plant.read().q[hip]) < 0.01  # the hip's own reply
    assert hw.backend.foreign_frames == 5 and hw.report()["bus"]["foreign_frames"] == 5


def test_a_bus_off_fails_the_write_into_a_hardware_fault(talos, mit, monkeypatch):
    import can

    hw, emulator, clock, state = mit
    for _ in range(5):
        state = tick(hw, clock, hold(talos, state))
    bus = hw.backend._buses["can2"]
    monkeypatch.setattr(type(bus), "state", property(lambda self: can.BusState.ERROR if self is bus else can.BusState.ACTIVE))
    with pytest.raises(HardwareFault, match="CAN bus can2 is bus-off"):
        tick(hw, clock, hold(talos, state))
    assert hw.state is LifecycleState.FAULT and hw.interventions["backend_fault"] == 1


def test_close_sends_damping_then_disables_every_motor(talos, mit):
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    assert emulator.enabled.all() and emulator.received[-1][1].kp.max() > 0
    hw.close()
    last = emulator.received[-1][1]
    assert np.all(last.kp == 0) and np.abs(last.tau_ff).max() < 0.1  # damping (zero within a 12-bit step)
    assert not emulator.enabled.any()


@pytest.mark.parametrize("stop", ["estop", "bad_measurement"])
def test_close_after_an_estop_or_a_fault_disables_every_motor(talos, mit, monkeypatch, stop):
    """An e-stop or a fault leaves the servos in damping, still enabled; closing must disable them
    (a host that exits after a fault must not leave the drives powered)."""
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    if stop == "estop":
        hw.estop()
    else:
        bad = dataclasses.replace(state, q=np.full(talos.nj, np.nan))
        monkeypatch.setattr(hw.backend, "read", lambda: bad)
        hw.read()
    assert hw.state in (LifecycleState.ESTOP, LifecycleState.FAULT)
    assert emulator.enabled.all() and np.all(emulator.received[-1][1].kp == 0)  # damping, still enabled
    hw.close()
    assert not emulator.enabled.any()


def test_one_failing_bus_leaves_every_other_bus_damped_then_disabled(talos, mit, monkeypatch):
    """A send that fails on one of the four buses: the e-stop still latches, every motor on the other
    three gets damping, and closing disables them; the error names the failing bus and its joints."""
    import can

    hw, emulator, clock, state = mit
    for _ in range(5):
        state = tick(hw, clock, hold(talos, state))
    assert emulator.enabled.all() and emulator.kp.min() > 0

    def broken(msg, timeout=None):
        raise can.CanOperationError("Transmit buffer full")

    monkeypatch.setattr(hw.backend._buses["can0"], "send", broken)
    on_can0 = np.array([m.bus == "can0" for m in hw.backend.config.motors])
    with pytest.raises(RuntimeError, match=r"^CAN bus can0 \(leg_left_1_joint, .*\): CanOperationError") as failed:
        hw.estop()
    assert "can1" not in str(failed.value)
    assert hw.state is LifecycleState.ESTOP and hw.backend.state is LifecycleState.ESTOP
    with pytest.raises(LifecycleError):
        hw.write(hold(talos, state))
    time.sleep(0.05)  # the emulated drives take their frames
    assert np.all(emulator.kp[~on_can0] == 0) and np.all(emulator.kd[~on_can0] > 0)  # damping
    assert np.all(emulator.kp[on_can0] > 0)  # can0's frames never went out
    hw.close()
    time.sleep(0.05)
    assert not emulator.enabled[~on_can0].any() and emulator.enabled[on_can0].all()


def test_ctrl_c_mid_walk_sends_damping_then_disables(monkeypatch, capsys):
    """Ctrl-C during a walk over the emulated MIT bus: exit status 130, and the last frames the
    motors got were damping (kp = 0), then disable."""
    import signal

    emulators = []
    original = MitCanEmulator.__init__

    def recorded(self, *args, **kwargs):
        original(self, *args, **kwargs)
        emulators.append(self)

    monkeypatch.setattr(MitCanEmulator, "__init__", recorded)
    # The SIGINT is raised by the control loop's own thread, 400 ticks (2 s) into the walk: at a known
    # point of the walk, whatever the machine's speed.
    controller_step, ticks = WalkingController.step, []

    def step(self, state):
        ticks.append(None)
        if len(ticks) == 400:
            signal.raise_signal(signal.SIGINT)
        return controller_step(self, state)

    monkeypatch.setattr(WalkingController, "step", step)
    # Python's own SIGINT handling, as `robot-ctrl` has it when started from a terminal: a test run
    # started as a background job (`cmd &` in a script) inherits SIGINT ignored, which Python keeps.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        assert main(["walk", "--distance", "3", "--hw", "mit-can-emulated", "--quiet"]) == 130
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(ticks) == 400
    assert capsys.readouterr().err.strip().splitlines()[-1] == "robot-ctrl: interrupted"
    (emulator,) = emulators
    t_last, last = emulator.received[-1]
    assert t_last > 0.5 and np.all(last.kp == 0) and last.kd.max() > 0  # walking, then damping
    assert np.any(emulator.received[-2][1].kp > 0) and not emulator.enabled.any()  # ... then disabled


def test_replies_are_taken_by_one_thread_at_a_time(talos, monkeypatch):
    """The safety layer's watchdog sends damping from its own thread while a write may be in flight:
    the two never wait on one bus at once (on a socket one could take the frame the other was told
    was there, and block for good). Each thread's wait hears the other's replies too (second answers,
    late at a stale check): here the backend holds on through them."""
    hw, emulator, clock = configured_mit(talos, stale_check_every=0, max_missed_replies=1000)
    hw.activate()
    state = hw.read()
    backend, waiting, most = hw.backend, [0], [0]
    for bus in backend._buses.values():
        def counted(timeout=None, recv=bus.recv):
            waiting[0] += 1
            most[0] = max(most[0], waiting[0])
            try:
                return recv(timeout)
            finally:
                waiting[0] -= 1
        monkeypatch.setattr(bus, "recv", counted)
    damping = hold(talos, state, kp=np.zeros(talos.nj))
    failed = []

    def writes(command):
        try:
            for _ in range(40):
                backend.write(command)
        except Exception as exc:  # noqa: BLE001 - a thread's failure is the test's
            failed.append(exc)
    threads = [threading.Thread(target=writes, args=(c,)) for c in (hold(talos, state), damping)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=30)
    hw.close()
    emulator.close()
    assert not failed and not any(t.is_alive() for t in threads)
    assert most[0] == 1


def test_estop_latches_until_reset(talos, mit):
    hw, emulator, clock, state = mit
    for _ in range(30):
        state = tick(hw, clock, hold(talos, state))
    stopper = threading.Thread(target=hw.estop)
    stopper.start()
    stopper.join()
    hw.estop()  # idempotent
    assert hw.state is LifecycleState.ESTOP and hw.interventions["estop"] == 1
    count = len(emulator.received)
    assert np.all(emulator.received[-1][1].kp == 0)
    with pytest.raises(LifecycleError):
        hw.write(hold(talos, state))
    with pytest.raises(LifecycleError):
        hw.activate()  # still latched
    assert len(emulator.received) == count  # nothing reached the bus
    hw.reset()
    hw.activate()
    state = hw.read()
    tick(hw, clock, hold(talos, state))
    assert np.all(emulator.received[-1][1].kp <= 0.06 * talos.kp + 3.0)  # soft start again


def two_ports(config):
    """The legs on a port of their own, the rest of the robot on another."""
    port = config.buses["port"]
    motors = tuple(dataclasses.replace(m, bus="legs" if m.joint.startswith("leg_") else "upper") for m in config.motors)
    return dataclasses.replace(config, buses={"legs": dict(port), "upper": dict(port)}, motors=motors)


def fast_sync_read(config):
    """The legs and the rest on two ports, every servo model with Fast Sync Read."""
    config = two_ports(config)
    return dataclasses.replace(config, models={k: dict(v, fast_sync_read=True) for k, v in config.models.items()})


def configured_dynamixel(talos, without_current_mode=(), ports=lambda config: config, without_fast_sync_read=()):
    """The safety layer over the Dynamixel backend (configured, not active), the emulator on a pty
    per port, a fake clock; ``ports`` rearranges the config's ports."""
    config = ports(load_bus_config("talos_dynamixel", talos.joint_names))
    emulator = DynamixelEmulator(config, MujocoBackend(talos))
    emulator.without_current_mode = set(without_current_mode)
    emulator.without_fast_sync_read = set(without_fast_sync_read)
    emulator.start()
    config = dataclasses.replace(config, buses={name: dict(port, device=emulator.port_names[name])
                                                for name, port in config.buses.items()})
    clock = FakeClock()
    hw = SafetyLayer(DynamixelBackend(config, talos.kd, body_sensors=emulator.body_state, effort=talos.effort,
                                      velocity=talos.velocity_limit),
                     SafetyLimits.from_robot(talos, soft_start=0.05), clock=clock)
    try:
        hw.configure()
    except Exception:
        hw.close()
        emulator.close()
        raise
    return hw, emulator, clock


def test_dynamixel_servos_run_in_current_based_position_mode_limited_to_their_effort(talos):
    hw, emulator, clock = configured_dynamixel(talos)
    try:
        assert np.all(emulator.operating_mode == 5) and np.all(emulator.return_delay == 0)
        assert np.all(emulator.profile == 0)
        hw.activate()
        expected = np.ceil(talos.effort / 0.01)  # talos-emulated: 0.01 N·m per current unit
        np.testing.assert_array_equal(emulator.goal_current, expected)
        state = hw.read()
        knee = talos.joint_names.index("leg_left_4_joint")
        emulator.goal_current[knee] = 2000  # 20 N·m: the servo's own limit now binds
        q = state.q.copy()
        q[knee] += 0.2  # kp × 0.2 rad asks far more than 20 N·m
        for _ in range(30):
            state = tick(hw, clock, hold(talos, state, q=q))
        sent = emulator.received[-1][1]
        torque = sent.kp[knee] * (sent.q[knee] - state.q[knee]) - sent.kd[knee] * state.dq[knee]
        assert sent.kp[knee] > 0 and abs(torque) <= 20.0 + 0.5
    finally:
        hw.close()
        emulator.close()


def test_servos_split_over_two_ports_run_in_lock_step(talos):
    hw, emulator, clock = configured_dynamixel(talos, ports=two_ports)
    try:
        assert [p.name for p in hw.backend.ports] == ["legs", "upper"] and len(set(emulator.port_names.values())) == 2
        assert [len(p.motors) for p in hw.backend.ports] == [12, 20]
        hw.activate()
        state = hw.read()
        start, received = state.t, len(emulator.received)
        elbow = talos.joint_names.index("arm_left_4_joint")
        q = state.q.copy()
        q[elbow] -= 0.2
        for k in range(1, 61):
            state = tick(hw, clock, hold(talos, state, q=q))
            assert len(emulator.received) == received + k and state.t == pytest.approx(start + k * DT)
        assert abs(state.q[elbow] - q[elbow]) < 0.02 and hw.backend.missing_replies == 0
    finally:
        hw.close()
        emulator.close()


def test_fast_sync_read_gives_the_servos_state_in_one_packet_per_port(talos):
    hw, emulator, clock = configured_dynamixel(talos, ports=fast_sync_read)
    try:
        assert [p.fast for p in hw.backend.ports] == [True, True]
        hw.activate()
        state = hw.read()
        elbow = talos.joint_names.index("arm_left_4_joint")
        q = state.q.copy()
        q[elbow] -= 0.2
        fast, sync = emulator.instructions[dxl.INST_FAST_SYNC_READ], emulator.instructions[dxl.INST_SYNC_READ]
        for _ in range(60):
            state = tick(hw, clock, hold(talos, state, q=q))
            plant = emulator.body_state()
            np.testing.assert_allclose(state.q, plant.q, atol=1e-5)  # one position unit: 6.3e-6 rad
            np.testing.assert_allclose(state.dq, plant.dq, atol=1e-3)
        assert abs(state.q[elbow] - q[elbow]) < 0.02 and hw.backend.missing_replies == 0
        assert emulator.instructions[dxl.INST_FAST_SYNC_READ] - fast == 2 * 60  # one per port and tick
        assert emulator.instructions[dxl.INST_SYNC_READ] - sync == 2 * 2 * (60 // 40)  # the error checks only
    finally:
        hw.close()
        emulator.close()


def test_servos_without_fast_sync_read_fail_the_configuration_naming_their_port(talos):
    elbow = talos.joint_names.index("arm_left_4_joint")
    with pytest.raises(HardwareFault, match=r"servos on \S+ \(upper\) answer a Sync Read but not a Fast Sync Read: "
                                            r"set fast_sync_read: false"):
        configured_dynamixel(talos, ports=fast_sync_read, without_fast_sync_read={elbow})


def test_a_servo_without_current_based_position_mode_fails_the_configuration(talos):
    with pytest.raises(HardwareFault, match=r"arm_left_3_joint \(servo 17\) does not take 5 at address 11"):
        configured_dynamixel(talos, without_current_mode={talos.joint_names.index("arm_left_3_joint")})


def test_temperature_derates_then_faults(talos):
    hw, emulator, clock = configured_dynamixel(talos)
    try:
        hw.activate()
        state = hw.read()
        for _ in range(20):
            state = tick(hw, clock, hold(talos, state))
        assert np.all(state.temperature == 35)
        emulator.temperature[3] = 75.0  # halfway from derate (70) to fault (80)
        state = tick(hw, clock, hold(talos, state))
        state = tick(hw, clock, hold(talos, state))
        kp = emulator.received[-1][1].kp
        assert kp[3] == pytest.approx(0.6 * talos.kp[3], rel=0.01) and kp[4] == pytest.approx(talos.kp[4], rel=0.01)
        emulator.temperature[3] = 82.0  # past the layer's fault (80), below the servo's own limit (85)
        tick(hw, clock, hold(talos, state))
        hw.read()  # a Sync Write has no reply: this read's round trip orders it after the damping write
        assert hw.state is LifecycleState.FAULT and hw.interventions["temperature_fault"] == 1
        assert np.all(emulator.received[-1][1].kp == 0)
        with pytest.raises(LifecycleError):
            hw.write(hold(talos, state))
        emulator.temperature[3] = 40.0  # cooled down: an explicit reset brings it back
        hw.reset()
        hw.activate()
        state = tick(hw, clock, hold(talos, hw.read()))
        assert hw.state is LifecycleState.ACTIVE and emulator.received[-1][1].kp[3] > 0
    finally:
        hw.close()
        emulator.close()


@pytest.mark.parametrize("kind", ["mit-can-emulated", "dynamixel-emulated"])
def test_balance_demo_over_an_emulated_bus(kind, tmp_path):
    assert main(["balance", "--hw", kind, "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fell"] is False and report["hand_error_m"] < 0.01
    assert report["safety"]["interventions"] == {} and report["safety"]["state"] == "active"


def test_a_walk_over_a_bus_that_loses_one_reply_in_a_hundred(tmp_path):
    """3 m over the emulated MIT-CAN bus with 1 % of the replies lost at random (--reply-loss): the
    lost values are held (a motor past max_missed_replies would be a fault, exit status 3), the walk
    does not fall and ends at its goal."""
    assert main(["walk", "--distance", "3", "--hw", "mit-can-emulated", "--reply-loss", "0.01", "--quiet",
                 "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["fell"] is False and report["final_position_error_m"] < 0.05
    assert report["disturbances"]["reply_loss"] == 0.01
    lost = report["safety"]["bus"]["missing_replies"] / (report["time_s"] / DT * 32)
    assert 0.005 < lost < 0.015  # about 1 % were lost


def test_reply_loss_needs_the_emulated_mit_bus(capsys):
    assert main(["walk", "--distance", "1", "--reply-loss", "0.01"]) == 2
    assert "--reply-loss acts on the emulated MIT-CAN bus (--hw mit-can-emulated)" in capsys.readouterr().err


def test_dynamixel_hardware_errors_gain_range_and_a_soft_torque_on(talos):
    from robot_ctrl.buses.dynamixel_backend import ERROR_CHECK_TICKS

    hw, emulator, clock = configured_dynamixel(talos)
    try:
        knee = talos.joint_names.index("leg_left_4_joint")
        emulator.hardware_error[knee] = 0x20  # shut down by an overload before we start
        with pytest.raises(HardwareFault, match="leg_left_4_joint: hardware error \\(overload\\)"):
            hw.activate()
        assert not emulator.torque_enable.any()
        emulator.hardware_error[knee] = 0  # rebooted
        hw.reset()
        hw.activate()
        # Torque came on with P = 0 and the goal at the present position.
        assert emulator.torque_enable.all() and not emulator.gains[:, 2].any()
        state = hw.read()
        for _ in range(10):
            state = tick(hw, clock, hold(talos, state))
        hw.backend._send(hold(talos, state, kp=1e6 * np.ones(talos.nj)))  # beyond the register range
        hw.read()  # a Sync Write has no reply: this read's round trip orders it after the gains
        assert emulator.gains[:, 2].max() == dxl.GAIN_MAX  # clipped, so the servo took it
        emulator.hardware_error[knee] = 0x04  # overheating during the run
        with pytest.raises(HardwareFault, match="leg_left_4_joint: hardware error \\(overheating\\)"):
            for _ in range(ERROR_CHECK_TICKS):
                state = tick(hw, clock, hold(talos, state))
        assert hw.state is LifecycleState.FAULT and emulator.torque_enable.sum() == talos.nj - 1  # the rest damp
        hw.close()
        assert not emulator.torque_enable.any()  # closing after the fault disabled every servo
    finally:
        hw.close()
        emulator.close()


def test_dynamixel_servos_silent_for_more_reads_than_allowed_are_a_fault(talos, monkeypatch):
    """A failed Sync Read holds the last values (a stale state); more than ``max_missed_replies`` in
    a row is a fault in damping, naming the port, not a robot held stale for good."""
    hw, emulator, clock = configured_dynamixel(talos)
    try:
        hw.activate()
        state = hw.read()
        for _ in range(5):
            state = tick(hw, clock, hold(talos, state))
        port = hw.backend.ports[0]
        monkeypatch.setattr(port, "read_present", lambda: None)
        for _ in range(hw.backend.config.max_missed_replies):
            tick(hw, clock, hold(talos, state))
        assert hw.state is LifecycleState.ACTIVE
        with pytest.raises(HardwareFault, match=f"no status from the servos on {port.device}"):
            tick(hw, clock, hold(talos, state))
        assert hw.state is LifecycleState.FAULT and hw.interventions["backend_fault"] == 1
    finally:
        hw.close()
        emulator.close()


def test_dynamixel_protective_limits_are_written_at_configure_and_act(talos):
    """Shutdown, Temperature, PWM and Velocity Limit go to every servo at configure (read back);
    a servo that reaches its temperature limit reports overheating and switches its torque off,
    which the next status read turns into a fault naming it."""
    from robot_ctrl.buses.dynamixel_backend import DEFAULT_TEMPERATURE_LIMIT, ERROR_CHECK_TICKS

    hw, emulator, clock = configured_dynamixel(talos)
    try:
        p = emulator.protection
        assert np.all(p[dxl.SHUTDOWN] == 0x34) and np.all(p[dxl.TEMPERATURE_LIMIT] == DEFAULT_TEMPERATURE_LIMIT)
        assert np.all(p[dxl.PWM_LIMIT] == dxl.PWM_MAX)
        velocity = p[dxl.VELOCITY_LIMIT] * emulator.units.velocity  # [rad/s], gear ratio 1
        assert np.all((velocity >= talos.velocity_limit) & (velocity < talos.velocity_limit + 0.002))
    finally:
        hw.close()
        emulator.close()
    # A model whose servos stop at 65 °C, below the safety layer's derating (70 °C).
    cool = lambda config: dataclasses.replace(  # noqa: E731
        config, models={k: dict(v, temperature_limit_c=65) for k, v in config.models.items()})
    hw, emulator, clock = configured_dynamixel(talos, ports=cool)
    try:
        assert np.all(emulator.protection[dxl.TEMPERATURE_LIMIT] == 65)
        hw.activate()
        state = hw.read()
        knee = talos.joint_names.index("leg_left_4_joint")
        emulator.temperature[knee] = 66.0
        with pytest.raises(HardwareFault, match="leg_left_4_joint: hardware error \\(overheating\\)"):
            for _ in range(ERROR_CHECK_TICKS):
                state = tick(hw, clock, hold(talos, state))
        assert emulator.torque_enable[knee] == 0
    finally:
        hw.close()
        emulator.close()


@pytest.mark.parametrize("answer", ["spoofed", "twice", "twice_last"])
def test_a_dynamixel_servo_that_answers_unasked_is_not_read_and_faults(talos, monkeypatch, answer):
    """A status packet with the knee's id before its own (another node's spoof, its position 1 rad
    off), the knee's answer twice, or the last servo's twice (the second then waits, unasked, for
    the next tick): the SDK would take the first and pass over the other unseen. Neither is taken:
    the joint keeps its last values, and two ticks in a row of it are a fault naming it."""
    hw, emulator, clock = configured_dynamixel(talos)
    try:
        hw.activate()
        state = hw.read()
        motors = hw.backend.config.motors
        joint = "leg_left_4_joint" if answer != "twice_last" else next(
            m.joint for m in reversed(motors) if m.bus == motors[0].bus)
        i = talos.joint_names.index(joint)
        servo, true_q = motors[i].id, state.q[i]
        handle = emulator._handle

        def answers(port, sender, instruction, params):
            reply = handle(port, sender, instruction, params)
            if instruction != dxl.INST_SYNC_READ or servo not in params[4:]:
                return reply
            registers = bytearray(emulator._load(i, dxl.PRESENT, dxl.PRESENT_LENGTH))
            own = dxl.status(servo, bytes(registers))
            position = dxl.to_signed(int.from_bytes(registers[6:10], "little"), 4)
            registers[6:10] = dxl.to_bytes(position + int(round(1.0 / emulator.units.position[i])), 4)
            spoof = dxl.status(servo, bytes(registers))
            assert own in reply
            return reply.replace(own, spoof + own if answer == "spoofed" else own + own)
        monkeypatch.setattr(emulator, "_handle", answers)
        with pytest.raises(HardwareFault, match=f"{joint} answered unasked"):
            for _ in range(20):
                state = tick(hw, clock, hold(talos, state))
                assert abs(state.q[i] - true_q) < 0.05  # never the spoof's
        assert hw.backend.duplicate_replies + hw.backend.late_replies >= 2
    finally:
        hw.close()
        emulator.close()


def test_a_dynamixel_answer_that_comes_after_its_wait_is_found_at_the_next_tick_and_faults(talos, monkeypatch):
    """The knee's answer withheld from its Sync Read and sent after the SDK gave up on it: the read
    misses, and the answer, waiting when the next tick starts, is late; two ticks in a row of it are
    a fault naming the knee before its missed reads are (the SDK alone would clear it unseen)."""
    monkeypatch.setattr(dynamixel_port, "EMULATED_REPLY_MARGIN", 0.0)  # give up after the SDK's own timeout
    hw, emulator, clock = configured_dynamixel(talos)
    try:
        hw.activate()
        state = hw.read()
        i = talos.joint_names.index("leg_left_4_joint")
        motor = hw.backend.config.motors[i]
        master = emulator._fds[2 * list(emulator.config.buses).index(motor.bus)]
        handle, withheld = emulator._handle, []

        def without_the_knee(port, sender, instruction, params):
            reply = handle(port, sender, instruction, params)
            if instruction != dxl.INST_SYNC_READ or motor.id not in params[4:]:
                return reply
            own = dxl.status(motor.id, emulator._load(i, dxl.PRESENT, dxl.PRESENT_LENGTH))
            withheld.append(own)
            return reply.replace(own, b"")
        monkeypatch.setattr(emulator, "_handle", without_the_knee)
        with pytest.raises(HardwareFault, match="leg_left_4_joint answered unasked"):
            for _ in range(5):
                state = tick(hw, clock, hold(talos, state))
                os.write(master, withheld.pop())  # after the tick's wait
        assert hw.backend.late_replies == 2 and hw.backend.missing_replies == 2
    finally:
        hw.close()
        emulator.close()


def test_an_expired_dynamixel_bus_watchdog_fails_the_run(talos):
    """A host that stalls past the servos' bus watchdog (100 ms) leaves them stopped where they
    were, torque on, ignoring goals (the X-series e-manual): the next status read says so instead
    of the robot silently holding a stale posture."""
    from robot_ctrl.buses.dynamixel_backend import ERROR_CHECK_TICKS

    hw, emulator, clock = configured_dynamixel(talos)
    try:
        hw.activate()
        state = hw.read()
        for _ in range(30):
            state = tick(hw, clock, hold(talos, state))
        stopped = state.q.copy()
        threading.Event().wait(0.3)  # the host stalls (the layer's clock is held: only the servos notice)
        elbow = talos.joint_names.index("arm_left_4_joint")
        moved = stopped.copy()
        moved[elbow] -= 0.2
        with pytest.raises(HardwareFault, match="bus watchdog expired"):
            for _ in range(ERROR_CHECK_TICKS):
                state = tick(hw, clock, hold(talos, state, q=moved))
                applied = emulator.received[-1][1]
                assert applied.kp[elbow] > 0 and abs(applied.q[elbow] - stopped[elbow]) < 0.01  # held, stiff
    finally:
        hw.close()
        emulator.close()


def with_reply(talos, fmt):
    config = load_bus_config("talos_mit_can", talos.joint_names)
    return {name: dict(model, reply=fmt) for name, model in config.models.items()}


def test_damiao_drives_take_a_can_timeout_and_disable_themselves_when_the_host_stops(talos):
    hw, emulator, clock = configured_mit(talos, models=with_reply(talos, "damiao"), drive_timeout=0.2)
    try:
        assert [r[9] for r in emulator.registers] == [4000] * talos.nj  # 0.2 s in 50 µs units, read back
        assert hw.backend.drive_timeout_joints == talos.joint_names
        hw.activate()
        state = hw.read()
        assert state.temperature is not None and np.all(state.temperature == 30.0)  # the drives' report
        for _ in range(10):
            state = tick(hw, clock, hold(talos, state))
        threading.Event().wait(0.3)  # the host stalls past the drives' timeout
        with pytest.raises(HardwareFault, match="leg_left_1_joint: communication lost"):
            tick(hw, clock, hold(talos, state))
        assert not emulator.enabled.any() and hw.state is LifecycleState.FAULT
    finally:
        hw.close()
        emulator.close()


def test_drives_without_a_command_timeout_need_each_joint_named(talos, tmp_path, capsys):
    """A drive with no command timeout of its own holds its last stiff command when the host dies:
    a bus config with such drives is refused unless it names each of their joints and says why."""
    import yaml

    config = load_bus_config("talos_mit_can", talos.joint_names)
    data = yaml.safe_load(config.path.read_text())
    bare = tmp_path / "no_ack.yaml"
    bare.write_text(yaml.safe_dump({k: v for k, v in data.items() if k != "without_drive_timeout"}))
    with pytest.raises(ConfigError, match="32 drives have no command timeout of their own"):
        MitCanBackend(load_bus_config(bare, talos.joint_names), talos.kd)
    assert main(["hw", "stand", "--hw", "mit-can-emulated", "--bus-config", str(bare)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "without_drive_timeout" in err
    one_short = dict(data, without_drive_timeout=dict(data["without_drive_timeout"],
                                                      joints=data["without_drive_timeout"]["joints"][1:]))
    bare.write_text(yaml.safe_dump(one_short))
    with pytest.raises(ConfigError, match=r"1 drives have no command timeout of their own \(leg_left_1_joint\)"):
        MitCanBackend(load_bus_config(bare, talos.joint_names), talos.kd)
    damiao = dataclasses.replace(config, models={k: dict(v, reply="damiao") for k, v in config.models.items()},
                                 without_drive_timeout=None)
    assert MitCanBackend(damiao, talos.kd).drive_timeout_joints == tuple(talos.joint_names)  # nothing to name


def test_a_drive_that_does_not_confirm_its_timeout_fails_the_configuration(talos):
    config = fresh_mit_config(talos, models=with_reply(talos, "damiao"))
    emulator = MitCanEmulator(config, MujocoBackend(talos))
    emulator.silent = {talos.joint_names.index("arm_right_2_joint")}
    emulator.start()
    hw = SafetyLayer(MitCanBackend(config, talos.kd, body_sensors=emulator.body_state),
                     SafetyLimits.from_robot(talos), clock=FakeClock())
    try:
        with pytest.raises(HardwareFault, match="arm_right_2_joint did not confirm their CAN timeout"):
            hw.configure()
    finally:
        hw.close()
        emulator.close()


def test_a_drive_fault_in_an_8_byte_reply_is_a_hardware_fault(talos):
    hw, emulator, clock = configured_mit(talos, models=with_reply(talos, "cubemars"))
    knee = talos.joint_names.index("leg_left_4_joint")
    try:
        hw.activate()
        state = hw.read()
        for _ in range(10):
            state = tick(hw, clock, hold(talos, state))
        emulator.faults[knee] = 4
        with pytest.raises(HardwareFault, match="leg_left_4_joint: over-current"):
            tick(hw, clock, hold(talos, state))
        assert hw.state is LifecycleState.FAULT and np.all(emulator.received[-1][1].kp == 0)  # damping sent
    finally:
        hw.close()
        emulator.close()


def test_a_drive_in_fault_refuses_activation(talos):
    hw, emulator, clock = configured_mit(talos, models=with_reply(talos, "damiao"))
    emulator.faults[talos.joint_names.index("torso_2_joint")] = 8
    try:
        with pytest.raises(HardwareFault, match="torso_2_joint: over-voltage"):
            hw.activate()
        assert not emulator.enabled.any()
    finally:
        hw.close()
        emulator.close()


def test_gains_and_torques_cross_a_gear_ratio_of_nine(talos, tmp_path):
    """A joint behind an N = 9 reduction: the motor turns N times as far and as fast, carries 1/N of
    the torque, and its PD gains are kp / N², kd / N² (the motor-side law τ_m = kp_m (p_ref − p) + ...
    gives N τ_m = kp (q_ref − q) + ... at the joint). Every shipped config has N = 1."""
    source = load_bus_config("talos_mit_can", talos.joint_names).path.read_text()
    path = tmp_path / "geared.yaml"
    path.write_text(source.replace("gear_ratio: 1.0", "gear_ratio: 9.0"))
    config = load_bus_config(path, talos.joint_names)
    n, d, zero = config.gear, config.direction, config.zero
    assert np.all(n == 9.0) and set(d) <= {-1.0, 1.0}
    rng = np.random.default_rng(0)
    q, dq, tau = rng.uniform(-1, 1, talos.nj), rng.uniform(-2, 2, talos.nj), rng.uniform(-50, 50, talos.nj)
    p, v, kp_m, kd_m, tau_m = config.to_motor(q, dq, talos.kp, talos.kd, tau)
    np.testing.assert_allclose(kp_m, talos.kp / 81.0, rtol=1e-12)
    np.testing.assert_allclose(kd_m, talos.kd / 81.0, rtol=1e-12)
    np.testing.assert_allclose(tau_m, d * tau / 9.0, rtol=1e-12)
    np.testing.assert_allclose(p, d * 9.0 * q + zero, rtol=1e-12)
    np.testing.assert_allclose(v, d * 9.0 * dq, rtol=1e-12)
    # A motor-side PD at the motor-side gains is the joint-side PD seen through the gear.
    error_m, rate_m = rng.uniform(-0.5, 0.5, talos.nj), rng.uniform(-1, 1, talos.nj)
    q_back, dq_back, joint_torque = config.to_joint(p - error_m, v - rate_m, kp_m * error_m + kd_m * rate_m + tau_m)
    np.testing.assert_allclose(joint_torque, talos.kp * (q - q_back) + talos.kd * (dq - dq_back) + tau, rtol=1e-9)


@pytest.mark.parametrize("path", sorted(HW_CONFIGS.glob("*.yaml")), ids=lambda p: p.stem)
def test_each_shipped_bus_config_fits_its_robot(path):
    """``configs/hw/<robot>_<bus>.yaml`` maps every joint of its robot, and an MIT drive model's ranges
    carry what the controller sends: torques up to the effort limit, the servo gains."""
    robot = load_robot(path.stem.split("_")[0])
    config = load_bus_config(path, robot.joint_names)
    assert tuple(m.joint for m in config.motors) == robot.joint_names
    if config.backend != "mit_can":
        return
    for motor, effort, kp, kd in zip(config.motors, robot.effort, robot.kp, robot.kd):
        ranges = config.models[motor.model]
        assert ranges["torque"][1] >= effort and ranges["kp"][1] >= kp and ranges["kd"][1] >= kd, motor.joint


def test_one_failing_dynamixel_port_leaves_the_other_ports_damped_then_torque_off(talos):
    """The legs' port fails: the e-stop's damping and the close's torque off still reach every servo
    on the other port; the error names the failing port."""
    hw, emulator, clock = configured_dynamixel(talos, ports=two_ports)
    try:
        hw.activate()
        state = hw.read()
        for _ in range(5):
            state = tick(hw, clock, hold(talos, state))
        legs = next(port for port in hw.backend.ports if port.name == "legs")
        on_legs = np.array([m.bus == "legs" for m in hw.backend.config.motors])
        assert emulator.torque_enable.all() and emulator.gains[:, 2].min() > 0

        def broken(*args):
            raise OSError("the legs' port is unplugged")

        for method in ("write_gains", "write_goals", "_write"):
            setattr(legs, method, broken)
        with pytest.raises(RuntimeError, match=r"\(legs\): the legs' port is unplugged") as failed:
            hw.estop()
        assert "(upper)" not in str(failed.value)
        start = time.monotonic()  # a Sync Write has no reply: the emulated servos take it when they read it
        while np.any(emulator.gains[~on_legs, 2]) and time.monotonic() - start < 2.0:
            time.sleep(0.01)
        assert np.all(emulator.gains[~on_legs, 2] == 0) and np.all(emulator.gains[~on_legs, 0] > 0)  # P 0, D on
        assert np.all(emulator.gains[on_legs, 2] > 0)
        hw.close()
        assert not emulator.torque_enable[~on_legs].any() and emulator.torque_enable[on_legs].all()
    finally:
        hw.close()
        emulator.close()


@pytest.fixture
def sigterm_interrupts():
    """SIGTERM raises KeyboardInterrupt, as robot-ctrl's handler makes it."""
    import signal

    def interrupt(signum, frame):
        raise KeyboardInterrupt(signal.Signals(signum).name)

    previous = signal.signal(signal.SIGTERM, interrupt)
    yield
    signal.signal(signal.SIGTERM, previous)


def test_a_second_sigterm_inside_close_still_damps_and_disables_every_drive(talos, mit, monkeypatch,
                                                                           sigterm_interrupts):
    """The first SIGTERM ended the run; a second one arrives while close() sends damping: the damping
    and the disable still reach every drive, then the interrupt goes on."""
    import os
    import signal

    hw, emulator, clock, state = mit
    for _ in range(5):
        state = tick(hw, clock, hold(talos, state))
    send = hw.backend._send_each

    def interrupted(frames):  # the signal comes in the middle of the damping frames
        os.kill(os.getpid(), signal.SIGTERM)
        return send(frames)

    monkeypatch.setattr(hw.backend, "_send_each", interrupted)
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        hw.close()
    time.sleep(0.05)
    assert np.all(emulator.kp == 0) and not emulator.enabled.any()


def test_a_signal_inside_activate_leaves_every_drive_damped_and_disabled(talos, monkeypatch, sigterm_interrupts):
    """SIGTERM while activate() enables the drives (after the enable frames, before the replies):
    the layer and the backend latch FAULT, and closing damps and disables every drive."""
    import os
    import signal

    hw, emulator, clock = configured_mit(talos)
    try:
        collect = hw.backend._collect

        def interrupted(*args, **kwargs):
            os.kill(os.getpid(), signal.SIGTERM)
            return collect(*args, **kwargs)

        monkeypatch.setattr(hw.backend, "_collect", interrupted)
        with pytest.raises(KeyboardInterrupt):
            hw.activate()
        monkeypatch.setattr(hw.backend, "_collect", collect)
        time.sleep(0.05)
        assert emulator.enabled.all()  # the enable frames went out
        assert hw.state is LifecycleState.FAULT and hw.backend.state is LifecycleState.FAULT
        hw.close()
        time.sleep(0.05)
        assert np.all(emulator.kp == 0) and np.all(emulator.kd > 0)  # damping was sent ...
        assert not emulator.enabled.any()  # ... and every drive disabled
    finally:
        hw.close()
        emulator.close()


def test_emulated_damiao_drives_disable_themselves_on_silence_without_a_next_frame(talos):
    """As a real Damiao drive does: its CAN timeout acts when the host stops sending, not when the
    next frame comes."""
    hw, emulator, clock = configured_mit(talos, models=with_reply(talos, "damiao"), drive_timeout=0.1)
    try:
        hw.activate()
        state = hw.read()
        for _ in range(5):
            state = tick(hw, clock, hold(talos, state))
        assert emulator.enabled.all()
        time.sleep(0.05)
        assert emulator.enabled.all()  # within the timeout
        time.sleep(0.15)  # past it, and no frame since
        assert not emulator.enabled.any() and set(emulator.faults.values()) == {13}
    finally:
        hw.close()
        emulator.close()


def test_a_spoofed_reply_beside_the_drives_own_is_counted_and_neither_is_taken(talos, mit, monkeypatch):
    """Another node sends with the host's id a frame naming the knee, at 2 rad, just before the knee's
    own reply: two answers to one request. Neither is taken (the knee keeps its last reading, not the
    false 2 rad), each is counted, and four such ticks in a row are a fault naming the knee."""
    hw, emulator, clock, state = mit
    for _ in range(10):
        state = tick(hw, clock, hold(talos, state))
    knee = talos.joint_names.index("leg_left_4_joint")
    m = emulator.config.motors[knee]
    send_before_each_reply_of(monkeypatch, emulator, knee, HOST_ID, m.direction * 2.0 + m.zero_offset)
    held = state.q[knee]
    for k in range(3):
        state = tick(hw, clock, hold(talos, state))
        assert state.q[knee] == pytest.approx(held, abs=1e-9) and abs(state.q[knee] - 2.0) > 0.5
        assert hw.backend.duplicate_replies == k + 1 and hw.backend.missed[knee] == k + 1
    with pytest.raises(HardwareFault, match=r"leg_left_4_joint missed more than 3 replies in a row \(4 second answers"):
        tick(hw, clock, hold(talos, state))
    assert hw.report()["bus"]["duplicate_replies"] >= 4  # the fault's damping is answered twice too


@pytest.mark.parametrize("delay", [0.005, 0.02])
def test_replies_a_period_or_more_late_are_found_by_the_stale_checks_and_fault(talos, mit, monkeypatch, delay):
    """The knee's replies reach the host 5 ms (one control period) or 20 ms after the drive sent them,
    each with the state of when it was sent, ticks back to back: with nothing in the frame to tell
    them from fresh ones, most would be read as the current state. The checks that listen with
    nothing asked find them late, and two such checks in a row are a fault naming the knee, within
    a few checks (the first may come before the first late reply does; the knee's old reply, first on
    its bus, can end the wait before the bus's other drives answer, and they are named too)."""
    hw, emulator, clock, state = mit
    for _ in range(10):
        state = tick(hw, clock, hold(talos, state))
    knee = talos.joint_names.index("leg_left_4_joint")
    bus = emulator._buses[emulator.config.motors[knee].bus]
    reply, send = emulator._reply, bus.send

    def late(i):
        if i != knee:
            return reply(i)
        packed = []
        monkeypatch.setattr(bus, "send", packed.append)  # pack it now, send it later
        reply(i)
        monkeypatch.setattr(bus, "send", send)
        threading.Timer(delay, send, (packed[-1],)).start()

    monkeypatch.setattr(emulator, "_reply", late)
    every, ticks = hw.backend.config.stale_check_every, 0
    with pytest.raises(HardwareFault, match=r"leg_left_4_joint(, [a-z_0-9]+)* answered late in 2 stale checks"):
        while ticks < 5 * every:
            ticks += 1
            state = tick(hw, clock, hold(talos, state))
    assert ticks <= 4 * every and hw.backend.late_replies >= 2
