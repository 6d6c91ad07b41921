"""A child process that dies with the thread that started it (Linux ``PR_SET_PDEATHSIG``).

The simulated robot's process, the dynamic filter's worker and a campaign's trials are children
that must not outlive their parent: killed outright (SIGKILL, the machine's OOM killer), a parent
runs no cleanup, and a child blocked on a pipe whose other end a sibling still holds would wait
forever. Elsewhere this does nothing (those children then rely on their own orphan checks).
"""

from __future__ import annotations

import ctypes
import signal
import sys

PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Ask the kernel to SIGKILL this process when the thread that created it ends."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except OSError:
        pass
