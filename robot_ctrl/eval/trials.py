"""Running many independent trials of a ``robot-ctrl`` command side by side.

Each trial is the command line a user would type, run in its own process (a crash or a hang of
one trial cannot take the others down, and the simulated robot of each gets its own processes),
``jobs`` at a time, with a progress bar; its ``report.json`` is read back.
"""

from __future__ import annotations

import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from tqdm import tqdm


@dataclass(frozen=True)
class Trial:
    name: str  # also the trial's output folder under the campaign's
    argv: tuple[str, ...]  # robot-ctrl arguments, without --out


def run_trials(trials: list[Trial], out_dir: Path, jobs: int = 1, timeout: float = 600.0,
               progress: bool = True) -> dict[str, dict]:
    """Each trial's report (``{"error": ...}`` when it wrote none), by name."""
    out_dir = Path(out_dir)

    def one(trial: Trial) -> tuple[str, dict]:
        folder = out_dir / trial.name
        command = [sys.executable, "-m", "robot_ctrl.cli", *trial.argv, "--quiet", "--out", str(folder)]
        try:
            run = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            return trial.name, {"error": f"no result within {timeout:.0f} s"}
        report = folder / "report.json"
        if not report.is_file():
            lines = (run.stderr or run.stdout).strip().splitlines()
            return trial.name, {"error": lines[-1] if lines else f"exit status {run.returncode}"}
        return trial.name, json.loads(report.read_text())

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        results = {}
        for name, report in tqdm(pool.map(one, trials), total=len(trials), desc="trials", disable=not progress,
                                 leave=False):
            results[name] = report
    return results
