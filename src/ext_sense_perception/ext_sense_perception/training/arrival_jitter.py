"""Arrival jitter as a late reader makes it: re-stamping events per read (no ROS).

The driver stamps each read's words over the time since the previous read, so a late read
stamps a whole chunk at once (issue #16). :class:`ReadDelay` (``bench/bench_arrival.py``) is
the time from when the oldest unread word was due to the read's return. :func:`rechunk_writes`
and :func:`late_read_window_set` replay it on byte streams; :func:`augment` re-stamps binned
windows; :func:`onset_shifted` adds copies at moved onsets.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import NamedTuple

import numpy as np
from joblib import Parallel, delayed

from ext_sense_drivers.nuskin.clock import ArrivalClock
from ext_sense_perception.data.device_stream import (
    READ_PERIOD_NS,
    StreamCounts,
    window_set_from_stream,
)
from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.window import WindowConfig
from ext_sense_perception.profiles import OnsetSource
from ext_sense_runtime.enums import Task
from ext_sense_runtime.records import GroundTruth

LINK_BAUD = 4_000_000
"""The graphs' NUSkin link rate: the arrival clock's spread cap (10 us per word)."""


class ReadDelay(NamedTuple):
    """A measured distribution of read delays as quantiles: ``delay_ns`` at each of ``probs``.

    Linear between them (an inverse CDF); ``source`` says where it was measured.
    """

    probs: tuple[float, ...]
    delay_ns: tuple[int, ...]
    source: str = ""

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``(n,)`` int64 delays, ns."""
        return np.interp(rng.random(n), self.probs, self.delay_ns).astype(np.int64)


MEASURED_READ_DELAY = ReadDelay(
    probs=(0.0, 0.10, 0.25, 0.50, 0.75, 0.90, 0.95, 0.99, 0.999, 1.0),
    delay_ns=(46_000, 101_000, 240_000, 315_000, 456_000, 1_494_000, 1_697_000, 3_596_000,
              5_127_000, 5_269_000),
    source="bench/bench_arrival.py --quick: taps stream, both cores hogged, default scheduling "
    "(2-core VM shared with other jobs)",
)  # fmt: skip
"""Read delays of the driver's reader without real-time priority on a loaded machine."""

DEFAULT_FRACTION: dict[Task, float] = {Task.HANDOVER_STABILITY: 0.5, Task.TAP_LOCALIZATION: 0.25}
"""The recipe's ``arrival_jitter`` when it names none, by task (others: 0): the handover model
is the one live stamps hurt most; a quarter of the tap windows keep the tap model's estimate
within 0.3 cm of an onset moved by 2 ms while its CV stays within 15 % of fresh taps
(``bench/bench_window_shift.py``, docs/perception.md).
"""


def default_fraction(task: Task | str) -> float:
    """The augmented fraction of a task's NUSkin windows when the recipe leaves it open."""
    return DEFAULT_FRACTION.get(Task.parse(task, PerceptionError), 0.0)


def read_groups(
    t_ns: np.ndarray, delay: ReadDelay, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The reads a late reader makes of words due at ``t_ns`` (non-decreasing, ns).

    A read returns ``delay`` after the oldest unread word was due (never before the previous read)
    and takes every word due by then. Returns ``(ends, read_ns)``: read ``k`` takes words
    ``ends[k-1]:ends[k]`` and returns at ``read_ns[k]``.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    ends: list[int] = []
    reads: list[int] = []
    draws = delay.sample(rng, 256)
    i, k, prev = 0, 0, None
    while i < t.size:
        if k == draws.size:
            draws, k = delay.sample(rng, 256), 0
        r = int(t[i]) + int(draws[k])
        k += 1
        if prev is not None and r <= prev:
            r = prev + 1
        j = int(np.searchsorted(t, r, side="right"))
        ends.append(j)
        reads.append(r)
        prev, i = r, j
    return np.asarray(ends, dtype=np.int64), np.asarray(reads, dtype=np.int64)


def restamp(t_ns: np.ndarray, delay: ReadDelay, rng: np.random.Generator) -> np.ndarray:
    """The ``(n,)`` stamps the driver gives words due at ``t_ns`` when read by a late reader."""
    ends, reads = read_groups(t_ns, delay, rng)
    clock = ArrivalClock.for_baud(LINK_BAUD)
    out = np.empty(np.asarray(t_ns).size, dtype=np.int64)
    start = 0
    for end, r in zip(ends.tolist(), reads.tolist(), strict=True):
        out[start:end] = clock.stamp(end - start, r)
        start = end
    return out


def rechunk_writes(
    writes: Iterable[tuple[int, bytes]], delay: ReadDelay, rng: np.random.Generator
) -> list[tuple[int, bytes]]:
    """A device byte stream regrouped into a late reader's reads: ``(read_ns, bytes)``.

    Cut it with ``window_set_from_stream(..., read_period_ns=1)`` (each item one read).
    """
    items = list(writes)
    if not items:
        return []
    t = np.asarray([int(w[0]) for w in items], dtype=np.int64)
    ends, reads = read_groups(t, delay, rng)
    out, start = [], 0
    for end, r in zip(ends.tolist(), reads.tolist(), strict=True):
        out.append((r, b"".join(bytes(b) for _, b in items[start:end])))
        start = end
    return out


def jitter_window(
    x: np.ndarray, period_ns: int, onset_bin: int | None, delay: ReadDelay, rng: np.random.Generator
) -> np.ndarray:
    """One binned NUSkin window as a late reader would have stamped its events (same events, moved).

    ``onset_bin`` is the bin to re-align on the re-stamped onset, or None (an external onset).
    """
    counts = np.rint(x).astype(np.int64)
    channel, sample = np.nonzero(counts)
    if channel.size == 0:
        return x.copy()
    v = counts[channel, sample]
    n = np.abs(v)
    ch = np.repeat(channel, n)
    sign = np.repeat(np.sign(v), n)
    idx = np.repeat(sample, n).astype(np.int64)
    # events of one bin spread evenly inside it (unknown within a bin)
    rank = np.arange(ch.size) - np.repeat(np.cumsum(n) - n, n)
    t = idx * period_ns + ((2 * rank + 1) * period_ns) // (2 * np.repeat(n, n))
    order = np.argsort(t, kind="stable")
    t, ch, sign = t[order], ch[order], sign[order]
    new = restamp(t, delay, rng)
    if onset_bin is not None:
        first = int(np.searchsorted(t, onset_bin * period_ns))
        if first < t.size:
            new = new - (new[first] - t[first])
    bins = np.clip(new // period_ns, 0, x.shape[1] - 1)
    out = np.zeros(counts.shape, dtype=np.float64)
    np.add.at(out, (ch, bins), sign)
    return out.astype(x.dtype)


def augment(
    ws: WindowSet, fraction: float, seed: int = 0, delay: ReadDelay = MEASURED_READ_DELAY
) -> WindowSet:
    """The set with ``fraction`` (0..1) of its NUSkin windows re-stamped by :func:`jitter_window`.

    In place, since copies of one trial in different folds would leak. BioTac windows (stamped by
    the sensor's own clock) are returned as they are.
    """
    if not 0.0 <= float(fraction) <= 1.0:
        raise PerceptionError(
            f"The 'arrival_jitter' parameter must be in [0, 1]. Got {fraction} instead."
        )
    if ws.sensor != "nuskin" or fraction == 0.0 or len(ws.y) == 0:
        return ws
    g = ws.geometry
    profile = ws.task_profile
    onset_bin = (
        None
        if profile.onset_source is OnsetSource.EXTERNAL or g.pre_ns < 0
        else int(g.pre_ns // g.period_ns)
    )
    rng = np.random.default_rng(seed)
    pick = rng.random(len(ws.y)) < float(fraction)
    X = ws.X.copy()  # noqa: N806  (the window matrix, as in WindowSet)
    for i in np.flatnonzero(pick):
        X[i] = jitter_window(ws.X[i], int(g.period_ns), onset_bin, delay, rng)
    return ws._replace(X=X)


ONSET_SHIFT_NS = 2_000_000
"""How far :func:`onset_shifted` moves an onset at most, ns (the arrival clock of a real
link moves it by up to about 2 ms, issue 30).
"""


def shift_window(x: np.ndarray, shift_ns: int, period_ns: int) -> np.ndarray:
    """A binned NUSkin window ``(..., n_samples)`` cut again with its onset moved by ``shift_ns``.

    A bin's events are taken as spread evenly inside it; events moved past either end leave the
    window and none come in (positive shift: the window starts later).
    """
    q, f = divmod(int(shift_ns), int(period_ns))
    counts = np.rint(x).astype(np.float64)
    n = np.abs(counts)
    # of a bin's n evenly spread events, those within f of its start fall one bin earlier
    early = np.sign(counts) * np.clip(np.ceil(n * f / period_ns - 0.5), 0.0, n)
    out = np.zeros_like(counts)
    size = counts.shape[-1]
    for part, move in ((counts - early, -q), (early, -q - 1)):
        lo, hi = max(0, -move), min(size, size - move)
        if lo < hi:
            out[..., lo + move : hi + move] += part[..., lo:hi]
    return out.astype(x.dtype)


def onset_shifted(
    ws: WindowSet, copies: int, max_shift_ns: int = ONSET_SHIFT_NS, seed: int = 0
) -> WindowSet:
    """The set and ``copies`` (>= 0) more of each NUSkin window, onsets moved by ``U(-max, +max)``.

    Copies keep their trial's ``groups`` entry, so folds keep a trial whole. BioTac windows and
    external onsets (stamped by the arm) are returned as they are.
    """
    if copies < 0:
        raise PerceptionError(f"The 'onset_shifts' parameter must be >= 0. Got {copies} instead.")
    if max_shift_ns <= 0:
        raise PerceptionError(
            f"The 'max_shift_ns' parameter must be > 0. Got {max_shift_ns} instead."
        )
    if (
        ws.sensor != "nuskin"
        or copies == 0
        or len(ws.y) == 0
        or ws.task_profile.onset_source is OnsetSource.EXTERNAL
    ):
        return ws
    period = int(ws.geometry.period_ns)
    rng = np.random.default_rng(seed)
    shifts = rng.integers(-int(max_shift_ns), int(max_shift_ns) + 1, size=(copies, len(ws.y)))
    moved = [
        np.stack([shift_window(x, int(s), period) for x, s in zip(ws.X, row, strict=True)])
        for row in shifts
    ]
    tiled = ws.subset(np.tile(np.arange(len(ws.y)), copies + 1))  # labels, trials, sessions
    return tiled._replace(
        X=np.concatenate([ws.X, *moved]), data_hash=f"{ws.data_hash}+{copies}shifted"
    )


def late_read_window_set(
    writes: Sequence[tuple[int, bytes]],
    truths: Sequence[GroundTruth],
    config: WindowConfig,
    late_reads: int = 2,
    delay: ReadDelay = MEASURED_READ_DELAY,
    seed: int = 0,
    source: str = "stream",
    n_jobs: int = 1,
) -> tuple[WindowSet, StreamCounts]:
    """A device stream cut as the live graph cuts it, with ideal reads and again per late read.

    Each of the ``late_reads`` extra cuts reads the bytes as a late reader would (a fresh draw of
    ``delay``), so events, reads and detected onsets move as they do live, which :func:`augment`
    only approximates (docs/benchmarks.md, "Late-read training"). The reads are drawn first, so
    ``n_jobs`` does not change the result. Returns every cut's windows and the ideal cut's counts
    (PerceptionError: no window matched a truth).
    """
    if late_reads < 0:
        raise PerceptionError(
            f"The 'late_reads' parameter must be at least 0. Got {late_reads} instead."
        )
    items = list(writes)
    rng = np.random.default_rng(seed)
    # (reads, read period): the ideal reader's own period, then one read per late read
    streams = [(items, READ_PERIOD_NS)]
    streams += [(rechunk_writes(items, delay, rng), 1) for _ in range(late_reads)]
    cut = delayed(window_set_from_stream)
    # one job runs them here, one after the other (joblib's sequential backend)
    done = Parallel(n_jobs=max(1, min(n_jobs, len(streams))))(
        cut(reads, truths, config, read_period_ns=p, source=source) for reads, p in streams
    )
    return concat_cuts([ws for ws, _ in done]), done[0][1]


def concat_cuts(cuts: Sequence[WindowSet]) -> WindowSet:
    """Window sets of one stream cut several ways, as one set (its ``data_hash`` names them all)."""
    first = cuts[0]
    return first._replace(
        X=np.concatenate([c.X for c in cuts]),
        y=np.concatenate([c.y for c in cuts]),
        groups=np.concatenate([c.groups for c in cuts]),
        rod_length_m=np.concatenate([c.rod_length_m for c in cuts]),
        data_hash=f"{first.data_hash}+{len(cuts) - 1}late",
    )
