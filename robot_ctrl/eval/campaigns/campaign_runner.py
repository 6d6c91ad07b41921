"""Running a campaign's trials to completion, resumably.

Each trial's folder is ``DIR/trials/<id>/``: what its command wrote (``report.json``,
``timeseries.npz``) and ``row.json``, the campaign's row for it. The folder is written whole under
a temporary name and renamed, so a trial is done exactly when its ``row.json`` exists: rerunning the
same campaign after a kill (Ctrl-C, SIGKILL, a lost machine) runs only the trials without one.
A trial that fails or exceeds its time limit is an error row, and the campaign goes on. Ctrl-C
starts no more trials, lets the running ones end and keeps their rows.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from tqdm import tqdm

from robot_ctrl.eval.campaigns.campaign_backends import Backend
from robot_ctrl.eval.campaigns.trial_process import Trial, TrialOutcome

#: A row from a trial, the report its command wrote (None without one) and its outcome.
RowFunction = Callable[[Trial, "dict | None", TrialOutcome], dict]


@dataclass(frozen=True)
class CampaignRun:
    rows: list[dict]  # the trials done, in the order given
    reports: dict[str, dict]  # trial id -> its report (trials that wrote one)
    interrupted: bool  # Ctrl-C: some trials are not done

    @property
    def complete(self) -> bool:
        return not self.interrupted


def trial_dir(out_dir: Path, trial_id: str) -> Path:
    return Path(out_dir) / "trials" / trial_id


def _load_done(out_dir: Path, trials: Sequence[Trial]) -> dict[str, dict]:
    """Rows of the trials already done; leftovers of trials cut short are removed."""
    folder = Path(out_dir) / "trials"
    if folder.is_dir():
        for partial in folder.glob(".*.partial"):
            shutil.rmtree(partial, ignore_errors=True)
    done = {}
    for trial in trials:
        row = trial_dir(out_dir, trial.id) / "row.json"
        if row.is_file():
            done[trial.id] = json.loads(row.read_text())
    return done


def _write(out_dir: Path, trial: Trial, outcome: TrialOutcome, row: dict) -> None:
    final = trial_dir(out_dir, trial.id)
    partial = final.parent / f".{trial.id}.partial"
    shutil.rmtree(partial, ignore_errors=True)
    partial.mkdir(parents=True)
    for name, data in outcome.files.items():
        (partial / name).write_bytes(data)
    (partial / "row.json").write_text(json.dumps(row, indent=2) + "\n")
    if final.exists():  # an older folder without its row: the trial did not finish then
        shutil.rmtree(final)
    os.replace(partial, final)


def _report(outcome: TrialOutcome) -> dict | None:
    data = outcome.files.get("report.json")
    return json.loads(data) if data is not None else None


def run_campaign(trials: Sequence[Trial], out_dir: Path, backend: Backend, row_of: RowFunction, *,
                 timeout: float = 600.0, progress: bool = True, label: str = "trials") -> CampaignRun:
    """Run the ``trials`` not yet done in ``out_dir`` on ``backend``, each within ``timeout`` [s];
    ``row_of`` turns a trial's report into its row (a row with ``fell`` true counts as a fall in
    the progress bar)."""
    ids = [t.id for t in trials]
    if len(set(ids)) != len(ids):
        raise ValueError("campaign trials need distinct ids")
    out_dir = Path(out_dir)
    rows = _load_done(out_dir, trials)
    reports = {t.id: json.loads(p.read_text()) for t in trials
               if t.id in rows and (p := trial_dir(out_dir, t.id) / "report.json").is_file()}
    todo = [t for t in trials if t.id not in rows]
    by_id = {t.id: t for t in trials}
    bar = tqdm(total=len(trials), initial=len(rows), desc=label, unit="trial", disable=not progress, leave=False)

    def record(outcome: TrialOutcome) -> None:
        trial, report = by_id[outcome.id], _report(outcome)
        row = row_of(trial, report, outcome)
        _write(out_dir, trial, outcome, row)
        rows[trial.id] = row
        if report is not None:
            reports[trial.id] = report
        bar.update(1)
        bar.set_postfix(falls=sum(bool(r.get("fell")) for r in rows.values()),
                        errors=sum(r.get("error") is not None for r in rows.values()), refresh=False)

    interrupted = False
    if todo:
        backend.start(todo, timeout)
        try:
            try:
                for outcome in backend.outcomes():
                    record(outcome)
            except KeyboardInterrupt:
                interrupted = True
                backend.cancel_pending()
                bar.write("interrupted: the running trials end first (their rows are kept); run the same command "
                          "again to finish the campaign")
                for outcome in backend.outcomes():
                    record(outcome)
        finally:
            backend.close()
            bar.close()
    else:
        bar.close()
    return CampaignRun([rows[i] for i in ids if i in rows], reports, interrupted or len(rows) < len(trials))
