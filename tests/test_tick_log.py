"""The per-tick binary log (``--log``) and ``robot-ctrl log``: the report a log gives is the run's."""

import json
import re

import numpy as np

from robot_ctrl.cli import main
from robot_ctrl.eval.recording.tick_log import log_report, read_tick_log

SAME = ("fell", "fall_time_s", "time_s", "peak_torque_ratio", "peak_torque_joint", "peak_torque_nm", "peak_grf_n")


def test_a_walks_log_gives_the_runs_report(tmp_path, capsys):
    run, log = tmp_path / "run", tmp_path / "logs" / "walk.log"
    assert main(["walk", "--distance", "0.5", "--quiet", "--out", str(run), "--log", str(log)]) == 0
    assert main(["log", str(log)]) == 0
    walked = json.loads((run / "report.json").read_text())
    logged = json.loads((tmp_path / "logs" / "walk" / "report.json").read_text())
    assert {k: logged[k] for k in SAME} == {k: walked[k] for k in SAME}
    records = read_tick_log(log).records
    assert logged["ticks"] == len(records) == round(walked["time_s"] / 0.005) + 1  # every tick and the last state
    assert np.all(np.diff(records["t"]) > 0) and np.all(np.isnan(records["cmd_q"][-1]))
    assert 0 < logged["tracking_error_rms_rad"] < logged["tracking_error_max_rad"] < 0.05
    assert logged["safety"] == {"interventions": {}, "final_mode": "normal", "damping_ticks": 0}
    assert logged["base_measured"] is True and logged["timing"] is None  # a simulation keeps no deadlines
    page = (tmp_path / "logs" / "walk" / "report.html").read_text()
    assert re.findall(r'<img alt="([^"]+)"', page) == [
        "Peak joint torques against their limits", "Command and measurement of the joints tracked worst",
        "Joint torques relative to their limits (damping shaded)"]
    # A run that died mid-write leaves a log readable up to its last whole record.
    data = log.read_bytes()
    log.write_bytes(data[: len(data) - records.itemsize // 2])
    assert len(read_tick_log(log).records) == len(records) - 1
    assert log_report(read_tick_log(log))["ticks"] == len(records) - 1


def test_what_is_not_a_log_is_refused_in_one_line(tmp_path, capsys):
    text = tmp_path / "notes.txt"
    text.write_text("not a log\n")
    assert main(["log", str(text)]) == 2
    assert "is not a robot_ctrl tick log" in capsys.readouterr().err
    assert main(["log", str(tmp_path / "missing.log")]) == 2
    assert main(["walk", "--distance", "1", "--log", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
    # An --out that cannot take the report is refused before the run, not after it.
    assert main(["walk", "--distance", "1", "--out", str(text)]) == 2
    assert f"--out {text} is a file, not a folder" in capsys.readouterr().err
    assert main(["robustness", "--quick", "--out", str(text / "sub")]) == 2
    assert f"--out {text / 'sub'}: {text} is a file, not a folder" in capsys.readouterr().err


def test_the_log_is_written_off_the_control_thread(talos, tmp_path, capsys):
    """The control thread only packs a record; a thread of the log's own writes it (a slow disk must
    not delay a tick)."""
    import threading
    from types import SimpleNamespace

    from robot_ctrl.eval.recording.tick_log import TickLogWriter
    from robot_ctrl.hw.safety import SafetyLayer, SafetyLimits
    from robot_ctrl.hw.types import JointCommand
    from robot_ctrl.sim.mujoco_backend import MujocoBackend

    hw = SafetyLayer(MujocoBackend(talos), SafetyLimits.for_simulation(talos), clock=None)
    hw.bring_up()
    state = hw.read()
    writer = TickLogWriter(tmp_path / "ticks.log", talos, hw, 0.005)
    writers = []

    class Spy:  # the log file, noting which thread writes to it
        def __init__(self, file):
            self.file = file

        def write(self, data):
            writers.append(threading.current_thread().name)
            return self.file.write(data)

        def flush(self):
            self.file.flush()

        def close(self):
            self.file.close()

    writer._file = Spy(writer._file)
    zero = np.zeros(talos.nj)
    command = JointCommand(q=state.q, dq=zero, kp=talos.kp, kd=talos.kd, tau_ff=zero)
    for k in range(5):
        writer.on_command(SimpleNamespace(k=k, states=[state], commands=[command]))
    writer.close()
    hw.close()
    assert writers == ["tick-log"] * 5 and len(read_tick_log(tmp_path / "ticks.log").records) == 5
    # A run that stopped before its first tick leaves the header alone: refused in one line.
    header = (tmp_path / "ticks.log").read_bytes().partition(b"\n")[0] + b"\n"
    (tmp_path / "empty.log").write_bytes(header)
    assert main(["log", str(tmp_path / "empty.log")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("empty.log holds no tick: the run stopped before its first one (its header alone)")
    assert len(err.splitlines()) == 1


def test_a_record_holds_what_its_tick_had_and_nan_where_it_had_nothing(talos, tmp_path):
    """What a tick measured and commanded, field by field; NaN where the state has no such reading
    (no wrench, temperature, base or demand) or the tick no command (the last state, written at
    ``close``); the pacer's latest lateness; a header naming the robot and the record's layout."""
    import dataclasses
    import threading
    from collections import deque
    from types import SimpleNamespace

    from robot_ctrl.eval.recording.tick_log import TickLogWriter
    from robot_ctrl.hw.safety import SafetyLayer, SafetyLimits
    from robot_ctrl.hw.types import JointCommand
    from robot_ctrl.sim.mujoco_backend import MujocoBackend

    hw = SafetyLayer(MujocoBackend(talos), SafetyLimits.for_simulation(talos), clock=None)
    hw.bring_up()
    full = dataclasses.replace(hw.read(), tau_demand=np.full(talos.nj, 1.5), temperature=np.full(talos.nj, 41.0))
    bare = dataclasses.replace(full, t=full.t + 0.005, tau_demand=None, temperature=None, foot_wrench=None,
                               base_pos=None, base_quat_xyzw=None)
    zero = np.zeros(talos.nj)
    command = JointCommand(q=full.q + 0.01, dq=zero + 0.2, kp=talos.kp, kd=talos.kd, tau_ff=zero + 3.0)
    pacer = SimpleNamespace(lateness=deque([0.001, 0.0015, 0.0025]))
    path = tmp_path / "logs" / "a" / "ticks.log"
    writer = TickLogWriter(path, talos, hw, 0.005, pacer)
    writer.on_command(SimpleNamespace(k=0, states=[full], commands=[command]))
    writer.on_command(SimpleNamespace(k=1, states=[bare], commands=[command]))
    writer.on_state(SimpleNamespace(k=1, states=[bare]))
    assert [t.daemon for t in threading.enumerate() if t.name == "tick-log"] == [True]  # never keeps a dead run
    writer.close()
    writer.close()  # a second close writes nothing more
    hw.close()
    log = read_tick_log(path)
    r = log.records
    assert writer.ticks == 3 and r["k"].tolist() == [0, 1, 2] and r["t"].tolist() == [full.t, bare.t, bare.t]
    assert r["lateness"].tolist() == [0.0025] * 3 and r["floor_contacts"].tolist() == [0, 0, 0]
    assert r["mode"].tolist() == [log.header["modes"].index("normal")] * 3
    np.testing.assert_array_equal(r["q"][0], full.q)
    np.testing.assert_array_equal(r["tau_demand"][0], full.tau_demand)
    np.testing.assert_array_equal(r["foot_wrench"][0], [full.foot_wrench["left"], full.foot_wrench["right"]])
    np.testing.assert_array_equal(r["base_pos"][0], full.base_pos)
    np.testing.assert_array_equal(r["base_quat_xyzw"][0], full.base_quat_xyzw)
    for name in ("q", "dq", "kp", "kd", "tau_ff"):
        np.testing.assert_array_equal(r["cmd_" + name][1], getattr(command, name))
        assert np.all(np.isnan(r["cmd_" + name][2])), name  # the last state: no command
    for name in ("tau_demand", "temperature", "foot_wrench", "base_pos", "base_quat_xyzw"):
        assert np.all(np.isnan(r[name][1])), name
    np.testing.assert_array_equal(r["temperature"][0], full.temperature)
    header = log.header
    assert header["robot"] == "talos" and header["joint_names"] == list(talos.joint_names)
    assert header["effort"] == [float(e) for e in talos.effort] and header["control_dt"] == 0.005
    assert header["interventions"][0] == "estop" and header["modes"][0] == "off" and header["start_unix_s"] > 1.7e9
    assert [field[0] for field in header["dtype"]][:3] == ["k", "t", "wall"]
