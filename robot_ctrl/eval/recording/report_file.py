"""Writing a run's report: ``DIR/report.json``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable


def write_report(report: dict, out_dir: Path | None, log: Callable[[str], None] = print) -> None:
    """Write ``report`` as ``out_dir/report.json`` (creating the folder); nothing if ``out_dir`` is None."""
    if out_dir is None:
        return
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "report.json"
    path.write_text(json.dumps(report, indent=2) + "\n")
    log(f"wrote {path}")
