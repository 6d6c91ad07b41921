"""One trial of a campaign: a ``robot-ctrl`` command line run in a process group of its own.

The command is what a user would type; it runs in a temporary folder of the machine that runs it
(a campaign's worker may be another machine), and what it wrote comes back as bytes, so the
campaign writes every trial's folder itself. A crash or a hang of one trial cannot take the others
down: a trial past its time limit is killed with its whole process group, and on Linux the trial's
process is killed when the thread that started it dies (a campaign killed outright leaves no
orphans). The trial runs in a new session, so a terminal's Ctrl-C reaches the campaign, which lets
the running trials end, and not the trials themselves.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from robot_ctrl.parent_death import die_with_parent

#: The files of a trial's output folder that come back (the HTML report is rendered on demand).
KEPT_FILES = ("report.json", "timeseries.npz")


@dataclass(frozen=True)
class Trial:
    """``argv``: the ``robot-ctrl`` arguments (without ``--out``); ``id``: its folder's name."""

    id: str
    argv: tuple[str, ...]


@dataclass(frozen=True)
class TrialOutcome:
    id: str
    files: dict[str, bytes] = field(default_factory=dict)  # KEPT_FILES the command wrote
    error: str | None = None  # why there is no report: the command's last line, or the time limit
    exit_status: int | None = None
    wall_s: float = 0.0


def run_trial(trial: Trial, timeout: float) -> TrialOutcome:
    """Run ``robot-ctrl ARGV --quiet --out TMP`` within ``timeout`` [s] of wall time; whatever goes
    wrong becomes the outcome's error, never an exception."""
    try:
        return _run(trial, timeout)
    except Exception as exc:  # a trial that cannot even start is an error row, not a stopped campaign
        return TrialOutcome(trial.id, error=f"{type(exc).__name__}: {exc}")


def _run(trial: Trial, timeout: float) -> TrialOutcome:
    with tempfile.TemporaryDirectory(prefix="robot-ctrl-trial-") as tmp:
        command = [sys.executable, "-m", "robot_ctrl.cli", *trial.argv, "--quiet", "--out", tmp]
        start = time.monotonic()
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   start_new_session=True,
                                   preexec_fn=die_with_parent)
        try:
            _, stderr = process.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
            return TrialOutcome(trial.id, error=f"no result within {timeout:g} s", wall_s=time.monotonic() - start)
        wall = time.monotonic() - start
        files = {name: (Path(tmp) / name).read_bytes() for name in KEPT_FILES if (Path(tmp) / name).is_file()}
        error = None
        if "report.json" not in files:
            lines = stderr.strip().splitlines()
            error = lines[-1] if lines else f"exit status {process.returncode}"
        return TrialOutcome(trial.id, files, error, process.returncode, wall)
