"""Where protocol fits run: in this process or on a Dask cluster, with a cache of finished fits.

``ext-sense evaluate`` and ``ext-sense report`` take ``--workers N`` (a local cluster started
and stopped by the command, one single-threaded worker process per core) or ``--scheduler
tcp://HOST:PORT`` (an existing cluster whose workers run this project's environment); without
either, fits run here, one after the other. :meth:`FitExecutor.run_jobs` takes the fits of many
points at once (a :class:`FitJob` each: its tasks and its data), sends each point's data to the
workers once (``scatter``) and streams the tasks so the workers never wait between points;
finished fits are stored in a :class:`FitCache` as they arrive, so an interrupted run loses only
the fits that were running.
``dask`` is imported only when a cluster is asked for. No ROS.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

from ext_sense_perception.errors import PerceptionError


class FitCache:
    """Finished fits on disk, one pickle per key.

    Each is written atomically (a temporary file renamed into place), so a killed run leaves no
    half-written entry.
    """

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)  # made by the first put: a refused run leaves nothing

    def _path(self, key: str, store: str = "") -> Path:
        return self.directory / store / key[:2] / f"{key}.pkl"

    def __contains__(self, key: str) -> bool:
        """Whether ``key`` has a stored result in the main store (not read)."""
        return self._path(key).exists()

    def get(self, key: str, store: str = "") -> Any | None:
        """The stored result of ``key`` (None: not there or unreadable)."""
        path = self._path(key, store)
        try:
            with open(path, "rb") as fh:
                return pickle.load(fh)
        except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError):
            return None

    def put(self, key: str, value: Any, store: str = "") -> None:
        """Store ``value`` under ``key``, in the subdirectory ``store`` when one is given."""
        path = self._path(key, store)
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, delete=False, suffix=".tmp") as fh:
            pickle.dump(value, fh, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(fh.name, path)


class FitJob(NamedTuple):
    """The fits of one point: ``fn(task, **data)`` for each task, cached under its key.

    ``store`` names the cache's subdirectory its results go to ("": the cache itself).
    """

    fn: Callable[..., Any]
    tasks: list[Any]
    keys: list[str]
    data: dict[str, Any]
    store: str = ""


class FitFailure(NamedTuple):
    """A fit that raised: its error as text (kept in place of its result)."""

    error: str


LOST_FIT_ATTEMPTS = 3
"""Times a fit lost with its worker (killed, restarted after a missed heartbeat, its machine
gone) is sent again, with its data sent again where that went too, before it counts as failed.
A fit that itself ends its workers (Dask's ``KilledWorker``) is not sent again."""

WORKER_WAIT_S = 300.0
"""How long a lost fit waits for a worker to come back (a restart takes seconds)."""


def _guarded(fn: Callable[..., Any], task: Any, **data: Any) -> Any:
    """``fn(task, **data)`` on a worker, its error returned as a :class:`FitFailure`.

    So an exception out of a future is the cluster's (a lost worker or lost data), never the
    fit's.
    """
    try:
        return fn(task, **data)
    except Exception as err:
        return FitFailure(f"{type(err).__name__}: {err}")


class Progress:
    """One line across every fit of a run: done of total, running, failed, cached, time left.

    And how many fits were sent again after a lost worker, when any were.
    """

    LOG_EVERY_S = 30.0
    """Period of the progress lines when stderr is not a terminal (a log file, CI)."""

    def __init__(self, enabled: bool, workers: int) -> None:
        self.enabled, self.workers = enabled, max(workers, 1)
        self.total = self.done = self.failed = self.cached = self.running = self.resent = 0
        self._spent = 0.0
        self._terminal = sys.stderr.isatty()
        self._logged_at: float | None = None  # when a line was last written into a log
        self._last_logged = ""

    def add(self, n: int) -> None:
        """``n`` more fits were asked for."""
        self.total += n
        self.show()

    def finish(self, seconds: float | None, failed: bool = False, cached: bool = False) -> None:
        """One fit ended (``seconds`` of one worker's time, None for a cache hit)."""
        self.done += 1
        self.failed += int(failed)
        self.cached += int(cached)
        if seconds is not None:
            self._spent += seconds
        self.show()

    def left_s(self) -> float | None:
        """Time left from the mean fit so far, spread over the workers (None: no fit yet)."""
        computed = self.done - self.cached - self.failed
        if computed <= 0:
            return None
        return self._spent / computed * (self.total - self.done) / self.workers

    def line(self) -> str:
        """The progress line."""
        left = self.left_s()
        eta = f", about {left:.0f} s left" if left is not None and self.done < self.total else ""
        resent = f", {self.resent} sent again after a lost worker" if self.resent else ""
        return (
            f"fits: {self.done} of {self.total} done ({self.cached} cached), {self.running} "
            f"running, {self.failed} failed{resent}{eta}"
        )

    def show(self) -> None:
        """Rewrite the line on a terminal; into a log, a whole line every ``LOG_EVERY_S``.

        A log file cannot rewrite a line: thousands of carriage-return updates would make one
        line of megabytes that ``tail`` cannot show.
        """
        if not self.enabled:
            return
        if self._terminal:
            print("\r" + self.line(), end="", file=sys.stderr, flush=True)
            return
        now = time.monotonic()
        if self._logged_at is None or now - self._logged_at >= self.LOG_EVERY_S:
            self._logged_at = now
            self._log(self.line())

    def _log(self, line: str) -> None:
        """One whole line into the log, unless it repeats the last one."""
        if line != self._last_logged:
            self._last_logged = line
            print(line, file=sys.stderr, flush=True)

    def close(self) -> None:
        """End the display: a newline after the last rewrite, or the final line into a log."""
        if not (self.enabled and self.total):
            return
        if self._terminal:
            print(file=sys.stderr, flush=True)
        else:
            self._log(self.line())


class FitExecutor:
    """Runs a function over fit tasks: here, or on a Dask client; caches results by key.

    Args:
        client: A ``distributed.Client`` (None: run in this process).
        cache: Where finished fits are kept (None: nowhere).
        progress: Show the progress line on stderr.
    """

    def __init__(
        self, client: Any = None, cache: FitCache | None = None, progress: bool = False
    ) -> None:
        self.client = client
        self.cache = cache
        workers = len(client.scheduler_info().get("workers", {})) if client is not None else 1
        self.progress = Progress(progress, workers)

    def map(
        self, fn: Callable[..., Any], tasks: list[Any], keys: list[str], **data: Any
    ) -> list[Any]:
        """``fn(task, **data)`` for every task, in task order.

        Raises:
            PerceptionError: when any fit failed (the others are cached all the same), naming
                the first failure.
        """
        results = self.run_jobs([FitJob(fn, tasks, keys, data)])[0]
        check(results)
        return results

    def run_jobs(self, jobs: list[FitJob]) -> list[list[Any]]:
        """Every fit of every job, submitted together; results per job, in task order.

        On a cluster, jobs stream in order with at most :meth:`window` fits in flight, so
        the workers never wait at the boundary between two points, and a job's data is on
        the workers only while its fits run. Each task carries its own seed, so results do not
        depend on the order fits finish in. A fit that raised gives a :class:`FitFailure` in
        its place (see :func:`check`); the others are kept and cached all the same.
        """
        results: list[list[Any]] = [[None] * len(job.tasks) for job in jobs]
        todo: list[tuple[int, int]] = []  # (job, task) not in the cache
        self.progress.add(sum(len(job.tasks) for job in jobs))
        for j, job in enumerate(jobs):
            for i, key in enumerate(job.keys):
                hit = self.cache.get(key, job.store) if self.cache is not None else None
                if hit is not None:
                    results[j][i] = hit
                    self.progress.finish(None, cached=True)
                else:
                    todo.append((j, i))
        if self.client is None:
            for j, i in todo:
                self.progress.running = 1
                t0 = time.perf_counter()
                results[j][i] = self._call(jobs[j], i)
                self.progress.running = 0
                self._done(jobs[j], i, results[j][i], time.perf_counter() - t0)
        elif todo:
            self._run_on_cluster(jobs, todo, results)
        return results

    def window(self) -> int:
        """Fits kept in flight on a cluster: enough to cover a point boundary on every worker."""
        return 4 * self.progress.workers

    def _call(self, job: FitJob, i: int) -> Any:
        return _guarded(job.fn, job.tasks[i], **job.data)  # one failed fit keeps the others

    def _done(self, job: FitJob, i: int, value: Any, seconds: float | None) -> None:
        """Cache a finished fit (task ``i`` of ``job``) and count it."""
        failed = isinstance(value, FitFailure)
        if self.cache is not None and not failed:
            self.cache.put(job.keys[i], value, job.store)
        self.progress.finish(seconds, failed=failed)

    def _run_on_cluster(
        self, jobs: list[FitJob], todo: list[tuple[int, int]], results: list[list[Any]]
    ) -> None:
        from distributed import KilledWorker, as_completed

        by_job: dict[int, list[int]] = {}
        for j, i in todo:
            by_job.setdefault(j, []).append(i)
        queue = iter(by_job.items())
        # data on the workers, by identity: (value, its future, jobs in flight using it,
        # generation: how many times it was sent, so a loss resends it once, not once per fit)
        live: dict[int, list[Any]] = {}
        left: dict[int, int] = {}
        futures: dict[Any, tuple[int, int, dict[int, int]]] = {}  # -> job, task, generations
        attempts: dict[tuple[int, int], int] = {}
        running = as_completed()

        def submit(j: int, i: int) -> None:
            job, shared, generations = jobs[j], {}, {}
            for name, value in job.data.items():
                hit = live[id(value)]
                if hit[1] is None:  # sent once, to every worker
                    hit[1] = self.client.scatter(value, broadcast=True)
                    hit[3] += 1
                shared[name], generations[id(value)] = hit[1], hit[3]
            attempt = attempts.setdefault((j, i), 0)
            key = f"fit-{job.keys[i]}" + (f"-again{attempt}" if attempt else "")
            future = self.client.submit(
                _guarded, job.fn, job.tasks[i], **shared, key=key, pure=False
            )
            futures[future] = (j, i, generations)
            running.add(future)

        def submit_next() -> bool:
            item = next(queue, None)
            if item is None:
                return False
            j, items = item
            for value in jobs[j].data.values():
                live.setdefault(id(value), [value, None, 0, 0])[2] += 1
            left[j] = len(items)
            for i in items:
                submit(j, i)
            return True

        while len(futures) < self.window() and submit_next():
            pass
        self.progress.running = min(len(futures), self.progress.workers)
        last = time.perf_counter()
        for future in running:
            j, i, generations = futures.pop(future)
            try:  # the fit's own errors come back as a FitFailure (_guarded): this is the cluster's
                results[j][i] = future.result()
            except KilledWorker as err:  # the fit itself ended worker after worker: not again
                results[j][i] = FitFailure(f"{type(err).__name__}: {err}")
            except Exception as err:  # lost with its worker, or its data lost with one
                attempts[(j, i)] += 1
                lost = f"{type(err).__name__}: {err}"
                if attempts[(j, i)] <= LOST_FIT_ATTEMPTS:
                    for value in jobs[j].data.values():
                        hit = live[id(value)]
                        if hit[3] == generations[id(value)]:  # not yet sent again since
                            hit[1] = None
                    try:
                        self.client.wait_for_workers(1, timeout=WORKER_WAIT_S)
                        submit(j, i)
                        self.progress.resent += 1
                        continue
                    except Exception as again:  # no worker came back, or the send failed
                        lost = f"{type(again).__name__}: {again}"
                results[j][i] = FitFailure(
                    f"lost with a worker {attempts[(j, i)]} times; the last: {lost}"
                )
            left[j] -= 1
            if not left[j]:  # the workers may drop data no job in flight uses
                for value in jobs[j].data.values():
                    hit = live[id(value)]
                    hit[2] -= 1
                    if not hit[2]:
                        del live[id(value)]
            while len(futures) < self.window() and submit_next():
                pass
            self.progress.running = min(len(futures), self.progress.workers)
            now = time.perf_counter()
            # on W busy workers a fit ends about every (fit time / W): W x the gap per fit
            self._done(jobs[j], i, results[j][i], (now - last) * self.progress.workers)
            last = now

    def close_line(self) -> None:
        """End the progress line (see :meth:`Progress.close`)."""
        self.progress.close()


def check(results: list[Any]) -> None:
    """Raise when a job's results hold a failed fit.

    Raises:
        PerceptionError: naming how many fits failed and the first failure.
    """
    errors = [r.error for r in results if isinstance(r, FitFailure)]
    if errors:
        raise PerceptionError(
            f"{len(errors)} of {len(results)} fits failed (finished ones are kept for a "
            f"rerun); the first: {errors[0]}"
        )


@contextlib.contextmanager
def fit_executor(
    scheduler: str | None = None,
    workers: int | None = None,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> Iterator[FitExecutor]:
    """The executor a command asked for (``--scheduler`` / ``--workers`` / neither).

    Args:
        scheduler: Address of an existing scheduler (``tcp://HOST:PORT``).
        workers: Start a local cluster of this many single-threaded worker processes.
        cache_dir: Where finished fits are kept (None: no cache).
        progress: Show the progress line.

    Raises:
        PerceptionError: both options, a bad worker count, or a scheduler that cannot be
            reached.
    """
    if scheduler and workers:
        raise PerceptionError("Give '--scheduler' or '--workers', not both.")
    if workers is not None and workers < 1:
        raise PerceptionError(f"The '--workers' option must be >= 1. Got {workers} instead.")
    cache = FitCache(cache_dir) if cache_dir is not None else None
    if not scheduler and not workers:
        ex = FitExecutor(None, cache, progress)
        yield ex
        ex.close_line()
        return
    from distributed import Client, LocalCluster

    with contextlib.ExitStack() as stack:
        try:
            if scheduler:
                client = stack.enter_context(Client(scheduler, timeout="10s"))
            else:
                cluster = stack.enter_context(
                    LocalCluster(
                        n_workers=workers,
                        threads_per_worker=1,
                        processes=True,
                        dashboard_address=None,
                    )
                )
                client = stack.enter_context(Client(cluster))
        except (OSError, TimeoutError) as err:
            raise PerceptionError(f"Cannot reach the Dask scheduler {scheduler!r}: {err}") from err
        ex = FitExecutor(client, cache, progress)
        yield ex
        ex.close_line()
