"""Signals held while the servos are brought to their safe state.

Ctrl-C or SIGTERM becomes a ``KeyboardInterrupt`` wherever the main thread is (``robot-ctrl``'s
handler). Arriving inside :meth:`HardwareAdapter.close`, between the damping and the disable or
halfway through a bus, it would leave drives enabled. Inside :func:`signals_held` the signals are
only recorded; once the block has run, the handlers are restored and the first signal recorded is
raised again, so it acts as it would have, after the servos are safe.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Iterator

HELD = (signal.SIGINT, signal.SIGTERM)
_caught: list[int] | None = None  # the signals recorded while held (main thread only)


@contextmanager
def signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM for the block (nested blocks hold them once; a thread other than the
    main one cannot set handlers, and its block runs as it is)."""
    global _caught
    if _caught is not None or threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    _caught = caught
    previous = {s: signal.signal(s, lambda signum, frame: caught.append(signum)) for s in HELD}
    try:
        yield
    finally:
        _caught = None
        for s, handler in previous.items():
            signal.signal(s, handler)
        if caught:
            signal.raise_signal(caught[0])  # now acted on as its restored handler says
