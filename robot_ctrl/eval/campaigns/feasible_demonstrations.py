"""Feasible demonstrations (thesis 3.8.3): walk-and-reach sequences played by the whole pipeline in
MuJoCo, recorded as a new training set.

The thesis trains its robot primitives on runs of the physically simulated robot, not on the
kinematic trajectories they came from: 10 sequences, each played at the speed scalings 0.8, 0.92
and 1.2, through WPG + dynamic filter + stack of tasks, 30 runs. Here each run is a drawer task
(``robot-ctrl drawer``, primitives learned from the kinematic set) at one of ``FEASIBLE_BASES``
(cabinet distance and object slot: 3- and 4-action sequences, front and back slots) and one speed
class, run as a campaign (resumable, local or Ray). From each run's time series:

- the actions are cut at the **measured** touch-downs: each gait cycle starts at the foot contact
  (vertical force rising through ``CONTACT_SHARE`` of the robot's weight) nearest to the tick at
  which the synthesis switched action; standing starts where the synthesis switched to it (the
  robot's last steps of the stop may land after it: the pelvis coming to rest is no touch-down)
  and ends where the sequence ended. A 4-action run
  gives its last normal cycle as action 1 (the thesis also recorded 4-action sequences);
- the signals are the **realized** ones: the base's twist ``(vx, vy, ωz)`` in its heading frame and
  the measured upper-body joint angles, averaged over each 0.02 s sample;
- the lengths are the measured pelvis advance along the start heading over each action;
- ``body``: the base's height, roll and pitch and every joint angle (the naive baseline learns the
  whole body).

A run that fell or missed the drawer criteria is not feasible data: the set is refused with the
run named. The speed classes change the durations (the synthesis's clock, ``modes.SpeedClass``), not
the lengths; the thesis scaled the pelvis's forward velocity at fixed upper-body timing, which
changes the lengths: both spread the training set over speed, ours over the (length, duration) map
that the learned regressions read.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Callable

import numpy as np

from robot_ctrl import ROOT
from robot_ctrl.eval.campaigns.campaign_backends import Backend
from robot_ctrl.eval.campaigns.campaign_runner import trial_dir
from robot_ctrl.eval.campaigns.drawer_campaign import DrawerTrial, run_drawer_trials
from robot_ctrl.geometry import GRAVITY
from robot_ctrl.modes import SpeedClass
from robot_ctrl.robot.config_file import load_robot_config
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.synthesis.demonstrations import (
    PELVIS_CHANNELS,
    Demonstration,
    DemonstrationSet,
    upper_body_joints,
)
from robot_ctrl.synthesis.step_planning import Action

#: (cabinet distance from the start pelvis [m], object slot): the first six give one normal cycle,
#: a short one and standing; the last four a normal cycle more. All within the 1.83 m that drawn
#: campaign trials stay beyond.
FEASIBLE_BASES = ((1.38, "front_left"), (1.40, "back_right"), (1.44, "front_right"), (1.48, "back_left"),
                  (1.52, "front_left"), (1.56, "back_right"), (1.64, "front_right"), (1.69, "back_left"),
                  (1.74, "back_right"), (1.80, "front_left"))
FEASIBLE_SPEEDS = (SpeedClass.SLOW, SpeedClass.MIDDLE, SpeedClass.FAST)  # the thesis's 0.8, 0.92, 1.2
SAMPLE_DT = 0.02  # [s] the demonstration's sample time, as the kinematic set's
CONTACT_SHARE = 0.1  # of the robot's weight: a foot's vertical force above it is a contact
MIN_SWING = 0.1  # [s] shortest swing phase that ends in a touch-down
SNAP_WINDOW = 0.1  # [s] an action switch this close to a touch-down starts at the touch-down
BODY_BASE_CHANNELS = ("base_z", "base_roll", "base_pitch")


def feasible_trials(dataset: Path, robot: str) -> list[DrawerTrial]:
    """The runs of ``robot``: every base at every speed class, with primitives learned from ``dataset``."""
    dynfilter = load_robot_config(robot).drawer_dynfilter
    return [DrawerTrial(i * len(FEASIBLE_SPEEDS) + j, "ours", d, slot, speed, dynfilter=dynfilter,
                        dataset=str(Path(dataset).resolve()), robot=robot)
            for i, (d, slot) in enumerate(FEASIBLE_BASES) for j, speed in enumerate(FEASIBLE_SPEEDS)]


def touchdowns(t: np.ndarray, grf: np.ndarray, weight: float) -> np.ndarray:
    """Times [s] at which a foot's vertical force rises through ``CONTACT_SHARE`` × ``weight``
    after at least ``MIN_SWING`` [s] without contact (``grf``: (ticks, feet) [N]); a heel that
    bounces once on landing is one touch-down."""
    times = []
    for contact in (grf > CONTACT_SHARE * weight).T:
        last_contact = -np.inf
        for k in range(1, len(t)):
            if contact[k] and not contact[k - 1] and t[k] - last_contact >= MIN_SWING:
                times.append(t[k])
            if contact[k]:
                last_contact = t[k]
    return np.sort(times)


def _action_times(starts: np.ndarray) -> list[float]:
    """Start times of the last normal cycle, the short cycle and standing, and the end [s], from the
    run's ``action_starts`` rows (time, action)."""
    actions = [int(a) for a in starts[:, 1]]
    pattern = [Action.WALK, Action.SHORT, Action.STAND, Action.ENDED]
    for k in range(len(actions) - 3, -1, -1):
        if actions[k : k + 4] == pattern:
            return [float(v) for v in starts[k : k + 4, 0]]
    raise ValueError(f"the run's actions {actions} do not end with a normal cycle, a short cycle and standing")


def _roll_pitch(quat_xyzw: np.ndarray) -> np.ndarray:
    x, y, z, w = quat_xyzw.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    return np.stack([roll, pitch], axis=1)


def demonstration_from_run(series: dict, slot: str, upper: np.ndarray, weight: float) -> Demonstration:
    """One demonstration from a drawer run's ``timeseries.npz`` arrays; ``upper``: the indices of the
    upper-body joints in joint order; ``weight``: the robot's [N]."""
    t = series["drawer_t"]
    bounds_t = _action_times(series["action_starts"])
    steps = touchdowns(t, series["drawer_grf"], weight)
    for k in range(2):  # the gait cycles' starts
        if len(steps):
            nearest = steps[np.argmin(np.abs(steps - bounds_t[k]))]
            if abs(nearest - bounds_t[k]) <= SNAP_WINDOW:
                bounds_t[k] = float(nearest)
    bounds = np.round((np.array(bounds_t) - bounds_t[0]) / SAMPLE_DT).astype(int)
    if np.any(np.diff(bounds) < 10):
        raise ValueError(f"an action of the run lasts under {10 * SAMPLE_DT:g} s (boundaries {bounds_t} s)")
    grid = bounds_t[0] + SAMPLE_DT * np.arange(bounds[-1] + 1)
    # Each sample is the mean of the ticks within ±dt/2 of it.
    lo = np.searchsorted(t, grid - SAMPLE_DT / 2)
    hi = np.maximum(np.searchsorted(t, grid + SAMPLE_DT / 2), lo + 1)
    base = series["base_quat_xyzw"].astype(float)
    per_tick = np.concatenate([series["base_twist"], series["joint_q"][:, upper], series["base_pos"][:, 2:3],
                               _roll_pitch(base), series["joint_q"]], axis=1).astype(float)
    csum = np.concatenate([np.zeros((1, per_tick.shape[1])), np.cumsum(per_tick, axis=0)])
    samples = (csum[hi] - csum[lo]) / (hi - lo)[:, None]
    n_signals = 3 + len(upper)
    xy, yaw0 = series["drawer_base"][:, :2], float(series["drawer_base"][0, 2])
    advance = xy @ np.array([np.cos(yaw0), np.sin(yaw0)])
    at = [advance[min(int(np.searchsorted(t, b - 1e-9)), len(t) - 1)] for b in bounds_t]
    lengths = np.array([at[1] - at[0], at[2] - at[1], 0.0])
    return Demonstration(slot, lengths, np.diff(bounds) * SAMPLE_DT, bounds, samples[:, :n_signals],
                         samples[:, n_signals:])


def _shown(path: Path) -> str:
    """``path`` relative to the project when inside it (the command works from any checkout)."""
    try:
        return str(Path(path).resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def record_feasible_set(robot: RobotModel, source: Path, runs_dir: Path, backend: Backend, out: Path, *,
                        progress: bool = True, log: Callable[[str], None] = print) -> DemonstrationSet | None:
    """Run the feasible trials (primitives from the kinematic set ``source``) into ``runs_dir``
    (resumable), build the set from them and save it to ``out``; None when interrupted. Beside the
    runs: ``feasible_runs.json`` (their rows) and ``trials.txt`` (them as a campaign's trials file)."""
    trials = feasible_trials(source, robot.name)
    run = run_drawer_trials(trials, runs_dir, backend, progress=progress, label="feasible runs")
    if not run.complete:
        log(f"{len(run.rows)} of {len(trials)} runs done; run the same command again to finish them")
        return None
    bad = [r for r in run.rows if not r["success"]]
    if bad:
        raise ValueError(f"{len(bad)} of the runs are not feasible demonstrations (fell, failed a drawer criterion or "
                         f"errored), first {bad[0]['id']}: see {trial_dir(runs_dir, bad[0]['id'])}")
    upper = np.array([robot.joint_names.index(n) for n in upper_body_joints(robot)])
    weight = robot.mass * GRAVITY
    demos = []
    for spec in trials:
        with np.load(trial_dir(runs_dir, spec.id) / "timeseries.npz") as f:
            demos.append(demonstration_from_run(dict(f), spec.slot, upper, weight))
    comfort = run.reports[trials[0].id]["comfort_distance_m"]
    provenance = {
        "source": "physics",
        "made_by": "eval/campaigns/feasible_demonstrations.py: drawer runs in MuJoCo (synthesis, WPG, dynamic filter, stack of "
                   "tasks), realized base twist and joint angles, actions cut at measured touch-downs",
        "from_dataset": f"{Path(source).name} sha256 {hashlib.sha256(Path(source).read_bytes()).hexdigest()[:16]}",
        "runs": [{"id": s.id, "distance_m": s.distance, "slot": s.slot, "speed": s.speed.value} for s in trials],
        "regenerate": f"robot-ctrl synth-demos --from-physics --robot {robot.name} --out {_shown(out)}"}
    body_channels = BODY_BASE_CHANNELS + tuple(robot.joint_names)
    result = DemonstrationSet(robot.name, PELVIS_CHANNELS + upper_body_joints(robot), SAMPLE_DT, comfort,
                              tuple(demos), provenance, body_channels)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    result.save(Path(out))
    (Path(runs_dir) / "feasible_runs.json").write_text(json.dumps(run.rows, indent=2) + "\n")
    (Path(runs_dir) / "trials.txt").write_text(  # the same sequences for a campaign (resynthesis)
        "# the runs the feasible demonstration set was recorded from (robot-ctrl synth-demos --from-physics)\n"
        + "".join(f"{t.distance:g} {t.slot} {t.speed.value}\n" for t in trials))
    return result
