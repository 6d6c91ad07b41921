"""Robustness campaign: the 3 m walk at 0.25 m/s under pushes in 8 directions at 4 gait phases,
growing until the robot falls, and under model mismatch (mass, friction, latency). Each trial is
``robot-ctrl walk`` with disturbance options, run by the campaign runner (``eval/campaigns/campaign_runner.py``:
resumable, on a local or a Ray backend; each walk's report under ``DIR/trials/``); the campaign writes
``robustness.json`` and ``robustness.html`` (polar plot of the largest survived push per direction
and phase, beside the largest the LIP could capture from the state each push met, ``eval.push_capture``;
a pass/fail table per mismatch)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

from robot_ctrl.eval.campaigns.campaign_backends import Backend
from robot_ctrl.eval.campaigns.campaign_runner import run_campaign
from robot_ctrl.eval.campaigns.trial_process import Trial, TrialOutcome
from robot_ctrl.eval.reports.robustness_report import render_robustness
from robot_ctrl.wpg.params import WalkParams

WALK = ("walk", "--distance", "3", "--speed", "0.25")
DIRECTIONS = (0, 45, 90, 135, 180, -135, -90, -45)  # [deg] in the start frame, 0 forward, 90 left


def push_phases(single: float = WalkParams.single_support, double: float = WalkParams.double_support) -> dict:
    """Push start times [s] in the third step of the walk: start, middle and end of its single
    support, and its double support. The walk stands one sample, moves its ZMP onto the first stance
    foot (``start_transfer``), then steps: touch-down k comes at
    ``T + t_transfer + k t_single + (k − 1) t_double`` (T the 0.1 s sample; 1.6, 2.4, 3.2 s with the
    default 0.7 s + 0.1 s steps)."""
    p = WalkParams()
    start = round(p.sample_time + p.start_transfer + 2 * single + 2 * double, 6)
    mid = p.sample_time * int(single / 2 / p.sample_time + 1e-9)
    return {"single_start": start, "single_mid": round(start + mid, 6),
            "single_end": round(start + single - p.sample_time, 6), "double": round(start + single, 6)}


def walk_command(single: float = WalkParams.single_support, double: float = WalkParams.double_support) -> tuple:
    """The campaign's walk with this step timing (the default timing adds no option)."""
    if (single, double) == (WalkParams.single_support, WalkParams.double_support):
        return WALK
    return (*WALK, "--single-support", f"{single:g}", "--double-support", f"{double:g}")


PHASES = tuple(push_phases())  # their names
MAGNITUDES = (0.1, 0.2, 0.3, 0.4, 0.5)  # [N·s/kg]
BOUNDS = ("lip_capturable_ns_per_kg", "lip_capturable_own_timing_ns_per_kg")  # per push (eval.push_capture)
MISMATCH = {"mass ×0.85": ("--mass-scale", "0.85"), "mass ×1.15": ("--mass-scale", "1.15"),
            "friction ×0.3": ("--friction-scale", "0.3"), "friction ×0.4": ("--friction-scale", "0.4"),
            "friction ×1.0": ("--friction-scale", "1.0"), "latency 5 ms": ("--latency-ms", "5"),
            "latency 10 ms": ("--latency-ms", "10")}


TRIAL_TIMEOUT = 600.0  # [s] of wall time per walk


def _walked(report: dict | None) -> bool:
    return report is not None and not report["fell"]


def _row(trial: Trial, report: dict | None, outcome: TrialOutcome) -> dict:
    return {"id": trial.id, "command": " ".join(trial.argv), "fell": None if report is None else report["fell"],
            "wall_s": round(outcome.wall_s, 2), "error": outcome.error}


def _round(trials: list[Trial], out_dir: Path, backend: Backend, progress: bool, label: str) -> dict[str, dict | None]:
    """Each trial's report (None for one that wrote none), by id; KeyboardInterrupt if stopped."""
    run = run_campaign(trials, out_dir, backend, _row, timeout=TRIAL_TIMEOUT, progress=progress, label=label)
    if run.interrupted:
        raise KeyboardInterrupt("the campaign stopped; run the same command again to finish it")
    return {t.id: run.reports.get(t.id) for t in trials}


def run_robustness(out_dir: Path, backend: Backend, *, directions=DIRECTIONS, phases=PHASES,
                   magnitudes=MAGNITUDES, mismatch: dict = MISMATCH, log: Callable[[str], None] = print,
                   progress: bool = True, single: float = WalkParams.single_support,
                   double: float = WalkParams.double_support, command: str | None = None) -> dict:
    """Pushes grow per (direction, phase) until the first fall: one round of trials per magnitude,
    only for the cells that walked the round before. ``phases``: names of :func:`push_phases`;
    ``single``, ``double``: the walk's step timing [s], which sets its push times too. Every round
    runs on ``backend`` and resumes where a stopped campaign left it."""
    out_dir = Path(out_dir)
    walk, times = walk_command(single, double), push_phases(single, double)
    phases = {p: times[p] for p in phases}
    largest = {(d, p): 0.0 for d in directions for p in phases}
    capturable: dict[tuple, dict] = {cell: {} for cell in largest}  # the LIP's bounds (eval.push_capture)
    ended: dict[tuple, float | None] = {cell: None for cell in largest}  # final error after the largest survived
    standing = list(largest)  # cells that have not fallen yet
    for m in magnitudes:
        if not standing:
            break
        trials = [Trial(f"push_{p}_{d}_{m}", (*walk, "--push", f"{phases[p]}:{d}:{m}")) for d, p in standing]
        log(f"pushes of {m} N·s/kg: {len(trials)} walks")
        reports = _round(trials, out_dir, backend, progress, f"pushes of {m}")
        for cell, trial in zip(list(standing), trials):
            report = reports[trial.id]
            if not capturable[cell] and report is not None and report.get("push_capture"):
                capture = report["push_capture"][0]
                capturable[cell] = {k: capture[k] for k in BOUNDS}
            if _walked(report):
                largest[cell] = m
                ended[cell] = report["final_position_error_m"]
            else:
                standing.remove(cell)
    mismatch_trials = [Trial("mismatch_" + "".join(ch if ch.isalnum() else "_" for ch in name), (*walk, *args))
                       for name, args in mismatch.items()]
    reports = _round(mismatch_trials, out_dir, backend, progress, "mismatch")
    result = {
        "command": command, "walk": " ".join(walk), "push_duration_s": 0.1, "phases_s": phases, "magnitudes_ns_per_kg": list(magnitudes),
        "largest_survived_push": [{"direction_deg": d, "phase": p, "impulse_ns_per_kg": v,
                                   "final_position_error_m": ended[d, p]} | {k: capturable[d, p].get(k) for k in BOUNDS}
                                  for (d, p), v in largest.items()],
        "mismatch": [{"name": name, "walked": _walked(r), "fall_time_s": (r or {}).get("fall_time_s"),
                      "final_position_error_m": (r or {}).get("final_position_error_m"),
                      "error": None if r is not None else "no report"}
                     for name, r in zip(mismatch, reports.values())],
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "robustness.json").write_text(json.dumps(result, indent=2) + "\n")
    log(f"wrote {out_dir / 'robustness.json'} and {render_robustness(result, out_dir / 'robustness.html')}")
    return result
