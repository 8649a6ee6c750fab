"""The NUSkin receiver's event words: a vectorised streaming decoder and an encoder.

Each event is a 4-byte word; the top 3 bits of every byte tag its place (docs/nuskin.md)::

    byte 0  001x xTTT    T: taxel bits 6..4 (x: unused, 0)
    byte 1  010T TTTF    T: taxel bits 3..0, F: flag bit
    byte 2  100V VVVV    V: value bits 9..5
    byte 3  111V VVVV    V: value bits 4..0

A word is any four consecutive bytes tagged 1, 2, 4, 7; runs cannot overlap, so every intact
word is recovered however the stream is cut or damaged. Bytes outside words are
``skipped_bytes``, each run of them one ``resyncs``; taxel ids outside 1..80 are
``bad_taxel_words``. The real receivers leave the flag bit 0, so by default polarity is 0
(unknown); :attr:`FlagPolarity.IS_POSITIVE` reads flag 1 as +1, 0 as -1.
"""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.nuskin.errors import NuskinError
from ext_sense_drivers.nuskin.layout import FIRST_TAXEL, LAST_TAXEL

WORD_BYTES = 4
TAGS = (0b001, 0b010, 0b100, 0b111)
"""Tag (top 3 bits) of bytes 0..3 of a word."""
TAG_SHIFT = 5
MAX_TAXEL_FIELD = 127
MAX_VALUE = 1023

# The four tag bytes of a word read as one little-endian uint32, and the mask over the tags.
_WORD_TAGS_LE = 0x20 | 0x40 << 8 | 0x80 << 16 | 0xE0 << 24
_TAG_MASK_LE = 0xE0E0E0E0


class FlagPolarity(IntEnum):
    """How the flag bit of byte 1 becomes an event polarity."""

    IGNORE = 0
    """Every event gets polarity 0 (unknown): the real receivers leave the bit at 0."""
    IS_POSITIVE = 1
    """Flag 1 is a positive spike (+1), flag 0 a negative one (-1)."""


class DecodedWords(NamedTuple):
    """Words decoded from one chunk, ``(n,)`` arrays in stream order.

    ``polarity`` is the flag bit mapped by the decoder's :class:`FlagPolarity`; ``end`` the stream
    offset just past each word's last byte.
    """

    taxel: npt.NDArray[np.uint16]
    value: npt.NDArray[np.uint16]
    flag: npt.NDArray[np.uint8]
    polarity: npt.NDArray[np.int8]
    end: npt.NDArray[np.int64]

    @property
    def size(self) -> int:
        """Number of words."""
        return int(self.taxel.shape[0])


class WordCounters(NamedTuple):
    """Decoder counters since creation (monotonic)."""

    bytes_in: int
    words: int
    """Valid words returned."""
    resyncs: int
    skipped_bytes: int
    bad_taxel_words: int
    """Well-tagged words dropped because their taxel id is outside 1..80."""


def _polarity(flag: npt.NDArray[np.uint8], mode: FlagPolarity) -> npt.NDArray[np.int8]:
    if mode == FlagPolarity.IS_POSITIVE:
        return (flag.astype(np.int8) << 1) - np.int8(1)
    return np.zeros(flag.shape, np.int8)


class WordDecoder:
    """Streaming decoder: feed chunks split anywhere, get the words completed so far.

    Holds back at most 3 bytes (a word's valid beginning) between calls.
    """

    def __init__(self, flag_polarity: FlagPolarity = FlagPolarity.IGNORE) -> None:
        self.flag_polarity = FlagPolarity(flag_polarity)
        self._carry = np.empty(0, np.uint8)
        self._in_gap = False
        self._bytes_in = 0
        self._words = 0
        self._resyncs = 0
        self._skipped = 0
        self._bad_taxel = 0

    @property
    def counters(self) -> WordCounters:
        """Counters since creation."""
        return WordCounters(
            self._bytes_in, self._words, self._resyncs, self._skipped, self._bad_taxel
        )

    @property
    def pending(self) -> int:
        """Bytes held back as the possible start of a word."""
        return int(self._carry.shape[0])

    def feed(self, chunk: bytes | bytearray | memoryview | npt.NDArray[np.uint8]) -> DecodedWords:
        """The words ``chunk`` (any length) completes, in order; bad bytes are counted."""
        data = np.frombuffer(chunk, np.uint8) if not isinstance(chunk, np.ndarray) else chunk
        data = data.astype(np.uint8, copy=False).ravel()
        base = self._bytes_in - self._carry.shape[0]  # stream offset of buf[0]
        self._bytes_in += int(data.shape[0])
        buf = np.concatenate((self._carry, data)) if self._carry.shape[0] else data
        n = int(buf.shape[0])
        aligned = _aligned_words(buf)
        if aligned is not None:
            first, words = aligned
            starts = None
            tail = first + WORD_BYTES * int(words.shape[0])
        else:
            starts = _word_starts(buf)
            words = _gather_words(buf, starts)
            tail = int(starts[-1]) + WORD_BYTES if starts.shape[0] else 0
        carry_start = n - _prefix_suffix_len(buf, tail)
        if starts is None:
            self._count_aligned_gaps(first, tail, carry_start)
            end = np.arange(base + first + WORD_BYTES, base + tail + 1, WORD_BYTES, dtype=np.int64)
        else:
            self._count_gaps(starts, carry_start)
            end = starts.astype(np.int64) + (base + WORD_BYTES)
        self._carry = buf[carry_start:].copy()
        return self._extract(words, end)

    def flush(self) -> None:
        """End of stream: count held-back bytes as skipped (they can no longer form a word)."""
        if self._carry.shape[0]:
            self._skipped += int(self._carry.shape[0])
            if not self._in_gap:
                self._resyncs += 1
            self._in_gap = True
            self._carry = np.empty(0, np.uint8)

    def _count_gaps(self, starts: npt.NDArray[np.intp], carry_start: int) -> None:
        if starts.shape[0] == 0:
            if carry_start > 0:
                self._skipped += carry_start
                if not self._in_gap:
                    self._resyncs += 1
                self._in_gap = True
            return
        region_start = np.empty(starts.shape[0] + 1, np.intp)
        region_start[0] = 0
        region_start[1:] = starts + WORD_BYTES
        region_end = np.empty_like(region_start)
        region_end[:-1] = starts
        region_end[-1] = carry_start
        gaps = region_end - region_start
        self._skipped += int(gaps.sum())
        runs = int(np.count_nonzero(gaps))
        if gaps[0] > 0 and self._in_gap:
            runs -= 1  # the run began in an earlier chunk and was counted there
        self._resyncs += runs
        self._in_gap = bool(gaps[-1] > 0)

    def _count_aligned_gaps(self, first: int, tail: int, carry_start: int) -> None:
        """Gap counting when the words run back to back from ``first`` to ``tail``."""
        lead, trail = first, carry_start - tail
        self._skipped += lead + trail
        if lead and not self._in_gap:
            self._resyncs += 1
        if trail:
            self._resyncs += 1
        self._in_gap = bool(trail)

    def _extract(self, words: npt.NDArray[np.uint32], end: npt.NDArray[np.int64]) -> DecodedWords:
        """Fields of little-endian words (byte 0 in the low bits), dropping bad taxels."""
        taxel = (((words & 0x07) << 4) | ((words >> 9) & 0x0F)).astype(np.uint16)
        value = ((((words >> 16) & 0x1F) << 5) | ((words >> 24) & 0x1F)).astype(np.uint16)
        flag = ((words >> 8) & 1).astype(np.uint8)
        ok = (taxel - np.uint16(FIRST_TAXEL)) < np.uint16(LAST_TAXEL)  # 1..80, wraps 0 high
        n_bad = int(ok.shape[0] - np.count_nonzero(ok))
        if n_bad:
            self._bad_taxel += n_bad
            taxel, value, flag, end = taxel[ok], value[ok], flag[ok], end[ok]
        self._words += int(taxel.shape[0])
        return DecodedWords(taxel, value, flag, _polarity(flag, self.flag_polarity), end)


def _word_starts(buf: npt.NDArray[np.uint8]) -> npt.NDArray[np.intp]:
    """Indices ``i`` where ``buf[i:i+4]`` is tagged 1, 2, 4, 7."""
    n = int(buf.shape[0])
    if n < WORD_BYTES:
        return np.empty(0, np.intp)
    tag = buf >> TAG_SHIFT
    hit = tag[: n - 3] == TAGS[0]
    hit &= tag[1 : n - 2] == TAGS[1]
    hit &= tag[2 : n - 1] == TAGS[2]
    hit &= tag[3:] == TAGS[3]
    return np.flatnonzero(hit)


def _gather_words(
    buf: npt.NDArray[np.uint8], starts: npt.NDArray[np.intp]
) -> npt.NDArray[np.uint32]:
    """The words at ``starts`` as little-endian uint32 (byte 0 in the low bits)."""
    words = buf[starts].astype(np.uint32)
    for k in (1, 2, 3):
        words |= buf[starts + k].astype(np.uint32) << (8 * k)
    return words


def _aligned_words(
    buf: npt.NDArray[np.uint8],
) -> tuple[int, npt.NDArray[np.uint32]] | None:
    """Fast path for a clean stream: the first word's offset and the words from it (LE uint32).

    ``None`` when not every 4 bytes from the first byte tagged 1 are a word.
    """
    n = int(buf.shape[0])
    first = 0
    while first < WORD_BYTES and first < n and (int(buf[first]) >> TAG_SHIFT) != TAGS[0]:
        first += 1
    m = (n - first) // WORD_BYTES
    if first == WORD_BYTES or m == 0:
        return None
    span = buf[first : first + m * WORD_BYTES]
    words = np.ascontiguousarray(span).view("<u4")  # may be unaligned: NumPy copes
    if ((words & np.uint32(_TAG_MASK_LE)) != np.uint32(_WORD_TAGS_LE)).any():
        return None
    return first, words


def _prefix_suffix_len(buf: npt.NDArray[np.uint8], tail: int) -> int:
    """Length (0..3) of the suffix of ``buf[tail:]`` that is a word's valid beginning."""
    n = int(buf.shape[0])
    for k in (3, 2, 1):
        if n - k >= tail and all((int(buf[n - k + j]) >> TAG_SHIFT) == TAGS[j] for j in range(k)):
            return k
    return 0


def encode_words(
    taxel: npt.ArrayLike, value: npt.ArrayLike, flag: npt.ArrayLike | None = None
) -> bytes:
    """Encode events ``(n,)`` as ``4 * n`` bytes of receiver words (NuskinError if out of range).

    The whole 7-bit taxel field 0..127 is accepted (fault injection); ``flag`` ``None`` sends 0,
    as the real receivers do.
    """
    t = np.asarray(taxel, dtype=np.int64).ravel()
    v = np.asarray(value, dtype=np.int64).ravel()
    f = np.zeros_like(t) if flag is None else np.asarray(flag, dtype=np.int64).ravel()
    if not (t.shape == v.shape == f.shape):
        raise NuskinError(
            "The 'taxel', 'value' and 'flag' arrays must have one length. "
            f"Got {t.shape[0]}, {v.shape[0]} and {f.shape[0]} instead."
        )
    _check_range("taxel", t, 0, MAX_TAXEL_FIELD)
    _check_range("value", v, 0, MAX_VALUE)
    _check_range("flag", f, 0, 1)
    out = np.empty((t.shape[0], WORD_BYTES), np.uint8)
    out[:, 0] = (TAGS[0] << TAG_SHIFT) | (t >> 4)
    out[:, 1] = (TAGS[1] << TAG_SHIFT) | ((t & 0x0F) << 1) | f
    out[:, 2] = (TAGS[2] << TAG_SHIFT) | (v >> 5)
    out[:, 3] = (TAGS[3] << TAG_SHIFT) | (v & 0x1F)
    return out.tobytes()


def _check_range(name: str, a: npt.NDArray[np.int64], low: int, high: int) -> None:
    if a.shape[0] and (int(a.min()) < low or int(a.max()) > high):
        bad = a[(a < low) | (a > high)][0]
        raise NuskinError(f"The '{name}' values must be in {low}..{high}. Got {bad} instead.")
