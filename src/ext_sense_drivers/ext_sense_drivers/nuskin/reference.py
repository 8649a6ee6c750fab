"""A plain per-byte decoder of the receiver words: the oracle for the tests and the benchmark."""

from __future__ import annotations

from ext_sense_drivers.nuskin.layout import FIRST_TAXEL, LAST_TAXEL
from ext_sense_drivers.nuskin.wire import TAG_SHIFT, TAGS, WordCounters


class ReferenceDecoder:
    """Per-byte decoder; ``feed`` returns ``(taxel, value, flag)`` tuples."""

    def __init__(self) -> None:
        self._word: list[int] = []
        self._in_gap = False
        self.bytes_in = 0
        self.words = 0
        self.resyncs = 0
        self.skipped_bytes = 0
        self.bad_taxel_words = 0

    @property
    def counters(self) -> WordCounters:
        """Counters in the vectorised decoder's shape."""
        return WordCounters(
            self.bytes_in, self.words, self.resyncs, self.skipped_bytes, self.bad_taxel_words
        )

    def feed(self, chunk: bytes) -> list[tuple[int, int, int]]:
        """Decode the words that ``chunk`` completes."""
        out: list[tuple[int, int, int]] = []
        for byte in chunk:
            self.bytes_in += 1
            tag = byte >> TAG_SHIFT
            if tag == TAGS[len(self._word)]:
                self._word.append(byte)
                if len(self._word) == 4:
                    self._emit(out)
                continue
            self._skip(len(self._word))
            if tag == TAGS[0]:
                self._word = [byte]
            else:
                self._word = []
                self._skip(1)
        return out

    def _skip(self, n: int) -> None:
        if n:
            self.skipped_bytes += n
            if not self._in_gap:
                self.resyncs += 1
            self._in_gap = True

    def _emit(self, out: list[tuple[int, int, int]]) -> None:
        b0, b1, b2, b3 = self._word
        self._word = []
        self._in_gap = False
        taxel = (b0 & 0x07) << 4 | (b1 >> 1) & 0x0F
        if not FIRST_TAXEL <= taxel <= LAST_TAXEL:
            self.bad_taxel_words += 1
            return
        self.words += 1
        out.append((taxel, (b2 & 0x1F) << 5 | (b3 & 0x1F), b1 & 1))
