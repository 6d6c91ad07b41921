"""Drawer campaigns: many walk-and-reach trials, their rows and their summary per method and speed
class (thesis 3.8.3, Table 3.1 and Figs. 3.41, 3.47).

A trial is one ``robot-ctrl drawer`` run: distance (or, in a room, the cabinet's pose and the
room), slot, speed class, an optional goal jump, the dynamic filter and the method (``METHODS``: how a
trial becomes a command line; the comparison methods of the thesis add entries). Trials come from a
text file (:func:`read_trials`) or are drawn at random: at distances beyond every training sequence's
goal (:func:`draw_trials`), or as cabinets anywhere in random rooms (:func:`draw_poses`). The runner
(``eval/campaigns/campaign_runner.py``) makes them resumable and runs them on a local or a Ray backend.
Each trial's settings are checked as the drawer command checks them (``DrawerTask.check``, by the
command line, before anything runs).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from robot_ctrl.eval.campaigns.campaign_backends import Backend
from robot_ctrl.eval.campaigns.campaign_runner import CampaignRun, run_campaign
from robot_ctrl.eval.campaigns.trial_process import Trial, TrialOutcome
from robot_ctrl.eval.recording.drawer_recorder import failed_criteria
from robot_ctrl.eval.reports.campaign_report import demonstrations_label, render_campaign
from robot_ctrl.eval.reports.transition_postures import (
    TRANSITION_DISTANCES,
    TRANSITION_SLOT,
    draw_transition_postures,
    transition_postures,
    transition_summary,
)
from robot_ctrl.geometry.drawer_geometry import SLOTS
from robot_ctrl.modes import FilterMode, SpeedClass
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.synthesis.demonstrations import kinematic_dataset_path
from robot_ctrl.synthesis.learned import load_primitives

#: Where random trials' cabinets stand [m] from the start pelvis. Every training sequence's goal
#: lies within 1.83 m (the synthesis's 1.05-1.53 m, plus the walk before it starts): these are new.
DRAWN_DISTANCES = (2.0, 5.5)
DEFAULT_SPEEDS = (SpeedClass.SLOW, SpeedClass.MIDDLE, SpeedClass.FAST)
#: Random rooms: each side [m] uniform in ``DRAWN_ROOM_SIDES``, the cabinet's back against a wall
#: with probability ``AGAINST_WALL_SHARE``; its front panel ``DRAWN_POSE_DISTANCES`` [m] from the start
#: in any direction, facing any way. A draw whose front cannot be reached is drawn again.
DRAWN_ROOM_SIDES = (5.0, 8.0)
AGAINST_WALL_SHARE = 0.5
DRAWN_POSE_DISTANCES = (1.2, 6.0)
MAX_DRAWS = 100  # per trial: draws of a pose before the campaign gives up on finding a reachable one
TRIAL_TIMEOUT = 600.0  # [s] of wall time per trial; the longest drawer trial takes about a minute here


@dataclass(frozen=True)
class DrawerTrial:
    index: int  # position in the campaign (names its folder)
    method: str
    distance: float  # [m] cabinet from the start pelvis
    slot: str
    speed: SpeedClass
    jump: tuple[float, float] | None = None  # (time [s], new distance [m])
    dynfilter: FilterMode = FilterMode.FULL
    seed: int | None = None  # the draw's seed (random trials)
    dataset: str | None = None  # demonstration set of the primitives (None: the robot's); a path every worker reads
    sources: str = "3+2"  # periodic sources of the primitives' mixture model, FIRST+EXTRA
    robot: str | None = None  # robot config name (None: the command line's default robot)
    cabinet: tuple[float, float, float] | None = None  # in a room: (x [m], y [m], front yaw [deg]), start frame
    room: tuple[float, float] = (6.0, 6.0)  # [m] width along the cabinet's front, depth along the way it faces
    free_standing: bool = False  # the cabinet's back not against a wall

    @property
    def id(self) -> str:
        if self.cabinet is None:
            where = f"{self.distance:.3f}m"
        else:
            x, y, yaw = self.cabinet
            where = f"at{x:+.2f}{y:+.2f}{yaw:+.0f}deg"
        return f"{self.index:03d}_{self.method}_{self.sources}_{self.slot}_{where}_{self.speed.value}"

    def trial(self) -> Trial:
        return Trial(self.id, METHODS[self.method](self))


def _ours(t: DrawerTrial) -> tuple[str, ...]:
    """The method of the thesis: synthesis → WPG → dynamic filter → stack of tasks."""
    jump = ("--goal-jump", f"{t.jump[0]:g}:{t.jump[1]:g}") if t.jump else ()
    dataset = ("--dataset", t.dataset) if t.dataset else ()
    robot = ("--robot", t.robot) if t.robot else ()
    if t.cabinet is None:
        where: tuple[str, ...] = ("--distance", f"{t.distance:g}")
    else:  # one word: a negative X would read as an option
        where = ("--cabinet={:g},{:g},{:g}".format(*t.cabinet), "--room", "{:g},{:g}".format(*t.room),
                 *(("--free-standing",) if t.free_standing else ()))
    return ("drawer", *robot, *where, "--slot", t.slot, "--speed", t.speed.value,
            "--dynfilter", t.dynfilter.value, "--sources", t.sources, *jump, *dataset, "--no-html")


def _ours_no_feedback(t: DrawerTrial) -> tuple[str, ...]:
    """The same without the commander's position loops: what the synthesis itself achieves."""
    return (*_ours(t), "--no-position-feedback")


def _naive(t: DrawerTrial) -> tuple[str, ...]:
    """The naive baseline (thesis 3.8.4): every joint learned from the feasible runs, played on the servos."""
    return (*_ours(t), "--method", "naive")


#: Method name → the command line of one trial. ``wpg-direct`` (the thesis's "WPG" of Fig. 3.47) is
#: the generator of the feasible training runs applied to the new goal: the whole pipeline driven
#: by the primitives those runs were played from (the kinematic set, our stand-in for the thesis's
#: primitives learned from human data; :func:`method_dataset`), not by primitives learned from them.
METHODS: dict[str, Callable[[DrawerTrial], tuple[str, ...]]] = {"ours": _ours, "ours-no-feedback": _ours_no_feedback,
                                                                 "naive": _naive, "wpg-direct": _ours}


def method_dataset(method: str, dataset: str | None, robot: str) -> str | None:
    """The demonstration set a method's primitives are learned from (``dataset``: the campaign's
    ``--dataset``, None for the robot's default)."""
    return str(kinematic_dataset_path(robot)) if method == "wpg-direct" else dataset


def parse_methods(text: str) -> tuple[str, ...]:
    methods = tuple(m.strip() for m in text.split(",") if m.strip())
    unknown = [m for m in methods if m not in METHODS]
    if not methods or unknown:
        raise ValueError(f"method {', '.join(unknown) or repr(text)} is not one of {', '.join(METHODS)}")
    return methods


def parse_speeds(text: str) -> tuple[SpeedClass, ...]:
    return tuple(SpeedClass.parse(s.strip()) for s in text.split(",") if s.strip()) or DEFAULT_SPEEDS


def read_trials(path: Path, methods: Sequence[str], dynfilter: FilterMode) -> list[DrawerTrial]:
    """One trial per line, ``#`` comments; each line runs once per method. A line is either
    ``distance slot speed [jump_time jump_distance]`` (the cabinet straight ahead) or, in a room,
    ``X,Y,YAW_DEG [slot] [speed] [room=W,D] [free-standing]`` (the cabinet's pose in the start frame;
    by default front_left, nominal, a 6 x 6 m room with the cabinet's back against a wall).
    ValueError names the line."""
    trials = []
    for number, line in enumerate(Path(path).read_text().splitlines(), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        where = f"{path}:{number}"
        try:
            fields = (_pose_trial if "," in words[0] else _distance_trial)(words, f", got {line.strip()!r}")
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        for method in methods:
            trials.append(DrawerTrial(len(trials), method, dynfilter=dynfilter, **fields))
    if not trials:
        raise ValueError(f"{path}: no trial in it")
    return trials


def _distance_trial(words: list[str], got: str) -> dict:
    if len(words) not in (3, 5):
        raise ValueError(f"expected 'distance slot speed [jump_time jump_distance]'{got}")
    try:
        distance, jump = float(words[0]), (float(words[3]), float(words[4])) if len(words) == 5 else None
    except ValueError:
        raise ValueError(f"distance and jump must be numbers{got}") from None
    return dict(distance=distance, slot=_slot(words[1]), speed=SpeedClass.parse(words[2]), jump=jump)


def _pose_trial(words: list[str], got: str) -> dict:
    x, y, yaw = _numbers(words[0], "the cabinet's pose X,Y,YAW_DEG", 3, got)
    fields = dict(distance=round(float(np.hypot(x, y)), 3), cabinet=(x, y, yaw), slot="front_left",
                  speed=SpeedClass.NOMINAL)
    for word in words[1:]:
        if word in SLOTS:
            fields["slot"] = word
        elif word.startswith("room="):
            fields["room"] = _numbers(word.removeprefix("room="), "room=W,D", 2, got)
        elif word == "free-standing":
            fields["free_standing"] = True
        else:
            try:
                fields["speed"] = SpeedClass.parse(word)
            except ValueError:
                raise ValueError(f"{word!r} is not a slot ({', '.join(SLOTS)}), a speed class, room=W,D or "
                                 f"free-standing{got}") from None
    return fields


def _numbers(text: str, what: str, n: int, got: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n or not all(np.isfinite(values)):
        raise ValueError(f"{what} must be {n} finite numbers{got}")
    return values


def _slot(word: str) -> str:
    if word not in SLOTS:
        raise ValueError(f"slot {word!r} is not one of {', '.join(SLOTS)}")
    return word


def draw_trials(n: int, seed: int, speeds: Sequence[SpeedClass], methods: Sequence[str],
                dynfilter: FilterMode) -> list[DrawerTrial]:
    """``n`` trials per method: distances uniform in ``DRAWN_DISTANCES`` (mm resolution), slots
    uniform, speed classes in turn (as the thesis's 10 per class)."""
    rng = np.random.default_rng(seed)
    draws = [(round(float(rng.uniform(*DRAWN_DISTANCES)), 3), str(rng.choice(SLOTS)), speeds[k % len(speeds)])
             for k in range(n)]
    return [DrawerTrial(i * len(methods) + j, method, d, slot, speed, None, dynfilter, seed)
            for i, (d, slot, speed) in enumerate(draws) for j, method in enumerate(methods)]


def draw_poses(n: int, seed: int, speeds: Sequence[SpeedClass], methods: Sequence[str], dynfilter: FilterMode,
               reachable: Callable[[DrawerTrial], bool]) -> list[DrawerTrial]:
    """``n`` trials per method in random rooms (``DRAWN_ROOM_SIDES``, ``AGAINST_WALL_SHARE``), the
    cabinet's front ``DRAWN_POSE_DISTANCES`` from the start in a uniform direction, facing a uniform
    heading (cm and degree resolution), slots uniform, speed classes in turn; a draw that
    ``reachable`` refuses is drawn again. ValueError when ``MAX_DRAWS`` draws find none."""
    rng = np.random.default_rng(seed)
    draws = []
    for k in range(n):
        for _ in range(MAX_DRAWS):
            room = (round(float(rng.uniform(*DRAWN_ROOM_SIDES)), 2), round(float(rng.uniform(*DRAWN_ROOM_SIDES)), 2))
            free = bool(rng.uniform() >= AGAINST_WALL_SHARE)
            r, bearing = rng.uniform(*DRAWN_POSE_DISTANCES), rng.uniform(-np.pi, np.pi)
            x, y = round(float(r * np.cos(bearing)), 2), round(float(r * np.sin(bearing)), 2)
            yaw = float(round(rng.uniform(-180.0, 180.0)))
            trial = DrawerTrial(k, methods[0], round(float(np.hypot(x, y)), 3), str(rng.choice(SLOTS)),
                                speeds[k % len(speeds)], None, dynfilter, seed, cabinet=(x, y, yaw), room=room,
                                free_standing=free)
            if reachable(trial):
                draws.append(trial)
                break
        else:
            raise ValueError(f"no reachable cabinet pose in {MAX_DRAWS} draws (seed {seed})")
    return [replace(t, index=i * len(methods) + j, method=method)
            for i, t in enumerate(draws) for j, method in enumerate(methods)]


def failure_cause(report: dict) -> str | None:
    """Why a trial's drawer task did not succeed, in words (None: it did)."""
    if report["success"]:
        return None
    if report["fell"]:
        handover = (report.get("approach") or {}).get("handover_time_s")
        when = "" if report["fall_time_s"] is None else f" at {report['fall_time_s']:.2f} s"
        during = " on the approach" if handover is None or (report["fall_time_s"] or 0.0) < handover else ""
        return f"fell{when}{during}"
    failed = failed_criteria(report)
    return ", ".join(f"not {name}" for name in failed) if failed else report.get("stop_reason") or "not ended"


def drawer_row(spec: DrawerTrial, report: dict | None, outcome: TrialOutcome) -> dict:
    """The campaign's row of one trial (``report``: its drawer report, None if it wrote none)."""
    row = {"id": spec.id, "method": spec.method, "distance_m": spec.distance, "slot": spec.slot,
           "cabinet": list(spec.cabinet) if spec.cabinet else None, "room": list(spec.room) if spec.cabinet else None,
           "free_standing": spec.free_standing,
           "speed": spec.speed.value, "jump": list(spec.jump) if spec.jump else None, "seed": spec.seed,
           "dataset": spec.dataset, "sources": spec.sources, "dynfilter": spec.dynfilter.value, "wall_s": round(outcome.wall_s, 2), "error": outcome.error}
    if report is None:
        return row | {"fell": None, "success": False, "cause": outcome.error}
    errors = report.get("step_length_errors_m") or []
    ankle = report.get("peak_ankle_pitch_torque_ratio") or {}
    grf = report.get("peak_grf_n") or {}
    return row | {
        "fell": report["fell"], "fall_time_s": report["fall_time_s"], "success": report["success"],
        "cause": failure_cause(report),
        "pelvis_error_m": _difference(report.get("final_pelvis_to_drawer_m"), report.get("comfort_distance_m")),
        "pelvis_lateral_m": report.get("final_pelvis_lateral_m"),
        "pelvis_yaw_error_deg": report.get("final_pelvis_yaw_error_deg"),
        "handover_error": (report.get("approach") or {}).get("handover_error"),
        "unintended_contacts": report.get("unintended_contacts"),
        "step_length_errors_m": errors, "step_length_error_max_m": report.get("step_length_error_max_m"),
        "hand_error_m": report.get("hand_to_object_m"), "drawer_opening_m": report.get("drawer_opening_m"),
        "peak_ankle_pitch_torque_ratio": max(ankle.values()) if ankle else None,
        "peak_grf_ratio": round(max(grf.values()) / report["grf_limit_n"], 4) if grf else None,
        "zmp_lateral_error_rms_m": (report.get("zmp_error_rms_m") or {}).get("y"),
        "safety_interventions": report["safety"]["interventions"], "rtf": report["rtf"]}


def _difference(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None else round(a - b, 4)


def _stat(values: list[float], f) -> float | None:
    return round(float(f(values)), 5) if values else None


def summarize(rows: Sequence[dict]) -> list[dict]:
    """Per method, source count and speed class: trials, falls, successes, errors, median and max
    of the step length and hand errors (absolute), the largest peak ratios, and the largest final
    pelvis errors against the cabinet (distance from the comfort distance, lateral, yaw)."""
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for r in rows:
        groups.setdefault((r["method"], r.get("sources", "3+2"), r["speed"]), []).append(r)
    order = {s.value: k for k, s in enumerate(SpeedClass)}
    out = []
    for (method, sources, speed), rs in sorted(groups.items(), key=lambda kv: (kv[0][:2], order[kv[0][2]])):
        steps = [abs(e) for r in rs for e in r.get("step_length_errors_m") or []]

        def values(key: str, f=lambda v: v) -> list[float]:
            return [f(r[key]) for r in rs if r.get(key) is not None]

        out.append({"method": method, "sources": sources, "speed": speed, "trials": len(rs), "falls": sum(bool(r["fell"]) for r in rs),
                    "successes": sum(bool(r["success"]) for r in rs),
                    "errors": sum(r["error"] is not None for r in rs),
                    "step_length_error_median_m": _stat(steps, np.median), "step_length_error_max_m": _stat(steps, max),
                    "hand_error_median_m": _stat(values("hand_error_m"), np.median),
                    "hand_error_max_m": _stat(values("hand_error_m"), max),
                    "peak_ankle_pitch_torque_ratio": _stat(values("peak_ankle_pitch_torque_ratio"), max),
                    "peak_grf_ratio": _stat(values("peak_grf_ratio"), max),
                    "pelvis_error_max_m": _stat(values("pelvis_error_m", abs), max),
                    "pelvis_lateral_max_m": _stat(values("pelvis_lateral_m", abs), max),
                    "pelvis_yaw_error_max_deg": _stat(values("pelvis_yaw_error_deg", abs), max)})
    return out


def run_drawer_trials(trials: Sequence[DrawerTrial], out_dir: Path, backend: Backend, *,
                      timeout: float = TRIAL_TIMEOUT, progress: bool = True, label: str = "drawer trials") -> CampaignRun:
    """Run the drawer trials not yet done in ``out_dir``, each row from :func:`drawer_row`."""
    specs = {t.id: t for t in trials}
    return run_campaign([t.trial() for t in trials], out_dir, backend,
                        lambda trial, report, outcome: drawer_row(specs[trial.id], report, outcome),
                        timeout=timeout, progress=progress, label=label)


def run_drawer_campaign(trials: Sequence[DrawerTrial], out_dir: Path, backend: Backend, robot: RobotModel, *,
                        timeout: float = TRIAL_TIMEOUT, progress: bool = True,
                        log: Callable[[str], None] = print, command: str | None = None) -> dict | None:
    """Run the trials not yet done in ``out_dir``; when all are, write ``campaign.json`` and
    ``campaign.html`` (``robot``: the trials' robot, for the Fig. 3.38 postures) and return the
    campaign; None when interrupted."""
    run = run_drawer_trials(trials, out_dir, backend, timeout=timeout, progress=progress)
    if not run.complete:
        log(f"{len(run.rows)} of {len(trials)} trials done; run the same command again to finish the campaign")
        return None
    transitions = campaign_transitions(run.rows, robot)
    campaign = {"command": command, "trials": run.rows, "summary": summarize(run.rows),
                "transition_postures": [t | transition_summary(postures) for t, postures in transitions]}
    out_dir = Path(out_dir)
    tmp = out_dir / ".campaign.json.partial"
    tmp.write_text(json.dumps(campaign, indent=2) + "\n")
    tmp.replace(out_dir / "campaign.json")
    log(f"wrote {out_dir / 'campaign.json'} and {render_campaign(campaign, out_dir, transition_figure(robot, transitions))}")
    return campaign


def campaign_transitions(rows: Sequence[dict], robot: RobotModel) -> list[tuple[dict, list[dict]]]:
    """Thesis Fig. 3.38 for the primitives of the campaign's ``ours`` trials, one per demonstration
    set and source count: ``({"dataset", "sources"}, transition_postures(...))`` at
    ``TRANSITION_DISTANCES`` (kinematic: the synthesis alone, no physics)."""
    groups = sorted({(r.get("dataset"), r.get("sources", "3+2")) for r in rows if r["method"] == "ours"}, key=str)
    out = []
    for dataset, sources in groups:
        primitives = load_primitives(robot, Path(dataset) if dataset else None, tuple(int(n) for n in sources.split("+")))
        postures = transition_postures(robot, primitives, TRANSITION_DISTANCES, TRANSITION_SLOT)
        out.append(({"dataset": dataset, "sources": sources}, postures))
    return out


def transition_figure(robot: RobotModel, transitions: list[tuple[dict, list[dict]]]):
    """One side view per primitives of :func:`campaign_transitions` (None without any)."""
    if not transitions:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(transitions), figsize=(4.5 * len(transitions), 6.5), squeeze=False)
    for ax, (group, postures) in zip(axes[0], transitions):
        draw_transition_postures(robot, postures, ax, f"{demonstrations_label(group['dataset'])}, "
                                 f"{group['sources']} sources")
    return fig
