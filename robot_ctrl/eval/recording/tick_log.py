"""Per-tick binary log of a run on any hardware (``--log FILE``), and its reader.

A file is one line of JSON (the robot, its joints and effort limits, the control period, the
safety layer's intervention kinds, the numpy dtype of a record), then one fixed-size record per
control tick: the measured state the command was computed from, the command, the safety layer's
mode and cumulative intervention counts, the bus statistics (replies missed in all and per motor
in a row, late replies, error frames) and the loop's lateness behind its deadline (real hardware).
Records are packed on the control thread and written by a thread of their own (a slow disk never
delays a tick), flushed every ``FLUSH_TICKS``: a run that dies leaves a log readable up to its last
whole record written. Values a backend does not measure are NaN (the base pose
on servo buses, temperatures in simulation). SI units, joint order of the robot config.

:func:`log_report` turns a log into the report of a simulated run (``RunMetrics``: falls, peak
torques against the limits) plus tracking, safety, bus and timing figures; ``robot-ctrl log``
writes it as ``report.json``, the series as ``timeseries.npz`` and renders ``report.html``.
"""

from __future__ import annotations

import json
import queue
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from robot_ctrl.eval.recording.fall import FallCriterion
from robot_ctrl.eval.recording.run_metrics import RunMetrics
from robot_ctrl.geometry import SIDES
from robot_ctrl.hw.safety import INTERVENTIONS, SafetyLayer, SafetyMode
from robot_ctrl.hw.types import JointState

FORMAT = "robot_ctrl tick log"
VERSION = 1
FLUSH_TICKS = 200  # [ticks] 1 s at 200 Hz
MODES = tuple(SafetyMode)  # the safety layer's mode, logged as its index


def record_dtype(nj: int) -> np.dtype:
    f8 = "<f8"
    return np.dtype([
        ("k", "<i8"), ("t", f8), ("wall", f8), ("lateness", f8),
        ("q", f8, nj), ("dq", f8, nj), ("tau", f8, nj), ("tau_demand", f8, nj), ("temperature", f8, nj),
        ("base_pos", f8, 3), ("base_quat_xyzw", f8, 4), ("foot_wrench", f8, (2, 6)), ("floor_contacts", "u1"),
        ("cmd_q", f8, nj), ("cmd_dq", f8, nj), ("cmd_kp", f8, nj), ("cmd_kd", f8, nj), ("cmd_tau_ff", f8, nj),
        ("mode", "u1"), ("interventions", "<i8", len(INTERVENTIONS)),
        ("missing_replies", "<i8"), ("missed", "<i4", nj), ("late_replies", "<i8"), ("error_frames", "<i8"),
    ])


class TickLogWriter:
    """A ControlLoop recorder writing robot ``index``'s ticks to ``path``; :meth:`close` it."""

    def __init__(self, path: Path, robot, hw: SafetyLayer, control_dt: float, pacer=None, index: int = 0):
        self.path, self.hw, self.pacer, self.index = Path(path), hw, pacer, index
        self.dtype = record_dtype(robot.nj)
        header = {"format": FORMAT, "version": VERSION, "robot": robot.name, "joint_names": list(robot.joint_names),
                  "effort": [float(e) for e in robot.effort], "control_dt": control_dt,
                  "interventions": list(INTERVENTIONS), "modes": list(MODES), "start_unix_s": time.time(),
                  "dtype": [list(field) if len(field) == 2 else [field[0], field[1], list(field[2])]
                            for field in self.dtype.descr]}
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.path.open("wb")
        self._file.write(json.dumps(header).encode() + b"\n")
        self._record = np.zeros(1, self.dtype)
        self._last = None
        self.ticks = 0
        self._records: queue.SimpleQueue[bytes | None] = queue.SimpleQueue()
        self._writer = threading.Thread(target=self._write_records, name="tick-log", daemon=True)
        self._writer.start()

    def _write_records(self) -> None:
        written = 0
        while (record := self._records.get()) is not None:
            self._file.write(record)
            written += 1
            if written % FLUSH_TICKS == 0:
                self._file.flush()

    def on_command(self, tick) -> None:
        self._write(tick.k, tick.states[self.index], tick.commands[self.index])

    def on_state(self, tick) -> None:
        self._last = tick

    def close(self) -> None:
        """Write the last state read (its command fields NaN: no command was computed from it)."""
        if self._last is not None:
            self._write(self._last.k + 1, self._last.states[self.index], None)
            self._last = None
        if self._writer.is_alive():
            self._records.put(None)
            self._writer.join()
        self._file.close()

    def _write(self, k: int, s, c) -> None:
        r, hw = self._record[0], self.hw
        backend = hw.backend
        r["k"], r["t"], r["wall"] = k, s.t, time.monotonic()
        r["lateness"] = self.pacer.lateness[-1] if self.pacer is not None and self.pacer.lateness else np.nan
        r["q"], r["dq"], r["tau"] = s.q, s.dq, s.tau
        r["tau_demand"] = s.tau_demand if s.tau_demand is not None else np.nan
        r["temperature"] = s.temperature if s.temperature is not None else np.nan
        r["foot_wrench"] = [s.foot_wrench[side] for side in SIDES] if s.foot_wrench is not None else np.nan
        r["floor_contacts"] = len(s.floor_contacts)
        r["base_pos"] = s.base_pos if s.base_pos is not None else np.nan
        r["base_quat_xyzw"] = s.base_quat_xyzw if s.base_quat_xyzw is not None else np.nan
        for name in ("q", "dq", "kp", "kd", "tau_ff"):
            r["cmd_" + name] = getattr(c, name) if c is not None else np.nan
        r["mode"] = MODES.index(hw.mode)
        r["interventions"] = [hw.interventions[kind] for kind in INTERVENTIONS]
        r["missing_replies"], r["missed"] = backend.missing_replies, backend.missed
        r["late_replies"], r["error_frames"] = backend.late_replies, backend.error_frames
        self._records.put(self._record.tobytes())
        self.ticks += 1


@contextmanager
def open_tick_log(path: Path | None, robot, hw: SafetyLayer, control_dt: float, pacer=None) -> Iterator[list]:
    """The recorders to add to a run: ``[TickLogWriter]`` writing ``path``, or none without a path."""
    if path is None:
        yield []
        return
    writer = TickLogWriter(path, robot, hw, control_dt, pacer)
    try:
        yield [writer]
    finally:
        writer.close()


@dataclass(frozen=True)
class TickLog:
    header: dict
    records: np.ndarray  # structured, ``record_dtype``


def read_tick_log(path: Path) -> TickLog:
    """The header and every whole record of a log; ValueError naming the file if it is not one."""
    path = Path(path)
    data = path.read_bytes()
    line, _, body = data.partition(b"\n")
    try:
        header = json.loads(line)
    except (UnicodeDecodeError, json.JSONDecodeError):
        header = None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise ValueError(f"{path} is not a robot_ctrl tick log")
    if header.get("version") != VERSION:
        raise ValueError(f"{path}: tick log version {header.get('version')}, this robot_ctrl reads version {VERSION}")
    dtype = np.dtype([tuple(field[:2]) + ((tuple(field[2]),) if len(field) == 3 else ()) for field in header["dtype"]])
    whole = len(body) // dtype.itemsize * dtype.itemsize
    if whole == 0:
        raise ValueError(f"{path} holds no tick: the run stopped before its first one (its header alone)")
    return TickLog(header, np.frombuffer(body[:whole], dtype=dtype))


def log_report(log: TickLog) -> dict:
    """The run's report from its log: ``RunMetrics`` (falls where the base was measured, peak
    torques), command tracking, safety interventions, bus statistics and loop timing."""
    h, r = log.header, log.records
    names = tuple(h["joint_names"])
    base_measured = bool(np.isfinite(r["base_pos"]).all())
    metrics = RunMetrics(names, np.array(h["effort"]), FallCriterion(float(r["base_pos"][0, 2]) if base_measured
                                                                     else float("nan")))
    for rec in r[1:]:  # as a run's metrics: the states read after each command
        metrics.update(JointState(
            t=float(rec["t"]), q=rec["q"], dq=rec["dq"], tau=rec["tau"],
            tau_demand=rec["tau_demand"] if np.isfinite(rec["tau_demand"]).all() else None,
            base_pos=rec["base_pos"] if base_measured else None,
            foot_wrench=dict(zip(SIDES, rec["foot_wrench"])) if np.isfinite(rec["foot_wrench"]).all() else None,
            floor_contacts=("a body other than the feet",) * int(rec["floor_contacts"] > 0)))
    commanded = r[np.isfinite(r["cmd_q"]).all(axis=1)]
    if len(commanded) == 0:
        raise ValueError("the log has no command")
    error = np.abs(commanded["cmd_q"] - commanded["q"])  # each command against the state it was computed from
    worst = int(error.max(axis=0).argmax())
    final = r[-1]
    interventions = {kind: int(n) for kind, n in zip(h["interventions"], final["interventions"]) if n}
    lateness = r["lateness"][np.isfinite(r["lateness"])] * 1e3
    timing = None if lateness.size == 0 else {
        "median_ms": round(float(np.median(lateness)), 3), "p99_ms": round(float(np.percentile(lateness, 99)), 3),
        "max_ms": round(float(lateness.max()), 3),
        "late_ticks": int((lateness > 1e3 * h["control_dt"]).sum())}
    return metrics.report() | {
        "robot": h["robot"], "ticks": int(len(r)), "control_rate_hz": round(1.0 / h["control_dt"], 3),
        "base_measured": base_measured,
        "tracking_error_rms_rad": round(float(np.sqrt(np.mean(error**2))), 5),
        "tracking_error_max_rad": round(float(error.max()), 5), "tracking_error_max_joint": names[worst],
        "safety": {"interventions": interventions, "final_mode": h["modes"][int(final["mode"])],
                   "damping_ticks": int((r["mode"] == MODES.index(SafetyMode.DAMPING)).sum())},
        "bus": {"missing_replies": int(final["missing_replies"]), "late_replies": int(final["late_replies"]),
                "error_frames": int(final["error_frames"]),
                "longest_miss_streak": {n: int(m) for n, m in zip(names, r["missed"].max(axis=0)) if m}},
        "timing": timing,
    }


def log_series(log: TickLog) -> dict[str, np.ndarray]:
    """The arrays the HTML report plots for a log (``eval/reports/html_report.py``)."""
    r = log.records
    return {"log_t": r["t"], "log_q": r["q"], "log_cmd_q": r["cmd_q"], "log_tau": r["tau"],
            "log_lateness": r["lateness"], "log_mode": r["mode"], "log_missing_replies": r["missing_replies"],
            "log_joint_names": np.array(log.header["joint_names"]), "log_effort": np.array(log.header["effort"])}
