"""Training windows cut from a raw NUSkin byte stream by the live graph's own code (no ROS).

Removes the train/serve skew of windows cut at the true onset: the bytes go through the
driver's decoder and arrival clock (``DriverConfig.make_stream``) into
:class:`~ext_sense_perception.online.stage.WindowStage`, the ``contact_window`` node's core. The
writes of each ``read_period_ns`` tick are read together, as the live streamer wakes every
millisecond and the driver reads as soon as bytes wait.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence
from typing import NamedTuple

import numpy as np

from ext_sense_drivers.nuskin.driver_config import DriverConfig
from ext_sense_drivers.transports.base import Chunk
from ext_sense_perception.data.window_set import WindowSet, window_set_of
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.stage import WindowStage
from ext_sense_perception.online.window import ContactWindow, WindowConfig, bin_events
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.records import EventBlock, GroundTruth
from ext_sense_runtime.stamps import MS

DEFAULT_BAUD = 4_000_000
"""The graph's NUSkin link rate (sets the arrival clock's spread cap)."""
READ_PERIOD_NS = MS
"""The live streamer's wake-up period: writes within one are read together."""


class StreamCounts(NamedTuple):
    """What became of the stream's trials and windows."""

    words: int
    windows: int
    labelled: int
    unmatched_windows: int
    missed_trials: int
    skipped_bytes: int


class StreamCut(NamedTuple):
    """What the live graph makes of a byte stream: final windows, stamped events if kept, counts."""

    windows: list[ContactWindow]
    events: EventBlock
    words: int
    skipped_bytes: int


def cut_stream(
    writes: Iterable[tuple[int, bytes]],
    config: WindowConfig | None = None,
    *,
    baud: int = DEFAULT_BAUD,
    read_period_ns: int = READ_PERIOD_NS,
    read_jitter: float = 0.0,
    seed: int = 0,
    keep_events: bool = False,
) -> StreamCut:
    """The final windows (and, with ``keep_events``, the stamped events) of a NUSkin stream.

    ``writes`` are ``(t_ns, bytes)`` per write to the link, in time order; ``config`` defaults to
    the ``contact_window`` node's for taps; ``baud`` is what the arrival clock assumes. Writes
    within one ``read_period_ns`` tick are read together; ``read_jitter`` makes each tick last
    ``read_period_ns * U(1 - j, 1 + j)`` (seeded by ``seed``), as live reads vary. PerceptionError:
    a BioTac configuration, or a read period or jitter out of range.
    """
    config = config or WindowConfig.for_task(Task.TAP_LOCALIZATION, Sensor.NUSKIN)
    if config.sensor is not Sensor.NUSKIN:
        raise PerceptionError(
            f"The 'config.sensor' parameter must be nuskin. Got {config.sensor.label!r} instead."
        )
    if int(read_period_ns) <= 0:
        raise PerceptionError(
            f"The 'read_period_ns' parameter must be > 0. Got {read_period_ns} instead."
        )
    if not 0.0 <= read_jitter < 1.0:
        raise PerceptionError(f"The 'read_jitter' parameter must be in [0, 1). Got {read_jitter}.")
    decode = DriverConfig(baud=int(baud)).make_stream()
    stage = WindowStage(config)
    out: list[ContactWindow] = []
    kept: list[EventBlock] = []
    words = 0
    period = int(read_period_ns)
    rng = np.random.default_rng(seed)

    def read(data: bytes, read_ns: int) -> None:
        nonlocal words
        block = decode.feed(Chunk(data, read_ns))
        if block.t_ns.size:
            words += int(block.t_ns.size)
            if keep_events:
                kept.append(block)
            out.extend(stage.on_block(block))
        out.extend(stage.advance(read_ns))  # the node's timer: data up to now is complete

    pending: list[bytes] = []
    tick_end: int | None = None
    for t_ns, data in writes:
        t = int(t_ns)
        if tick_end is not None and t > tick_end:
            read(b"".join(pending), tick_end)
            pending = []
            tick_end = None
        if tick_end is None:
            if read_jitter:
                step = max(1, round(period * rng.uniform(1 - read_jitter, 1 + read_jitter)))
                tick_end = t + int(rng.integers(0, step))
            else:
                tick_end = -(-t // period) * period
        pending.append(bytes(data))
    if tick_end is not None:
        read(b"".join(pending), tick_end)
    out.extend(stage.flush())
    skipped = int(decode.batch_counters.skipped_bytes)
    finals = [w for w in out if not w.provisional]
    return StreamCut(finals, EventBlock.concat(kept), words, skipped)


def stream_windows(
    writes: Iterable[tuple[int, bytes]],
    config: WindowConfig | None = None,
    *,
    baud: int = DEFAULT_BAUD,
    read_period_ns: int = READ_PERIOD_NS,
    read_jitter: float = 0.0,
    seed: int = 0,
) -> tuple[list[ContactWindow], int, int]:
    """The final windows, decoded word count and skipped bytes of :func:`cut_stream`."""
    cut = cut_stream(
        writes, config, baud=baud, read_period_ns=read_period_ns, read_jitter=read_jitter, seed=seed
    )
    return cut.windows, cut.words, cut.skipped_bytes


def recut(
    events: EventBlock, onsets_ns: np.ndarray, config: WindowConfig, shifts_ns: np.ndarray | int = 0
) -> np.ndarray:
    """Windows ``(n, n_taxels, n_samples)`` of ``events`` cut again with each onset shifted.

    With no shift this is the window the ``contact_window`` node cut at that onset. ``shifts_ns`` is
    one shift or one per onset (positive: the window starts later). PerceptionError: a BioTac
    configuration, or shifts of another length than the onsets.
    """
    if config.sensor is not Sensor.NUSKIN:
        raise PerceptionError(
            f"The 'config.sensor' parameter must be nuskin. Got {config.sensor.label!r} instead."
        )
    onsets = np.asarray(onsets_ns, dtype=np.int64).reshape(-1)
    if np.ndim(shifts_ns) and np.shape(shifts_ns) != onsets.shape:
        raise PerceptionError(
            f"The 'shifts_ns' parameter must be one shift or one per onset ({onsets.size}). "
            f"Got shape {np.shape(shifts_ns)} instead."
        )
    shifts = np.broadcast_to(np.asarray(shifts_ns, dtype=np.int64), onsets.shape)
    period, n = config.period_ns, config.n_samples()
    starts = onsets + shifts - config.pre_ns
    lo = np.searchsorted(events.t_ns, starts, side="left")
    hi = np.searchsorted(events.t_ns, starts + n * period, side="left")
    out = np.zeros((onsets.size, config.n_taxels, n), np.float32)
    for i, (start, a, b) in enumerate(zip(starts.tolist(), lo.tolist(), hi.tolist(), strict=True)):
        out[i] = bin_events(events.select(slice(a, b)), start, n, period, config.n_taxels)
    return out


def match_truths(
    windows: Sequence[ContactWindow], truths: Sequence[GroundTruth], tolerance_ns: int
) -> tuple[list[tuple[ContactWindow, GroundTruth]], int, int]:
    """Label windows by the truth stamped nearest their onset, each truth used once.

    As the estimate monitor scores live estimates.

    Returns:
        ``(pairs of window and truth, windows left unmatched, truths left unmatched)``.
    """
    stamps = np.array([int(g.onset_ns) for g in truths], dtype=np.int64)
    order = np.argsort(stamps, kind="stable")
    stamps = stamps[order]
    taken = np.zeros(stamps.size, dtype=bool)
    picked: list[tuple[ContactWindow, GroundTruth]] = []
    unmatched = 0
    for win in windows:
        if not stamps.size:
            unmatched += 1
            continue
        j = int(np.searchsorted(stamps, win.onset_ns))
        near = [k for k in (j - 1, j) if 0 <= k < stamps.size and not taken[k]]
        best = min(near, key=lambda k: abs(int(stamps[k]) - win.onset_ns), default=None)
        if best is None or abs(int(stamps[best]) - win.onset_ns) > tolerance_ns:
            unmatched += 1
            continue
        taken[best] = True
        picked.append((win, truths[int(order[best])]))
    return picked, unmatched, int((~taken).sum())


def window_set_from_stream(
    writes: Iterable[tuple[int, bytes]],
    truths: Sequence[GroundTruth],
    config: WindowConfig | None = None,
    *,
    baud: int = DEFAULT_BAUD,
    read_period_ns: int = READ_PERIOD_NS,
    read_jitter: float = 0.0,
    seed: int = 0,
    match_tolerance_ns: int = 300 * MS,
    source: str = "stream",
) -> tuple[WindowSet, StreamCounts]:
    """A labelled set and counts, cut from a raw stream exactly as the live graph cuts it.

    Arguments as :func:`cut_stream`'s; ``truths`` are stamped on the writes' clock, and a window is
    labelled by the truth within ``match_tolerance_ns`` of its onset (``groups``: the trial).
    PerceptionError: no window matched any truth, or bad arguments.
    """
    config = config or WindowConfig.for_task(Task.TAP_LOCALIZATION, Sensor.NUSKIN)
    h = hashlib.sha256()

    def hashed(items: Iterable[tuple[int, bytes]]) -> Iterable[tuple[int, bytes]]:
        for t, b in items:
            h.update(b)
            yield t, b

    windows, words, skipped = stream_windows(
        hashed(writes),
        config,
        baud=baud,
        read_period_ns=read_period_ns,
        read_jitter=read_jitter,
        seed=seed,
    )
    picked, unmatched, missed = match_truths(windows, truths, match_tolerance_ns)
    if not picked:
        raise PerceptionError(
            f"The stream gave {len(windows)} windows and {len(truths)} truths but none matched "
            f"within {match_tolerance_ns / MS:g} ms; expected truths stamped on the writes' clock."
        )
    ws = window_set_of(
        config,
        [w for w, _ in picked],
        [g.label for _, g in picked],
        source,
        h.hexdigest()[:16],
        groups=np.asarray([g.trial for _, g in picked]),
        rod_length_m=np.asarray([g.rod_length_m for _, g in picked], dtype=np.float64),
    )
    counts = StreamCounts(words, len(windows), len(picked), unmatched, missed, skipped)
    return ws, counts
