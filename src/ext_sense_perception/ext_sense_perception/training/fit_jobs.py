"""Where protocol fits run, on joblib: here or on a Dask cluster, with a cache of finished fits.

``--workers N`` starts a local cluster, ``--scheduler`` uses an existing one, else fits run
here. Finished fits are cached by this process as they arrive (:class:`FitCache`), so an
interrupted run loses only the running fits and workers need no shared file system. No ROS.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, NamedTuple

from joblib import Memory, Parallel, delayed, parallel_config
from tqdm import tqdm

from ext_sense_perception.errors import PerceptionError

LOST_FIT_ATTEMPTS = 3
"""Times the remaining fits are sent again after the cluster lost a worker (and its data)."""

WORKER_WAIT_S = 300.0
"""How long fits sent again wait for a worker to come back (a restart takes seconds)."""

LOG_EVERY_S = 30.0
"""Period of the progress line when stderr is not a terminal (a log file, CI)."""


def _kept(key: str, value: Any) -> Any:
    """A finished fit as ``joblib.Memory`` keeps it: found by its key alone."""
    return value


class FitCache:
    """Finished fits on disk by key, in ``joblib.Memory`` stores under ``directory`` (made on put).

    Joblib writes entries atomically and empties a store when :func:`_kept`'s code changes.
    """

    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)
        self._memos: dict[str, Any] = {}

    def _memo(self, store: str) -> Any:
        if store not in self._memos:
            memory = Memory(self.directory / store, verbose=0)
            memo = memory.cache(_kept, ignore=["value"])
            memo.check_call_in_cache("", None)  # records _kept's code (a new store's first
            self._memos[store] = memo  # check would miss); joblib empties it when that changes
        return self._memos[store]

    def __contains__(self, key: str) -> bool:
        """Whether ``key`` has a stored result in the main store (not read)."""
        return self.directory.is_dir() and self._memo("").check_call_in_cache(key, None)

    def get(self, key: str, store: str = "") -> Any | None:
        """The stored result of ``key`` (None: not there or unreadable)."""
        if not (self.directory / store).is_dir():
            return None
        memo = self._memo(store)
        return memo(key, None) if memo.check_call_in_cache(key, None) else None

    def put(self, key: str, value: Any, store: str = "") -> None:
        """Store ``value`` under ``key``, in the subdirectory ``store`` when one is given."""
        self._memo(store).call(key, value)


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


def _guarded(where: tuple[int, int], fn: Callable[..., Any], task: Any, **data: Any) -> Any:
    """``(where, fn(task, **data))``, a fit's error returned as a :class:`FitFailure`.

    So an exception out of ``Parallel`` is the cluster's, and one failed fit keeps the others.
    """
    try:
        return where, fn(task, **data)
    except Exception as err:
        return where, FitFailure(f"{type(err).__name__}: {err}")


class _Lines:
    """stderr for tqdm in a log: whole lines, each once, not carriage-return rewrites."""

    def __init__(self) -> None:
        self.last = ""

    def write(self, text: str) -> None:
        for line in text.replace("\r", "\n").split("\n"):
            if line.strip() and line != self.last:
                self.last = line
                sys.stderr.write(line.rstrip() + "\n")

    def flush(self) -> None:
        sys.stderr.flush()


class FitRunner:
    """Runs fit jobs with joblib, here or on a Dask ``client`` (None: here); caches results by key.

    ``progress`` shows a progress line on stderr (into a log: a line every :data:`LOG_EVERY_S`).
    """

    def __init__(
        self, client: Any = None, cache: FitCache | None = None, progress: bool = False
    ) -> None:
        self.client, self.cache, self.progress = client, cache, progress
        self.total = self.done = self.cached = self.failed = self.resent = 0
        self._log = _Lines()  # one for the run: its last line is not repeated by the next job

    def map(
        self, fn: Callable[..., Any], tasks: list[Any], keys: list[str], **data: Any
    ) -> list[Any]:
        """``fn(task, **data)`` for every task, in order (PerceptionError: the first failed fit)."""
        results = self.run_jobs([FitJob(fn, tasks, keys, data)])[0]
        check(results)
        return results

    def run_jobs(self, jobs: list[FitJob]) -> list[list[Any]]:
        """Every fit of every job, run together; results per job, in task order.

        Each task carries its own seed, so results do not depend on finishing order. A failed fit
        gives a :class:`FitFailure` in its place (see :func:`check`).
        """
        results: list[list[Any]] = [[None] * len(job.tasks) for job in jobs]
        todo = []
        for j, job in enumerate(jobs):
            for i, key in enumerate(job.keys):
                hit = self.cache.get(key, job.store) if self.cache is not None else None
                results[j][i] = hit
                if hit is None:
                    todo.append((j, i))
        hits = sum(len(job.tasks) for job in jobs) - len(todo)
        self.total += hits + len(todo)  # one count across the runner's jobs
        self.cached += hits
        self.done += hits
        terminal = sys.stderr.isatty()
        with tqdm(
            total=self.total,
            initial=self.done,
            disable=not self.progress,
            file=sys.stderr if terminal else self._log,
            mininterval=0.5 if terminal else LOG_EVERY_S,
            bar_format="fits: {n_fmt} of {total_fmt} done {desc}, about {remaining} left",
            desc=self._status(),
        ) as bar:
            lost = ""
            for attempt in range(LOST_FIT_ATTEMPTS + 1):
                todo = [(j, i) for j, i in todo if results[j][i] is None]
                if not todo:
                    break
                try:
                    for (j, i), value in self._parallel(jobs, todo):
                        results[j][i] = value
                        self._done(jobs[j], i, value, bar)
                except Exception as err:  # the fits' own errors are FitFailures: the cluster's
                    if self.client is None:
                        raise
                    lost = f"lost with a worker {attempt + 1} times; the last: {err!r}"
                    with contextlib.suppress(Exception):  # none back in time: the next fails
                        self.client.wait_for_workers(1, timeout=WORKER_WAIT_S)
                    self.resent += sum(results[j][i] is None for j, i in todo)
                    bar.set_description_str(self._status(), refresh=False)
            for j, i in todo:
                if results[j][i] is None:
                    results[j][i] = FitFailure(lost)
                    self._done(jobs[j], i, results[j][i], bar)
        return results

    def _parallel(self, jobs: list[FitJob], todo: list[tuple[int, int]]) -> Iterator[Any]:
        """The fits of ``todo`` as they end, on the cluster when there is one."""
        calls = (
            delayed(_guarded)(w, jobs[w[0]].fn, jobs[w[0]].tasks[w[1]], **jobs[w[0]].data)
            for w in todo
        )
        if self.client is None:
            yield from Parallel(n_jobs=1, return_as="generator_unordered")(calls)
            return
        with parallel_config(backend="dask", client=self.client, wait_for_workers_timeout=60):
            # one fit per Dask task, four per worker in flight: none waits between points
            yield from Parallel(
                batch_size=1, pre_dispatch="4*n_jobs", return_as="generator_unordered"
            )(calls)

    def _done(self, job: FitJob, i: int, value: Any, bar: tqdm) -> None:
        """Cache a finished fit (task ``i`` of ``job``) and count it."""
        failed = isinstance(value, FitFailure)
        if self.cache is not None and not failed:
            self.cache.put(job.keys[i], value, job.store)
        self.done += 1
        self.failed += int(failed)
        bar.set_description_str(self._status(), refresh=False)
        bar.update(1)

    def _status(self) -> str:
        """The progress line's counts beside done of total."""
        resent = f", {self.resent} sent again after a lost worker" if self.resent else ""
        return f"({self.cached} cached), {self.failed} failed{resent}"


def check(results: list[Any]) -> None:
    """Raise a PerceptionError naming how many of ``results`` failed and the first failure."""
    errors = [r.error for r in results if isinstance(r, FitFailure)]
    if errors:
        raise PerceptionError(
            f"{len(errors)} of {len(results)} fits failed (finished ones are kept for a "
            f"rerun); the first: {errors[0]}"
        )


@contextlib.contextmanager
def fit_runner(
    scheduler: str | None = None,
    workers: int | None = None,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> Iterator[FitRunner]:
    """The runner asked for: an existing ``scheduler``, a local cluster of ``workers``, or here.

    PerceptionError: both options, a bad worker count, or an unreachable scheduler.
    """
    if scheduler and workers:
        raise PerceptionError("Give '--scheduler' or '--workers', not both.")
    if workers is not None and workers < 1:
        raise PerceptionError(f"The '--workers' option must be >= 1. Got {workers} instead.")
    cache = FitCache(cache_dir) if cache_dir is not None else None
    if not scheduler and not workers:
        yield FitRunner(None, cache, progress)
        return
    from distributed import Client, LocalCluster

    with contextlib.ExitStack() as stack:
        try:
            if scheduler:
                client = stack.enter_context(Client(scheduler, timeout="10s"))
            else:
                cluster = LocalCluster(
                    n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
                )
                stack.enter_context(cluster)
                client = stack.enter_context(Client(cluster))
        except (OSError, TimeoutError) as err:
            raise PerceptionError(f"Cannot reach the Dask scheduler {scheduler!r}: {err}") from err
        yield FitRunner(client, cache, progress)
