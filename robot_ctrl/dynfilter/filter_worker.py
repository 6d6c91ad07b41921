"""DynamicFilterWorker: the dynamic filter in a worker process, one pattern-generator sample behind.

The filter's passes (whole-body preview, multibody ZMP, preview correction: ``DynamicFilter``)
cost about as much as the rest of the control loop; here they run on another CPU core while the
controller executes the sample. At the start of sample k the controller sends sample k's plan and
takes the worker's result for sample k − 1, carried one sample ahead (``PreviewCorrection.advance``).

Simplification (docs/dynamic-filter.md): the offset applied during sample k was refined on the
plan of sample k − 1, 0.1 s older than the plan it corrects. The worker's chain of offset plans is
the in-process filter's chain fed the same requests; only its use is one sample later. The
controller waits for the result when the worker is late, so a run does not depend on timing.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
from dataclasses import dataclass
from typing import Callable, NoReturn

import numpy as np

from robot_ctrl.dynfilter.dynamic_filter import ComOffset, DynamicFilter, filter_request
from robot_ctrl.dynfilter.preview_correction import PreviewCorrection
from robot_ctrl.modes import FilterMode
from robot_ctrl.parent_death import die_with_parent
from robot_ctrl.robot.model import RobotModel
from robot_ctrl.wpg.plan import PlanPreview


@dataclass(frozen=True)
class FilterResult:
    """The offset plan after a request's passes (``PreviewCorrection`` state and jerks, aligned with
    the start of the request's sample) and the passes' diagnostics."""

    state: np.ndarray  # (3, 2)
    jerks: np.ndarray  # (N, 2)
    last_error: np.ndarray
    pass_rms: list[float]
    fallbacks: int  # updates the guard refused so far


def _serve(connection, robot: RobotModel, horizon: int, com_height: float, mode: str, passes: int) -> None:
    """Worker process: refine every request in order and send the result back, until ``None``."""
    die_with_parent()  # a controller killed outright sends no None, and the pipe may never report it gone
    # The command line's handlers are inherited by the fork: Ctrl-C stops the controller, which closes
    # us; a SIGTERM from its cleanup ends us quietly, without a second traceback.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    # Idle priority: the result is due a sample later, while the loop's physics thread shares this
    # core and is waited for every tick. Linux's SCHED_IDLE yields the core the moment the physics
    # wakes; elsewhere, the lowest nice value.
    if hasattr(os, "SCHED_IDLE"):
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    elif hasattr(os, "nice"):
        os.nice(19)
    dynfilter = DynamicFilter(robot, horizon, com_height, mode, passes)
    while (request := connection.recv()) is not None:
        dynfilter.refine(request)
        c = dynfilter.correction
        connection.send(FilterResult(c.state.copy(), c.jerks.copy(), dynfilter.last_error, dynfilter.pass_rms,
                                     dynfilter.fallbacks))
    connection.close()


class DynamicFilterWorker:
    """Same interface as :class:`DynamicFilter` (``update``, ``offset``, ``last_error``,
    ``pass_rms``, ``close``) for the modes ``legs`` and ``full``; ``close()`` ends the worker."""

    def __init__(self, robot: RobotModel, horizon: int, com_height: float, mode: FilterMode | str = FilterMode.FULL,
                 passes: int = 2):
        DynamicFilter.check_settings(mode, passes)
        mode = FilterMode(mode)
        if mode is FilterMode.OFF:
            raise ValueError("dynfilter mode 'off' needs no worker: use DynamicFilter")
        self.mode, self.passes = mode, passes
        self.correction = PreviewCorrection(horizon, com_height)
        self.last_error: np.ndarray | None = None
        self.pass_rms: list[float] = []
        self.fallbacks = 0
        self._pending: float | None = None  # sample duration of the request in flight
        # fork shares the loaded robot model; other platforms pickle it to a fresh interpreter.
        context = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
        self._connection, child = context.Pipe()
        self._process = context.Process(target=_serve, args=(child, robot, horizon, com_height, mode, passes),
                                        daemon=True, name="dynamic-filter")
        self._process.start()
        child.close()

    def update(self, plan: PlanPreview, q_ref: np.ndarray, com_z: float, sole_height: float,
               posture: Callable[[float], np.ndarray]) -> None:
        """Start refining the sample the WPG just solved; apply the previous sample's result."""
        if self._pending is not None:
            result = self._receive()
            self.correction.state, self.correction.jerks = result.state, result.jerks
            self.correction.advance(self._pending)
            self.last_error, self.pass_rms, self.fallbacks = result.last_error, result.pass_rms, result.fallbacks
        request = filter_request(self.mode, plan, q_ref, com_z, sole_height, posture)
        try:
            self._connection.send(request)
        except OSError:
            self._stopped()
        self._pending = plan.sample_duration

    def offset(self, tau: float) -> ComOffset:
        """The CoM offset ``tau`` seconds into the current sample."""
        return ComOffset(*self.correction.at(tau))

    def _receive(self) -> FilterResult:
        try:
            return self._connection.recv()
        except (EOFError, OSError):
            self._stopped()

    def _stopped(self) -> NoReturn:
        self._process.join(timeout=1.0)
        raise RuntimeError(f"the dynamic filter worker stopped (exit code {self._process.exitcode}); "
                           "its error, if it raised one, is printed above") from None

    def close(self) -> None:
        if self._process is None:
            return
        try:
            self._connection.send(None)
        except OSError:
            pass  # already gone
        self._process.join(timeout=5.0)
        if self._process.is_alive():
            self._process.terminate()
        self._connection.close()
        self._process = self._connection = None
