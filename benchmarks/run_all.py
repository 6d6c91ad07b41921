"""Runs every benchmark script and writes ``benchmarks/RESULTS.md``: the date, the machine (CPU
model, core count), the package versions, a table of the figures the scripts give as JSON
(``--json``: one object as their last line), and each script's printed medians and ratios as it
printed them. ``make bench`` calls it in ``.venv-bench``."""

from __future__ import annotations

import datetime
import json
import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
SCRIPTS = ("bench_sot.py", "bench_wpg.py", "bench_loop.py", "bench_dynfilter.py", "bench_synthesis.py",
           "bench_drawer.py", "bench_crowd.py")
JSON_SCRIPTS = ("bench_sot.py", "bench_wpg.py", "bench_loop.py", "bench_drawer.py", "bench_crowd.py")
PACKAGES = ("robot-ctrl", "numpy", "scipy", "casadi", "mujoco", "pin", "quadprog", "daqp", "mink", "placo")


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "not installed"


def main() -> None:
    sections, figures = [], []
    for script in SCRIPTS:
        print(f"running {script} ...", flush=True)
        flags = ["--json"] if script in JSON_SCRIPTS else []
        run = subprocess.run([sys.executable, str(HERE / script), *flags], capture_output=True, text=True)
        lines = run.stdout.strip().splitlines()
        if flags and lines and lines[-1].startswith("{"):
            figures.extend((script, key, value) for key, value in json.loads(lines.pop()).items())
        output = "\n".join(lines) + (f"\n(exit status {run.returncode}: {run.stderr.strip().splitlines()[-1]})"
                                     if run.returncode else "")
        print(output)
        sections.append(f"## `{script}`\n\n```\n{output}\n```\n")
    table = "| script | figure | value |\n|---|---|---|\n" + "".join(
        f"| `{script}` | `{key}` | {'-' if value is None else value} |\n" for script, key, value in figures)
    header = (f"# Benchmark results\n\nWritten by `make bench` (`benchmarks/run_all.py`) on "
              f"{datetime.date.today().isoformat()}: {cpu_model()}, {os.cpu_count()} cores, Python "
              f"{platform.python_version()}.\n\n" + "\n".join(f"- {p} {version(p)}" for p in PACKAGES) + "\n\n"
              "Each section is the script's own output: medians, and ratios against the peers it runs in the same "
              "invocation. What each script measures is in its docstring. The figures the scripts give as JSON "
              "(`--json`; `-`: a peer not installed or not compared):\n\n" + table + "\n")
    (HERE / "RESULTS.md").write_text(header + "\n".join(sections))
    print(f"wrote {HERE / 'RESULTS.md'}")


if __name__ == "__main__":
    main()
