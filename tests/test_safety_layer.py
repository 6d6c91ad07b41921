"""The SafetyLayer driven through its public API with a recording backend: whatever the command
and the measurement, what reaches the backend is finite, inside the position limits and within
the torque limit at the measured state; faults never leave a stiff hold; e-stop and watchdog do
not wait for a write in flight."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from robot_ctrl.hw.adapter import HardwareAdapter, LifecycleError
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
