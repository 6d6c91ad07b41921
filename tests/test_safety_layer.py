"""The SafetyLayer driven through its public API with a recording backend: whatever the command
and the measurement, what reaches the backend is finite, inside the position limits and within
the torque limit at the measured state; faults never leave a stiff hold; e-stop and watchdog do
not wait for a write in flight."""

from __future__ import annotations

import dataclasses
import threading
import time

import numpy as np
import pytest

from robot_ctrl.hw.adapter import HardwareAdapter, HardwareFault, LifecycleError
from robot_ctrl.hw.safety import SafetyLayer, SafetyLimits
from robot_ctrl.hw.servo_torque import servo_torque
from robot_ctrl.hw.types import JointCommand, JointState, LifecycleState

DT = 0.005


class RecordingBackend(HardwareAdapter):
    """Returns the state the test sets; records every command and e-stop with the wall time."""

    def __init__(self, nj: int, q: np.ndarray):
        super().__init__(nj)
        self.measured = JointState(t=0.0, q=q.copy(), dq=np.zeros(nj), tau=np.zeros(nj))
        self.sent: list[tuple[float, object]] = []
        self.write_delay = 0.0

    def _on_configure(self) -> None:
        pass

    def _on_estop(self) -> None:
        self.sent.append((time.monotonic(), "estop"))

    def _read(self) -> JointState:
        return self.measured

    def _write(self, command: JointCommand) -> None:
        time.sleep(self.write_delay)
        self.sent.append((time.monotonic(), command))

    def commands(self) -> list[JointCommand]:
        return [c for _, c in self.sent if isinstance(c, JointCommand)]


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def limits(talos):
    return SafetyLimits.from_robot(talos, DT, soft_start=0.05)


def layer(talos, limits, clock=None):
    backend = RecordingBackend(talos.nj, talos.joints_from_q(talos.q_half_sitting))
    hw = SafetyLayer(backend, limits, clock=clock or FakeClock())
    hw.configure()
    hw.activate()
    hw.read()
    return hw, backend


def hold(talos, q, **change):
    fields = dict(q=q.copy(), dq=np.zeros(talos.nj), kp=talos.kp.copy(), kd=talos.kd.copy(), tau_ff=np.zeros(talos.nj))
    fields.update(change)
    return JointCommand(**fields)


def assert_safe(command: JointCommand, state: JointState, limits: SafetyLimits):
    for name in ("q", "dq", "kp", "kd", "tau_ff"):
        assert np.all(np.isfinite(getattr(command, name))), name
    assert np.all(command.q >= limits.lower) and np.all(command.q <= limits.upper)
    assert np.all(command.kp <= limits.kp_max) and np.all(command.kd <= limits.kd_max)
    torque = servo_torque(command.q, command.dq, command.kp, command.kd, command.tau_ff, state.q, state.dq)
    assert np.all(np.abs(torque) <= limits.effort * (1 + 1e-9) + 1e-9), np.max(np.abs(torque) / limits.effort)


ADVERSARIAL = [0.0, -1.0, 1e-9, 1e3, 1e12, -1e12, np.nan, np.inf, -np.inf]


def random_field(rng, n, scale, allow_bad):
    value = rng.normal(0.0, scale, n)
    picks = rng.random(n) < 0.2
    value[picks] = rng.choice(ADVERSARIAL if allow_bad else [0.0, 1e3, 1e12, -1e12], picks.sum())
    return value


def test_random_and_adversarial_commands_and_measurements_stay_safe(talos, limits):
    """A property test: 3000 random commands (huge, negative, NaN, inf, wrong types) at random
    measured states (beyond the limits, at high velocity, some NaN, some not numbers)."""
    rng = np.random.default_rng(7)
    hw, backend = layer(talos, limits)
    clock, n, checked, command_faults = hw.clock, talos.nj, 0, 0
    for k in range(3000):
        clock.t += DT
        q_meas = rng.uniform(limits.lower - 0.3, limits.upper + 0.3)
        dq_meas = rng.uniform(-3, 3) * limits.velocity
        roll = rng.random()
        if roll < 0.02:
            q_meas[rng.integers(n)] = np.nan
        elif roll < 0.03:
            q_meas = q_meas.astype(str)
        elif roll < 0.04:
            q_meas = q_meas + 1j
        backend.measured = JointState(t=k * DT, q=q_meas, dq=dq_meas, tau=np.zeros(n))
        hw.read()
        if hw.state is not LifecycleState.ACTIVE:  # a bad measurement, or rejected commands 20 ms in a row
            assert roll < 0.04 or hw.interventions["command_fault"] > command_faults
            assert hw.mode == "damping" and backend.commands()[-1].kp.max() == 0  # latched, damping
            command_faults = hw.interventions["command_fault"]
            with pytest.raises(LifecycleError):
                hw.write(hold(talos, q_meas))
            hw.reset()
            hw.activate()
            continue
        bad = rng.random() < 0.1  # NaN and inf in one command of ten: the others reach the filter
        fields = {"q": q_meas + random_field(rng, n, 0.5, bad), "dq": random_field(rng, n, 5.0, bad),
                  "kp": np.abs(random_field(rng, n, 1.0, bad)) * talos.kp,
                  "kd": np.abs(random_field(rng, n, 1.0, bad)) * talos.kd, "tau_ff": random_field(rng, n, 200, bad)}
        if rng.random() < 0.02:
            fields["q"] = fields["q"].astype(complex)
        before = len(backend.sent)
        hw.write(JointCommand(**fields))
        for command in backend.commands()[-(len(backend.sent) - before):] if len(backend.sent) > before else []:
            assert_safe(command, backend.measured, limits)
            checked += 1
    assert checked > 2500
    assert hw.interventions["rejected_command"] > 100 and hw.interventions["bad_measurement"] >= 30
    assert hw.interventions["gain_clamped"] > 100 and hw.interventions["torque_clamped"] > 1000


def settled(talos, limits, dq):
    """The layer past its soft start at half-sitting, then a fresh measured state moving at ``dq``."""
    hw, backend = layer(talos, limits)
    q = backend.measured.q
    for _ in range(20):
        hw.clock.t += DT
        hw.write(hold(talos, q))
        hw.read()
    backend.measured = JointState(t=1.0, q=q, dq=dq, tau=np.zeros(talos.nj))
    hw.read()
    return hw, backend, q


def test_the_report_keeps_what_the_controller_demanded_before_the_clamp(talos, limits):
    """The servos deliver at most the effort limit; the report must still show that the controller
    asked for twice that, per joint."""
    hw, backend, q = settled(talos, limits, np.zeros(talos.nj))
    knee = talos.joint_names.index("leg_left_4_joint")
    tau_ff = np.zeros(talos.nj)
    tau_ff[knee] = 2.0 * limits.effort[knee]
    hw.clock.t += DT
    hw.write(hold(talos, q, tau_ff=tau_ff))
    demanded = hw.report()["demanded_peak_torque_ratio"]
    assert demanded[knee] == pytest.approx(2.0, abs=1e-3) and max(np.delete(demanded, knee)) < 0.01
    sent = backend.commands()[-1]
    assert abs(sent.tau_ff[knee]) <= limits.effort[knee] + 1e-9  # delivered within the limit


def test_the_issue_cases_are_bounded_at_the_measured_state(talos, limits):
    hw, backend, q = settled(talos, limits, limits.velocity.copy())
    moving = backend.measured
    cases = {
        "kd 50 at the velocity limit, kp 0": hold(talos, q, kp=np.zeros(talos.nj), kd=np.full(talos.nj, 50.0)),
        "kd 1e12": hold(talos, q, kd=np.full(talos.nj, 1e12)),
        "kp 1e12": hold(talos, q + 0.01, kp=np.full(talos.nj, 1e12)),
        "beyond the position limit": hold(talos, limits.upper + 1.0),
    }
    for name, command in cases.items():
        hw.clock.t += DT
        hw.write(command)
        sent = backend.commands()[-1]
        assert_safe(sent, moving, limits)
    assert np.all(backend.commands()[-2].kp <= limits.kp_max)  # kp 1e12 capped, not passed on


def test_a_bad_measurement_sends_damping_and_latches(talos, limits):
    hw, backend = layer(talos, limits)
    q = backend.measured.q.copy()
    for _ in range(20):
        hw.clock.t += DT
        hw.write(hold(talos, q))
        hw.read()
    for bad in (np.where(np.arange(talos.nj) == 3, np.nan, q), q.astype(str)):
        backend.measured = JointState(t=1.0, q=bad, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj))
        hw.read()
        damping = backend.commands()[-1]
        assert hw.state is LifecycleState.FAULT and hw.interventions["bad_measurement"] >= 1
        assert np.all(damping.kp == 0) and np.all(damping.tau_ff == 0) and np.all(np.isfinite(damping.q))
        np.testing.assert_allclose(damping.q, np.clip(q, limits.lower, limits.upper))  # the last good posture
        count = len(backend.sent)
        with pytest.raises(LifecycleError):
            hw.write(hold(talos, q))
        hw.clock.t += 10 * DT
        hw.check_watchdog()
        assert len(backend.sent) == count  # latched: nothing stiff follows
        backend.measured = JointState(t=1.1, q=q, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj))
        hw.reset()
        hw.activate()
        hw.read()



def test_a_measurement_is_judged_field_by_field_when_the_quick_check_fails(talos):
    """JointState.problem checks every array at once for a quick answer; a NaN in a body reading, an
    infinite time, another dtype or shape go to the field-by-field check, which names what is wrong."""
    nj, zero = talos.nj, np.zeros(talos.nj)
    assert JointState(t=0.0, q=np.full(nj, 1e308), dq=zero, tau=zero).problem(nj) is None
    wrench = {"left": np.array([0.0, 0.0, 400.0, 0.0, np.nan, 0.0]), "right": np.zeros(6)}
    state = JointState(t=0.0, q=zero, dq=zero, tau=zero, base_pos=np.zeros(3), foot_wrench=wrench)
    assert state.problem(nj) == "JointState.foot_wrench['left'] is not finite at [4]"
    assert JointState(t=np.inf, q=zero, dq=zero, tau=zero).problem(nj) == "JointState.t is not finite at [0]"
    assert JointState(t=0.0, q=zero.astype(np.float32), dq=zero, tau=zero).problem(nj) is None
    assert "q has shape (3,)" in JointState(t=0.0, q=np.zeros(3), dq=zero, tau=zero).problem(nj)


def test_a_replaced_state_equals_dataclasses_replace_and_leaves_the_original():
    """JointState.replaced skips the frozen dataclass's __init__; what it gives must not differ."""
    zero = np.zeros(3)
    state = JointState(t=0.5, q=zero, dq=zero, tau=zero, base_quat_xyzw=np.array([0.0, 0.0, 0.0, 1.0]),
                       foot_wrench={"left": np.zeros(6)}, floor_contacts=("hand",))
    turned = np.array([0.0, 0.0, 1.0, 0.0])
    replaced = state.replaced(base_quat_xyzw=turned, t=0.6)
    expected = dataclasses.replace(state, base_quat_xyzw=turned, t=0.6)
    assert type(replaced) is JointState
    assert {f.name: getattr(replaced, f.name) for f in dataclasses.fields(JointState)} == \
        {f.name: getattr(expected, f.name) for f in dataclasses.fields(JointState)}
    assert state.base_quat_xyzw[3] == 1.0 and state.t == 0.5
    with pytest.raises(dataclasses.FrozenInstanceError):
        replaced.t = 0.7
    with pytest.raises(TypeError, match="no fields \\['base_quat'\\]"):
        state.replaced(base_quat=turned)

@pytest.mark.realtime
def test_estop_does_not_wait_for_a_write_in_flight(talos, limits):
    hw, backend = layer(talos, limits, clock=time.monotonic)
    q = backend.measured.q
    hw.write(hold(talos, q))
    backend.write_delay = 0.3  # a bus write stuck for 300 ms
    writer = threading.Thread(target=hw.write, args=(hold(talos, q),))
    writer.start()
    time.sleep(0.02)
    begun = time.monotonic()
    hw.estop()
    took = time.monotonic() - begun
    writer.join()
    assert took < 0.05, f"estop() took {took * 1e3:.0f} ms"
    assert backend.sent[-1][1] == "estop"  # the stuck write landed, then the e-stop was sent again
    assert [c for _, c in backend.sent].count("estop") == 2 and hw.interventions["estop"] == 1
    with pytest.raises(LifecycleError):
        hw.write(hold(talos, q))


@pytest.mark.realtime
def test_watchdog_thread_trips_within_its_period_even_during_a_stuck_write(talos, limits):
    hw, backend = layer(talos, limits, clock=time.monotonic)
    q = backend.measured.q
    hw.start_watchdog()
    try:
        for k in range(5):  # a loop that reads a fresh state and writes every half period
            time.sleep(DT / 2)
            backend.measured = JointState(t=(k + 1) * DT, q=q, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj))
            hw.read()
            last_write = time.monotonic()
            hw.write(hold(talos, q))
        trips = hw.interventions["watchdog"]
        time.sleep(0.1)  # the controller stalls
        tripped_at = next(t for t, c in backend.sent
                          if t >= last_write and isinstance(c, JointCommand) and c.kp.max() == 0)
        delay = tripped_at - last_write
        assert hw.interventions["watchdog"] == trips + 1
        # The limit is 2 periods; the thread checks every period (+ scheduling on a loaded machine).
        assert limits.watchdog_periods * DT <= delay <= (limits.watchdog_periods + 1) * DT + 0.05, delay

        backend.measured = JointState(t=1.0, q=q, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj))
        hw.read()  # a fresh state
        hw.write(hold(talos, q))  # resumes
        assert hw.mode == "normal"
        backend.measured = JointState(t=1.005, q=q, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj))
        hw.read()
        assert hw.mode == "normal"
        backend.write_delay = 0.2
        writer = threading.Thread(target=hw.write, args=(hold(talos, q),))
        begun = time.monotonic()
        writer.start()
        while hw.interventions["watchdog"] < trips + 2 and time.monotonic() - begun < 0.15:
            time.sleep(0.001)
        assert hw.interventions["watchdog"] == trips + 2 and time.monotonic() - begun < 0.15  # not blocked by the write
        writer.join()
        assert backend.commands()[-1].kp.max() == 0  # the damping is sent again after the stuck write
    finally:
        hw.stop_watchdog()


def test_the_watchdog_is_armed_at_activation(talos, limits):
    hw, backend = layer(talos, limits)
    assert not backend.commands()
    hw.clock.t += 2.5 * DT  # activated, but the controller never writes
    hw.read()
    assert hw.mode == "damping" and hw.interventions["watchdog"] == 1
    assert backend.commands()[-1].kp.max() == 0



def test_a_run_that_ends_on_purpose_disarms_the_watchdog_until_the_next_write(talos, limits):
    hw, backend = layer(talos, limits)
    command = hold(talos, backend.measured.q)
    hw.write(command)
    hw.disarm_watchdog()  # the run ended: its report is built while the servos hold the last command
    for _ in range(10):
        hw.clock.t += DT
        backend.measured = dataclasses.replace(backend.measured, t=backend.measured.t + DT)
        hw.read()
    assert hw.mode == "normal" and hw.interventions["watchdog"] == 0
    assert backend.commands()[-1].kp.max() > 0  # nothing but the last command was sent
    hw.write(command)  # writing again arms it again
    hw.clock.t += 2.5 * DT
    hw.read()
    assert hw.mode == "damping" and hw.interventions["watchdog"] == 1

class Ticker:
    """Drives a layer tick by tick with fresh measurements of a robot standing still at ``q``."""

    def __init__(self, talos, limits, q=None, temperature=None):
        self.hw, self.backend = layer(talos, limits)
        self.q = self.backend.measured.q.copy() if q is None else q
        self.temperature, self.nj = temperature, talos.nj

    def __call__(self, command: JointCommand) -> JointCommand:
        self.hw.clock.t += DT
        t = self.backend.measured.t + DT
        self.backend.measured = JointState(t=t, q=self.q, dq=np.zeros(self.nj), tau=np.zeros(self.nj),
                                           temperature=self.temperature)
        self.hw.read()
        self.hw.write(command)
        return self.backend.commands()[-1]


def test_each_limit_clamps_its_own_side_and_is_reported_by_name(talos, limits):
    """Position, step, velocity and gain limits each hold on both sides, each violation is counted
    under its own name, and a command within every limit passes unchanged and uncounted. (The
    effort is raised so that the torque bound, tested above, changes nothing here.)"""
    limits = dataclasses.replace(limits, effort=limits.effort * 1e3, soft_start=0.0)
    tick = Ticker(talos, limits)
    q, step, a, b = tick.q, limits.step_limit, 2, 9  # two leg joints
    counts = lambda: dict(tick.hw.interventions)  # noqa: E731
    sent = tick(hold(talos, q))
    assert counts() == {} and np.array_equal(sent.q, q) and np.array_equal(sent.kp, talos.kp)

    def target(positions: dict[int, float]) -> np.ndarray:
        """The standing posture with the given joints' targets changed."""
        out = q.copy()
        out[list(positions)] = list(positions.values())
        return out

    sent = tick(hold(talos, target({a: limits.upper[a] + 0.5})))
    assert counts() == {"position_clamped": 1, "position_step_limited": 1}
    assert sent.q[a] == pytest.approx(q[a] + step[a]) and np.array_equal(np.delete(sent.q, a), np.delete(q, a))
    sent = tick(hold(talos, target({b: limits.lower[b] - 0.5})))
    assert counts() == {"position_clamped": 2, "position_step_limited": 2}
    # From the last target, not from the measured posture (which has not moved): joint a goes on
    # up by one step, joint b down by one.
    assert sent.q[a] == pytest.approx(q[a]) and sent.q[b] == pytest.approx(q[b] - step[b])
    sent = tick(hold(talos, target({a: q[a] + 3 * step[a], b: q[b] - 3 * step[b]})))
    assert sent.q[a] == pytest.approx(q[a] + step[a]) and sent.q[b] == pytest.approx(q[b] - 2 * step[b])
    sent = tick(hold(talos, target({a: q[a] + 3 * step[a], b: q[b] - 3 * step[b]})))
    assert sent.q[a] == pytest.approx(q[a] + 2 * step[a]) and sent.q[b] == pytest.approx(q[b] - 3 * step[b])
    assert counts() == {"position_clamped": 2, "position_step_limited": 4}  # b arrived in its last tick
    for _ in range(3):
        tick(hold(talos, q))  # back where it stands, a step at a time
    assert counts()["position_step_limited"] == 6  # counted once per tick

    dq = np.zeros(talos.nj)
    dq[a], dq[b] = 2 * limits.velocity[a], -0.5 * limits.velocity[b]
    sent = tick(hold(talos, q, dq=dq))
    assert sent.dq[a] == limits.velocity[a] and sent.dq[b] == dq[b] and counts()["velocity_clamped"] == 1
    dq[a], dq[b] = 0.0, -2 * limits.velocity[b]
    sent = tick(hold(talos, q, dq=dq))
    assert sent.dq[b] == -limits.velocity[b] and counts()["velocity_clamped"] == 2

    kp = talos.kp.copy()
    kp[a] = 2 * limits.kp_max[a]
    sent = tick(hold(talos, q, kp=kp))
    assert sent.kp[a] == limits.kp_max[a] and np.array_equal(np.delete(sent.kp, a), np.delete(kp, a))
    kd = talos.kd.copy()
    kd[b] = 2 * limits.kd_max[b]
    sent = tick(hold(talos, q, kd=kd))
    assert sent.kd[b] == limits.kd_max[b] and sent.kp[a] == talos.kp[a] and counts()["gain_clamped"] == 2
    assert set(counts()) == {"position_clamped", "position_step_limited", "velocity_clamped", "gain_clamped"}


def test_the_soft_start_ramps_stiffness_and_feedforward_and_a_hot_servo_is_derated(talos, limits):
    """kp and τ_ff rise as (k + 1) dt / soft_start over the soft start (k: ticks since activation),
    then hold; kd is not ramped. Without a soft start, and when it has ended, the gains pass as
    commanded (never above). A servo between its derating and fault temperatures is sent its kp
    scaled by 1 − 0.8 (T − T_derate) / (T_fault − T_derate)."""
    limits = dataclasses.replace(limits, effort=limits.effort * 1e3, soft_start=0.05)
    tick = Ticker(talos, limits)
    tau_ff = np.full(talos.nj, 2.0)
    ramps = []
    for _ in range(14):
        sent = tick(hold(talos, tick.q, tau_ff=tau_ff))
        ramps.append(sent.kp / talos.kp)
        np.testing.assert_allclose(sent.tau_ff, 2.0 * ramps[-1])
        np.testing.assert_array_equal(sent.kd, talos.kd)
    expected = np.minimum(1.0, DT * np.arange(1, 15) / 0.05)
    np.testing.assert_allclose(np.array(ramps), np.repeat(expected[:, None], talos.nj, axis=1))
    for soft_start in (0.0, 0.05):
        tick = Ticker(talos, dataclasses.replace(limits, soft_start=soft_start))
        for _ in range(11 if soft_start else 1):
            sent = tick(hold(talos, tick.q))
        np.testing.assert_array_equal(sent.kp, talos.kp)
    hot = np.full(talos.nj, 30.0)
    hot[3] = (limits.temperature_derate + limits.temperature_fault) / 2
    tick = Ticker(talos, dataclasses.replace(limits, soft_start=0.0), temperature=hot)
    sent = tick(hold(talos, tick.q))
    assert sent.kp[3] == pytest.approx(0.6 * talos.kp[3]) and np.array_equal(np.delete(sent.kp, 3),
                                                                                 np.delete(talos.kp, 3))


def test_stale_measurements_rejected_commands_and_a_silent_controller_each_trip_at_their_count(talos, limits):
    """Exact thresholds: damping after more than ``stale_periods`` control periods without a new
    measurement (not at them); a FAULT after ``rejected_fault_time`` of rejected commands in a row,
    a rejected command meanwhile repeating the last one sent; the watchdog after more than
    ``watchdog_periods`` periods without a write (not at them)."""
    limits = dataclasses.replace(limits, soft_start=0.0)
    tick = Ticker(talos, limits)
    hw, backend, q = tick.hw, tick.backend, tick.q
    tick(hold(talos, q))
    for k in range(1, 6):  # the robot's measurements stop: the same sample read again
        hw.clock.t += DT
        hw.read()
        hw.write(hold(talos, q))
        sent = backend.commands()[-1]
        stale = k > limits.stale_periods
        assert hw.interventions["stale_state"] == int(stale) and (sent.kp.max() == 0) == stale, k
    last = tick(hold(talos, q + 0.01))  # fresh again: the soft start resumes the servos
    assert hw.mode == "normal" and np.array_equal(last.kp, talos.kp)

    bad = hold(talos, q, kp=np.full(talos.nj, np.nan))
    rejections = round(limits.rejected_fault_time / DT)  # 4 periods
    for k in range(1, rejections):
        sent = tick(bad)
        assert hw.interventions["rejected_command"] == k and hw.state is LifecycleState.ACTIVE
        np.testing.assert_array_equal(sent.q, last.q)
        np.testing.assert_array_equal(sent.kp, last.kp)
    tick(hold(talos, q))  # one good command between them starts the count again
    for k in range(1, rejections):
        tick(bad)
    assert hw.state is LifecycleState.ACTIVE and hw.interventions["command_fault"] == 0
    sent = tick(bad)
    assert hw.state is LifecycleState.FAULT and hw.interventions["command_fault"] == 1 and sent.kp.max() == 0

    tick = Ticker(talos, limits)
    hw = tick.hw
    tick(hold(talos, tick.q))
    hw.clock.t += limits.watchdog_periods * DT
    hw.check_watchdog()
    assert hw.interventions["watchdog"] == 0
    hw.clock.t += 1e-6
    hw.check_watchdog()
    assert hw.interventions["watchdog"] == 1 and tick.backend.commands()[-1].kp.max() == 0


def test_measurements_beyond_a_limit_and_hot_servos_are_reported_once_and_bound_the_torque(talos, limits):
    """A joint measured beyond a limit by more than ``limit_tolerance`` is reported when it gets
    there, on either side, not again while it stays; a servo at its warning temperature is reported
    once; a servo being derated gets a torque bound of its derated effort."""
    limits = dataclasses.replace(limits, soft_start=0.0)
    tick = Ticker(talos, limits)
    hw, q, a, b = tick.hw, tick.q.copy(), 2, 9
    for value, count in ((limits.upper[a] + limits.limit_tolerance, 0),
                         (limits.upper[a] + 0.5 * limits.limit_tolerance, 0),
                         (limits.upper[a] + 2 * limits.limit_tolerance, 1), (limits.upper[a] + 0.1, 1),
                         (q[a], 1), (limits.lower[a] - limits.limit_tolerance, 1),
                         (limits.lower[a] - 0.5 * limits.limit_tolerance, 1),
                         (limits.lower[a] - 2 * limits.limit_tolerance, 2)):
        tick.q = q.copy()
        tick.q[a] = value
        tick(hold(talos, q))
        assert hw.interventions["position_beyond_limit"] == count, value
    tick.q = q.copy()
    tick.q[b] = limits.lower[b] - 0.1
    tick(hold(talos, q))
    assert hw.interventions["position_beyond_limit"] == 3

    temperature = np.full(talos.nj, 30.0)
    tick = Ticker(talos, limits, temperature=temperature)
    hw = tick.hw
    temperature[a] = limits.temperature_warn
    for _ in range(3):
        tick(hold(talos, tick.q))
    assert hw.interventions["temperature_warn"] == 1 and hw.interventions["temperature_derate"] == 0
    temperature[a] = (limits.temperature_derate + limits.temperature_fault) / 2
    tau_ff = np.zeros(talos.nj)
    tau_ff[a] = 0.9 * limits.effort[a]
    sent = tick(hold(talos, tick.q, tau_ff=tau_ff))
    torque = servo_torque(sent.q, sent.dq, sent.kp, sent.kd, sent.tau_ff, tick.q, np.zeros(talos.nj))
    assert torque[a] == pytest.approx(0.6 * limits.effort[a]) and hw.interventions["torque_clamped"] == 1
    tick(hold(talos, tick.q))
    assert hw.interventions["temperature_derate"] == 2  # counted per tick while derating
    temperature[a] = limits.temperature_derate  # at the derating temperature: not yet
    tick(hold(talos, tick.q))
    assert hw.interventions["temperature_derate"] == 2 and hw.state is LifecycleState.ACTIVE
    temperature[a] = limits.temperature_fault  # at the fault temperature: damping, FAULT latched
    with pytest.raises(LifecycleError):
        tick(hold(talos, tick.q))
    sent = tick.backend.commands()[-1]
    assert hw.state is LifecycleState.FAULT and hw.interventions["temperature_fault"] == 1 and sent.kp.max() == 0
    temperature[a] = 30.0
    hw.reset()  # cooled down: a later warning is reported again
    hw.activate()
    temperature[a] = limits.temperature_warn
    tick(hold(talos, tick.q))
    assert hw.interventions["temperature_warn"] == 2 and hw.state is LifecycleState.ACTIVE

    # Far beyond the fault temperature, a joint moving fast is damped within a fifth of its effort.
    temperature[:] = 30.0
    temperature[a] = limits.temperature_fault + 20.0
    tick = Ticker(talos, limits, temperature=temperature)
    tick.backend.measured = JointState(t=0.0, q=tick.q, dq=np.zeros(talos.nj), tau=np.zeros(talos.nj))
    dq = np.zeros(talos.nj)
    dq[a] = limits.velocity[a]
    tick.hw.clock.t += DT
    tick.backend.measured = JointState(t=DT, q=tick.q, dq=dq, tau=np.zeros(talos.nj), temperature=temperature)
    tick.hw.read()
    sent = tick.backend.commands()[-1]
    damping = servo_torque(sent.q, sent.dq, sent.kp, sent.kd, sent.tau_ff, tick.q, dq)
    assert tick.hw.state is LifecycleState.FAULT and abs(damping[a]) <= 0.2 * limits.effort[a] + 1e-9
    assert abs(damping[a]) > 0.0  # damping, bounded, not nothing


def test_the_first_target_stays_inside_the_limits_when_the_robot_starts_beyond_them(talos, limits):
    """The step limit counts from the measured posture at the first command: a joint measured beyond
    its limit by more than a step is still sent a target on the limit, not one step from where it is."""
    limits = dataclasses.replace(limits, effort=limits.effort * 1e3, soft_start=0.0)
    a, b = 2, 9
    q = talos.joints_from_q(talos.q_half_sitting)
    q[a], q[b] = limits.upper[a] + 0.1, limits.lower[b] - 0.1
    tick = Ticker(talos, limits, q=q)
    for _ in range(2):  # and the next step counts from the limit, not from beyond it
        sent = tick(hold(talos, np.clip(q, limits.lower, limits.upper)))
        assert sent.q[a] == limits.upper[a] and sent.q[b] == limits.lower[b]
    assert tick.hw.interventions["position_step_limited"] == 1


def test_the_watchdog_thread_does_not_keep_a_dead_controller_alive(talos, limits):
    """The watchdog runs in a daemon thread named for what it is: a controller process that dies
    without closing the hardware exits (its servos then time out on the bus), not hangs."""
    hw, _ = layer(talos, limits)
    hw.start_watchdog()
    try:
        watchdog = [t for t in threading.enumerate() if t.name == "safety-watchdog"]
        assert len(watchdog) == 1 and watchdog[0].daemon
    finally:
        hw.stop_watchdog()


def test_a_failing_backend_latches_a_fault_and_the_report_says_what_happened(talos, limits):
    """A backend call that raises: the layer counts ``backend_fault``, e-stops the backend, latches
    FAULT and raises a HardwareFault naming the call and the error. The report a run writes carries
    the interventions, the layer's mode and state, the demanded torque ratio per joint (3 decimals)
    and the bus counters. Closing a layer that is still active sends damping, then disables."""
    limits = dataclasses.replace(limits, soft_start=0.0)
    tick = Ticker(talos, limits)
    hw, backend, q = tick.hw, tick.backend, tick.q
    tau_ff = np.zeros(talos.nj)
    tau_ff[4] = 0.12345 * limits.effort[4]
    tick(hold(talos, q, tau_ff=tau_ff))
    backend.missing_replies, backend.late_replies = 3, 2

    def fail(command):
        raise OSError("bus off")

    backend._write = fail
    with pytest.raises(HardwareFault, match=r"RecordingBackend\.write: bus off; the servos were sent damping, FAULT"):
        tick(hold(talos, q))
    assert backend.sent[-1][1] == "estop"
    report = hw.report()
    assert report["interventions"] == {"backend_fault": 1} and report["mode"] == "off" and report["state"] == "fault"
    assert report["demanded_peak_torque_ratio"][4] == 0.123 and sum(report["demanded_peak_torque_ratio"]) == 0.123
    assert report["bus"] == {"missing_replies": 3, "late_replies": 2, "error_frames": 0, "foreign_frames": 0,
                              "duplicate_replies": 0}

    tick = Ticker(talos, limits)
    tick(hold(talos, tick.q))
    tick.hw.close()
    assert tick.backend.commands()[-1].kp.max() == 0 and tick.backend.state is LifecycleState.INACTIVE
    assert tick.hw.report()["mode"] == "off"

    # The report reads the same before the layer ever ran, after a deactivation and after an e-stop.
    fresh = SafetyLayer(RecordingBackend(talos.nj, tick.q), limits, clock=FakeClock())
    assert {k: fresh.report()[k] for k in ("interventions", "mode", "state")} == \
        {"interventions": {}, "mode": "off", "state": "unconfigured"}
    tick = Ticker(talos, limits)
    tick(hold(talos, tick.q))
    tick.hw.deactivate()
    assert tick.hw.report()["mode"] == "off" and tick.hw.report()["state"] == "inactive"
    tick.hw.activate()
    tick(hold(talos, tick.q))
    tick.hw.estop()
    report = tick.hw.report()
    assert report["mode"] == "off" and report["state"] == "estop" and report["interventions"] == {"estop": 1}
