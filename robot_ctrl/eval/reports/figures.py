"""What every report's figures share: a matplotlib figure as embedded PNG data, shaded time spans."""

from __future__ import annotations

import base64
import io

import numpy as np


def figure_png(fig) -> str:
    """A matplotlib figure as base64 PNG data (closes the figure)."""
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buffer, format="png", dpi=100, bbox_inches="tight")  # no blank band around an equal-aspect plot
    plt.close(fig)
    return base64.b64encode(buffer.getvalue()).decode()


def shade_spans(ax, t, mask, **style) -> None:
    """Shade the time spans where ``mask`` holds (``style``: ``axvspan`` options)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(mask).astype(int), [0]])))
    for start, end in zip(edges[::2], edges[1::2]):
        ax.axvspan(t[start], t[end - 1], lw=0, **style)
