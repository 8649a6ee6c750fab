"""From transport chunks to stamped :class:`EventBlock`: the two NUSkin decoding paths.

:class:`WordStream` stamps receiver words with the arrival clock; :class:`AcesLineStream`
times ACES line events by the line's sample clock.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.nuskin.clock import ArrivalClock
from ext_sense_drivers.nuskin.wire import FlagPolarity, WordDecoder
from ext_sense_drivers.transports.base import Chunk
from ext_sense_runtime.records import EventBlock


class BatchCounters(NamedTuple):
    """The four counters every ``TaxelEventBatch`` carries (monotonic since start)."""

    words_total: int
    resyncs: int
    skipped_bytes: int
    bad_taxel_words: int


class FlaggedEvents(NamedTuple):
    """Decoded events and each one's flag bit as received (``None`` for the ACES line).

    The bit travels beside the :class:`EventBlock`, the event record of every package.
    """

    events: EventBlock
    flag: npt.NDArray[np.uint8] | None

    @classmethod
    def concat(cls, parts: list[FlaggedEvents]) -> FlaggedEvents:
        """Join parts; the flag is ``None`` unless some part has one (the others get zeros)."""
        events = EventBlock.concat([p.events for p in parts])
        if all(p.flag is None for p in parts):
            return cls(events, None)
        flags = [p.flag if p.flag is not None else np.zeros(p.events.size, np.uint8) for p in parts]
        return cls(events, np.concatenate(flags).astype(np.uint8, copy=False))


class WordStream:
    """Receiver words -> events stamped by ``clock`` (default: a 1 Mbit/s :class:`ArrivalClock`)."""

    def __init__(
        self,
        flag_polarity: FlagPolarity = FlagPolarity.IGNORE,
        clock: ArrivalClock | None = None,
    ) -> None:
        self.decoder = WordDecoder(flag_polarity)
        self.clock = clock if clock is not None else ArrivalClock.for_baud(1_000_000)

    def feed(self, chunk: Chunk) -> EventBlock:
        """Decode the chunk's words and spread them over the time since the previous read."""
        return self.feed_flagged(chunk).events

    def feed_flagged(self, chunk: Chunk) -> FlaggedEvents:
        """:meth:`feed`, keeping each word's flag bit as received."""
        words = self.decoder.feed(chunk.data)
        t_ns = self.clock.stamp(words.size, chunk.t_ns, len(chunk.data))
        return FlaggedEvents(EventBlock(t_ns, words.taxel, words.polarity, words.value), words.flag)

    def restart(self) -> EventBlock:
        """Count a held-back partial word as skipped: the new connection cannot complete it."""
        self.decoder.flush()
        return EventBlock.empty()

    @property
    def batch_counters(self) -> BatchCounters:
        """Words, resyncs, skipped bytes, out-of-range taxel words."""
        c = self.decoder.counters
        return BatchCounters(c.words, c.resyncs, c.skipped_bytes, c.bad_taxel_words)

    def diagnostics(self) -> dict[str, object]:
        """Decoder counters."""
        c = self.decoder.counters
        return {
            "bytes_decoded": c.bytes_in,
            "words_total": c.words,
            "resyncs": c.resyncs,
            "skipped_bytes": c.skipped_bytes,
            "bad_taxel_words": c.bad_taxel_words,
        }


class AcesLineStream:
    """Raw ACES line samples -> events timed by the line's sample clock.

    The first chunk of each connection fixes sample 0 at its arrival minus the duration of the
    samples before it (no drift correction). ``decoder_kwargs`` go to ``LineDecoder``.
    """

    def __init__(self, **decoder_kwargs: object) -> None:
        from ext_sense_drivers.aces.decoder import LineDecoder

        self._factory = LineDecoder
        self._kwargs = decoder_kwargs
        self._decoder = None
        self._probe = LineDecoder(**decoder_kwargs)  # validates the arguments now
        self.samples_before = 0
        """Samples sent before the next chunk on a stream joined late (a packet's
        ``time_base``); used and reset by the first chunk of each connection."""
        self._done = dict.fromkeys(
            (
                "detections",
                "samples",
                "nonfinite_samples",
                "bytes_dropped",
                "overload_samples",
                "rejected",
                "unresolved",
            ),
            0,
        )

    def feed(self, chunk: Chunk) -> EventBlock:
        """Decode the samples; events come out up to the decoder's latency later."""
        from ext_sense_drivers.aces.sample_clock import sample_to_ns
        from ext_sense_drivers.aces.wire import BYTES_PER_SAMPLE

        if self._decoder is None:
            n = self.samples_before + len(chunk.data) // BYTES_PER_SAMPLE
            self.samples_before = 0
            rate = self._probe.bank.sample_rate_hz
            t0 = int(chunk.t_ns) - int(sample_to_ns(np.int64(n), rate))
            self._decoder = self._factory(t0_ns=t0, **self._kwargs)
        return self._decoder.feed(chunk.data)

    def feed_flagged(self, chunk: Chunk) -> FlaggedEvents:
        """:meth:`feed`; the line has no flag bit, so the flag is ``None``."""
        return FlaggedEvents(self.feed(chunk), None)

    def restart(self) -> EventBlock:
        """Flush the decoder (signatures cut by the drop are found if most of them arrived)."""
        if self._decoder is None:
            return EventBlock.empty()
        block = self._decoder.flush()
        c = self._decoder.counters
        for key in self._done:
            self._done[key] += int(getattr(c, key))
        self._decoder = None
        return block

    def _total(self, key: str) -> int:
        now = int(getattr(self._decoder.counters, key)) if self._decoder is not None else 0
        return self._done[key] + now

    @property
    def batch_counters(self) -> BatchCounters:
        """Detections as words; dropped odd bytes as skipped; no resyncs or bad taxels."""
        return BatchCounters(self._total("detections"), 0, self._total("bytes_dropped"), 0)

    def diagnostics(self) -> dict[str, object]:
        """Decoder counters and the residual energy ratio of the current connection."""
        values: dict[str, object] = {key: self._total(key) for key in self._done}
        if self._decoder is not None:
            c = self._decoder.counters
            ratio = c.residual_energy / c.input_energy if c.input_energy > 0 else 0.0
            values["residual_energy_ratio"] = f"{ratio:.4f}"
        return values
