"""Where a campaign's trials run: ``local`` (a pool of this machine's threads, each waiting on a
trial's own process group) or ``ray`` (tasks on a Ray cluster, or on a Ray instance started here).
Both run the same trial function (:func:`robot_ctrl.eval.campaigns.trial_process.run_trial`), so a campaign
grows past one machine without code changes.

A backend starts trials, yields their outcomes as they end, and after a Ctrl-C cancels the trials
not yet started while the running ones end.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor, as_completed
from typing import Iterator, Protocol, Sequence

from robot_ctrl.eval.campaigns.trial_process import Trial, TrialOutcome, run_trial

#: Object store of a Ray instance started here [bytes]: outcomes are a few hundred kB each.
LOCAL_RAY_OBJECT_STORE = 256 * 2**20


class Backend(Protocol):
    def start(self, trials: Sequence[Trial], timeout: float) -> None: ...

    def outcomes(self) -> Iterator[TrialOutcome]:
        """Each started trial's outcome once, as it ends (none for a cancelled trial)."""

    def cancel_pending(self) -> None:
        """Start no more trials; the running ones go on to their end."""

    def close(self) -> None: ...


class LocalBackend:
    """``jobs`` trials at a time on this machine."""

    def __init__(self, jobs: int):
        self.jobs = jobs
        self._pool: ThreadPoolExecutor | None = None
        self._futures: list[Future] = []
        self._seen: set[int] = set()

    def start(self, trials: Sequence[Trial], timeout: float) -> None:
        self._pool = ThreadPoolExecutor(max_workers=self.jobs, thread_name_prefix="trial")
        self._futures = [self._pool.submit(run_trial, trial, timeout) for trial in trials]

    def outcomes(self) -> Iterator[TrialOutcome]:
        for future in as_completed(self._futures):
            if id(future) in self._seen or future.cancelled():
                continue
            self._seen.add(id(future))
            yield future.result()

    def cancel_pending(self) -> None:
        for future in self._futures:
            future.cancel()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)


class RayBackend:
    """At most ``jobs`` trials at a time as Ray tasks: on the cluster at ``address`` (whose workers
    have robot_ctrl installed, docs/campaigns.md), or on a Ray instance started here with ``jobs``
    CPUs when ``address`` is None (and stopped by :meth:`close`)."""

    def __init__(self, jobs: int, address: str | None = None):
        try:
            import ray
        except ImportError as exc:
            raise ValueError("--backend ray needs Ray: pip install 'robot-ctrl[cluster]'") from exc
        self.ray, self.jobs = ray, jobs
        self._owned = not ray.is_initialized()
        if self._owned:
            options = dict(include_dashboard=False, log_to_driver=False, configure_logging=False)
            if address is None:
                options.update(num_cpus=jobs, object_store_memory=LOCAL_RAY_OBJECT_STORE)
            ray.init(address=address, **options)
        self._task = ray.remote(num_cpus=1)(run_trial)
        self._timeout = 0.0  # [s] per trial, given to start
        self._waiting: list[Trial] = []
        self._running: dict = {}  # object ref -> trial

    def start(self, trials: Sequence[Trial], timeout: float) -> None:
        self._timeout = timeout
        self._waiting = list(trials)
        self._fill()

    def _fill(self) -> None:
        while self._waiting and len(self._running) < self.jobs:
            trial = self._waiting.pop(0)
            self._running[self._task.remote(trial, self._timeout)] = trial

    def outcomes(self) -> Iterator[TrialOutcome]:
        while self._running:
            done, _ = self.ray.wait(list(self._running), num_returns=1)
            self._running.pop(done[0])
            self._fill()
            yield self.ray.get(done[0])

    def cancel_pending(self) -> None:
        self._waiting = []

    def close(self) -> None:
        if self._owned and self.ray.is_initialized():
            self.ray.shutdown()


def open_backend(name: str, jobs: int, address: str | None = None) -> Backend:
    """The backend ``name`` (``local`` or ``ray``) running ``jobs`` trials at a time."""
    if name == "local":
        if address is not None:
            raise ValueError("--address names a Ray cluster: it goes with --backend ray")
        return LocalBackend(jobs)
    if name == "ray":
        return RayBackend(jobs, address)
    raise ValueError(f"backend {name!r} is not one of local, ray")
