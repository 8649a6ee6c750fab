"""Counters of both BioTac bridge decoders (vectorised and reference), compared by the tests."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ext_sense_drivers.biotac.frame_layout import MAX_SENSORS, SEQ_BACKWARD, SEQ_MODULO


@dataclass(frozen=True)
class BridgeCounters:
    """Decoder counters since it was created (monotonic; the last five per sensor slot 0..4).

    ``skipped_bytes`` are in no CRC-valid frame; ``crc_failures`` and ``truncated`` (cut off by
    the stream's end or a link reset) count sync candidates; ``other_frames`` (not 44 words) and
    ``bad_sensor_frames`` (a slot outside 0..4) are CRC-valid but skipped.
    """

    bytes_total: int = 0
    frames: int = 0
    skipped_bytes: int = 0
    crc_failures: int = 0
    truncated: int = 0
    other_frames: int = 0
    bad_sensor_frames: int = 0
    sensor_frames: tuple[int, ...] = (0,) * MAX_SENSORS
    dropped_frames: tuple[int, ...] = (0,) * MAX_SENSORS
    parity_errors: tuple[int, ...] = (0,) * MAX_SENSORS
    error_replies: tuple[int, ...] = (0,) * MAX_SENSORS
    seq_resets: tuple[int, ...] = (0,) * MAX_SENSORS

    def summary(self) -> str:
        """One line for logs and the CLI."""
        return (
            f"bytes={self.bytes_total} frames={self.frames} skipped_bytes={self.skipped_bytes} "
            f"crc_failures={self.crc_failures} truncated={self.truncated} "
            f"other_frames={self.other_frames} bad_sensor_frames={self.bad_sensor_frames} "
            f"dropped_frames={sum(self.dropped_frames)} parity_errors={sum(self.parity_errors)} "
            f"error_replies={sum(self.error_replies)} seq_resets={sum(self.seq_resets)}"
        )


SMALL_BATCH = 8
"""Batches up to this size take the per-frame path of :meth:`SequenceTracker.steps`."""


class SequenceTracker:
    """Per-sensor sequence bookkeeping shared by both decoders: gaps, restarts, counts."""

    def __init__(self) -> None:
        self.last = [-1] * MAX_SENSORS
        self.frames = [0] * MAX_SENSORS
        self.dropped = [0] * MAX_SENSORS
        self.parity = [0] * MAX_SENSORS
        self.errors = [0] * MAX_SENSORS
        self.resets = [0] * MAX_SENSORS

    def step(self, sensor: int, seq: int) -> tuple[int, bool]:
        """Account one frame; return ``(gap, seq_reset)``."""
        last = self.last[sensor]
        self.last[sensor] = seq
        self.frames[sensor] += 1
        if last < 0:
            return 0, False
        d = (seq - last - 1) % SEQ_MODULO
        if d >= SEQ_BACKWARD:
            self.resets[sensor] += 1
            return 0, True
        self.dropped[sensor] += d
        return d, False

    def steps(
        self, sensor: NDArray[np.uint8], seq: NDArray[np.uint16]
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """:meth:`step` over a batch in stream order (vectorised per sensor for big batches)."""
        n = seq.shape[0]
        if n <= SMALL_BATCH:
            pairs = [self.step(int(a), int(b)) for a, b in zip(sensor, seq, strict=True)]
            return (
                np.fromiter((p[0] for p in pairs), np.int64, n),
                np.fromiter((p[1] for p in pairs), bool, n),
            )
        gap = np.zeros(n, dtype=np.int64)
        reset = np.zeros(n, dtype=bool)
        for s in np.unique(sensor):
            sel = np.flatnonzero(sensor == s)
            cur = seq[sel].astype(np.int64)
            prev = np.empty_like(cur)
            prev[0] = self.last[s]
            prev[1:] = cur[:-1]
            d = (cur - prev - 1) % SEQ_MODULO
            back = d >= SEQ_BACKWARD
            if prev[0] < 0:
                d[0], back[0] = 0, False
            d[back] = 0
            gap[sel], reset[sel] = d, back
            self.last[s] = int(cur[-1])
            self.frames[s] += int(sel.size)
            self.dropped[s] += int(d.sum())
            self.resets[s] += int(back.sum())
        return gap, reset


class CounterState:
    """The counters every bridge decoder keeps, and their snapshot."""

    _seq: SequenceTracker
    _bytes_total: int
    _skipped: int
    _crc_failures: int
    _truncated: int
    _other: int
    _bad_sensor: int

    @property
    def counters(self) -> BridgeCounters:
        """A snapshot of the counters."""
        s = self._seq
        return BridgeCounters(
            bytes_total=self._bytes_total,
            frames=sum(s.frames),
            skipped_bytes=self._skipped,
            crc_failures=self._crc_failures,
            truncated=self._truncated,
            other_frames=self._other,
            bad_sensor_frames=self._bad_sensor,
            sensor_frames=tuple(s.frames),
            dropped_frames=tuple(s.dropped),
            parity_errors=tuple(s.parity),
            error_replies=tuple(s.errors),
            seq_resets=tuple(s.resets),
        )
