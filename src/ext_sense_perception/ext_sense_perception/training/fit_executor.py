"""Where protocol fits run: in this process or on a Dask cluster, with a cache of finished fits.

``ext-sense evaluate`` and ``ext-sense report`` take ``--workers N`` (a local cluster started
and stopped by the command, one single-threaded worker process per core) or ``--scheduler
tcp://HOST:PORT`` (an existing cluster whose workers run this project's environment); without
either, fits run here, one after the other. Each call to :meth:`FitExecutor.map` sends its data
to the workers once (``scatter``) and its split tasks after it; finished fits are stored in a
:class:`FitCache` as they arrive, so an interrupted run loses only the fits that were running.
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
from typing import Any

from ext_sense_perception.errors import PerceptionError


class FitCache:
    """Finished fits on disk, one pickle per key.

    Each is written atomically (a temporary file renamed into place), so a killed run leaves no
    half-written entry.
    """

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)  # made by the first put: a refused run leaves nothing

    def _path(self, key: str) -> Path:
        return self.directory / key[:2] / f"{key}.pkl"

    def get(self, key: str) -> Any | None:
        """The stored result of ``key`` (None: not there or unreadable)."""
        path = self._path(key)
        try:
            with open(path, "rb") as fh:
                return pickle.load(fh)
        except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError):
            return None

    def put(self, key: str, value: Any) -> None:
        """Store ``value`` under ``key``."""
        path = self._path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, delete=False, suffix=".tmp") as fh:
            pickle.dump(value, fh, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(fh.name, path)


class Progress:
    """One line across every fit of a run: done of total, running, failed, cached, time left."""

    def __init__(self, enabled: bool, workers: int) -> None:
        self.enabled, self.workers = enabled, max(workers, 1)
        self.total = self.done = self.failed = self.cached = self.running = 0
        self._spent = 0.0

    def add(self, n: int) -> None:
        """``n`` more fits were asked for."""
        self.total += n
        self.show()

    def finish(self, seconds: float | None, failed: bool = False, cached: bool = False) -> None:
        """One fit ended (``seconds`` of work, None for a cache hit)."""
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
        eta = f", about {left:.0f} s left" if left is not None else ""
        return (
            f"fits: {self.done} of {self.total} done ({self.cached} cached), {self.running} "
            f"running, {self.failed} failed{eta}"
        )

    def show(self) -> None:
        """Rewrite the line on a terminal (stderr)."""
        if self.enabled:
            print("\r" + self.line(), end="", file=sys.stderr, flush=True)


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
        results: list[Any] = [None] * len(tasks)
        todo = []
        self.progress.add(len(tasks))
        for i, key in enumerate(keys):
            hit = self.cache.get(key) if self.cache is not None else None
            if hit is not None:
                results[i] = hit
                self.progress.finish(None, cached=True)
            else:
                todo.append(i)
        errors: list[str] = []
        if self.client is None:
            for i in todo:
                self.progress.running = 1
                t0 = time.perf_counter()
                try:
                    results[i] = fn(tasks[i], **data)
                except Exception as err:  # one failed fit must not lose the others
                    errors.append(f"{type(err).__name__}: {err}")
                    self.progress.running = 0
                    self.progress.finish(time.perf_counter() - t0, failed=True)
                    continue
                self._store(keys[i], results[i])
                self.progress.running = 0
                self.progress.finish(time.perf_counter() - t0)
        elif todo:
            self._map_on_cluster(fn, tasks, keys, todo, data, results, errors)
        if errors:
            raise PerceptionError(
                f"{len(errors)} of {len(tasks)} fits failed (finished ones are kept for a "
                f"rerun); the first: {errors[0]}"
            )
        return results

    def _store(self, key: str, value: Any) -> None:
        if self.cache is not None:
            self.cache.put(key, value)

    def _map_on_cluster(self, fn, tasks, keys, todo, data, results, errors) -> None:
        from distributed import as_completed

        shared = {name: self.client.scatter(value, broadcast=True) for name, value in data.items()}
        started = time.perf_counter()
        futures = {
            self.client.submit(fn, tasks[i], **shared, key=f"fit-{keys[i]}", pure=False): i
            for i in todo
        }
        self.progress.running = len(futures)
        for future in as_completed(futures):
            i = futures[future]
            self.progress.running -= 1
            try:
                results[i] = future.result()
            except Exception as err:  # one failed fit must not lose the others
                errors.append(f"{type(err).__name__}: {err}")
                self.progress.finish(None, failed=True)
                continue
            self._store(keys[i], results[i])
            self.progress.finish((time.perf_counter() - started) / max(len(todo), 1))

    def close_line(self) -> None:
        """End the progress line (a newline after the last rewrite)."""
        if self.progress.enabled and self.progress.total:
            print(file=sys.stderr)


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
