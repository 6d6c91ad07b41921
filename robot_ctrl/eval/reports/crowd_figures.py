"""Figures of the kinematic crowd experiments (``robot-ctrl crowd run`` and ``crowd figure``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    """matplotlib's pyplot on the file-only backend (imported on first use: the library's import stays light)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_dispersion(result, path: Path, title: str) -> Path:
    """The mean angular dispersion of a kinematic crowd run (and its position and heading errors)
    against time, with the certified rate; written to ``path`` (PNG)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogy(result.times, result.dispersion, label="mean angular dispersion R̂")
    if result.position_error is not None:
        ax.semilogy(result.times, result.position_error, label="position error ‖z − o − mean‖ [m]")
    if result.heading_error is not None:
        ax.semilogy(result.times, result.heading_error, label="heading error ‖ψ − mean‖ [rad]")
    rate = next((c.rate for c in result.conditions if c.name == "hopf_diffusive"), None)
    if rate is not None:
        ax.semilogy(result.times, result.dispersion[0] * np.exp(-rate * result.times), "--",
                    label=f"certified rate {rate:.3g} 1/s")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("R̂")
    ax.set_ylim(1e-8, 1.5)
    ax.set_title(title)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_rate_slopes(data: dict, path: Path) -> Path:
    """Thesis Fig. 4.6 from :func:`robot_ctrl.crowd.experiments.rate_slopes`: (a) the empirical rate
    against the coupling strength for N = 5, (b) its slope dλ/dk against N beside λ⁺; PNG at ``path``."""
    import matplotlib.ticker

    plt = _pyplot()
    fig, (ax_a, ax_b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for topology, marker in (("all", "o"), ("ring", "s"), ("chain", "^"), ("star", "d")):
        rows = [v for v in data.values() if v["topology"] == topology]
        row = next(v for v in rows if v["n"] == 5)
        ax_a.plot(row["k"], row["rates"], marker, label=f"{topology}, N = 5 (simulated)")
        ax_a.plot(row["k"], [k * row["lambda_plus"] for k in row["k"]], "k:", lw=0.8)
        ns = [v["n"] for v in rows]
        ax_b.plot(ns, [v["slope"] for v in rows], marker, ms=9, mfc="none", label=f"{topology} (simulated)")
        ax_b.plot(ns, [v["theory_slope"] for v in rows], "--", label=f"{topology}: λ⁺ (theory)")
    ax_a.set_xlabel("coupling strength k")
    ax_a.set_ylabel("empirical rate λ [1/s]")
    ax_a.set_title("a) rate vs coupling (dotted: k λ⁺)")
    ax_a.legend(fontsize=8)
    ax_b.set_xscale("log")
    ax_b.set_yscale("log")
    ax_b.set_xticks(sorted({v["n"] for v in data.values()}))
    ax_b.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    ax_b.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax_b.set_xlabel("number of oscillators N")
    ax_b.set_ylabel("slope dλ/dk")
    ax_b.set_title("b) slope vs N (thesis Fig. 4.6)")
    ax_b.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
