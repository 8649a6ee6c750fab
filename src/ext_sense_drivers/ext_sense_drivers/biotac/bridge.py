"""The ext_sense BioTac bridge protocol: frame encoder and the vectorised streaming decoder.

A frame (all integers little-endian, see ``docs/biotac_bridge.md``)::

    0xAA 0x55 | seq u16 | sensor_id u8 | n_words u8 | n_words x (b0, b1) | crc u16

The CRC-16/CCITT-FALSE covers ``seq`` through the last word byte. A standard frame holds 44
words (96 bytes). The decoder searches for the sync pair, checks the CRC, and on a failure
steps one byte past the failed sync and searches again, so no intact frame behind garbage is
ever skipped. Frames with another word count that pass their CRC are skipped whole and counted
(``other_frames``); they are reserved for later use of the protocol.

:class:`BridgeDecoder` finds all sync candidates of a chunk, checks all CRCs and decodes all
words with NumPy in one pass; :class:`ext_sense_drivers.biotac.reference.ReferenceDecoder` is
the plain per-byte decoder with the same results and counters.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ext_sense_drivers.biotac.crc import (
    crc16_ccitt_false,
    crc16_ccitt_false_columns,
    crc16_ccitt_false_rows,
)
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.words import (
    ELECTRODE_POSITIONS,
    N_ELECTRODES,
    N_PAC,
    PAC_POSITIONS,
    PDC_POSITION,
    TAC_POSITION,
    TDC_POSITION,
    WORD_STATUS,
    WORD_VALUE,
    WORDS_PER_FRAME,
    WordStatus,
    encode_values,
)

SYNC = b"\xaa\x55"
HEADER = struct.Struct("<2sHBB")
"""Sync, seq, sensor_id, n_words."""
CRC = struct.Struct("<H")
HEADER_SIZE = HEADER.size  # 6
FRAME_OVERHEAD = HEADER_SIZE + CRC.size  # 8
STANDARD_FRAME_SIZE = FRAME_OVERHEAD + 2 * WORDS_PER_FRAME  # 96
MAX_SENSORS = 5
"""Sensor slots 0..4 share one bridge link."""
SEQ_MODULO = 1 << 16
SEQ_BACKWARD = 1 << 15
"""A sequence step of this many frames or more is taken as a restart, not as a gap."""


def encode_frame(seq: int, sensor_id: int, replies: ArrayLike | bytes) -> bytes:
    """One bridge frame around reply words as the BioTac sent them.

    Args:
        seq: Frame sequence number, 0..65535 (the bridge wraps it).
        sensor_id: Sensor slot, 0..255 on the wire (0..4 are valid slots).
        replies: Reply words ``b0 << 8 | b1`` (up to 255 of them, any bits, so corrupt words
            and error replies can be encoded), or their bytes in wire order.

    Returns:
        The frame bytes, CRC included.

    Raises:
        BioTacError: A field is out of range.
    """
    if not 0 <= int(seq) < SEQ_MODULO:
        raise BioTacError(f"The 'seq' field must be in 0..65535. Got {seq} instead.")
    if not 0 <= int(sensor_id) <= 0xFF:
        raise BioTacError(f"The 'sensor_id' field must be in 0..255. Got {sensor_id} instead.")
    if isinstance(replies, bytes | bytearray | memoryview):
        payload = bytes(replies)
        if len(payload) % 2:
            raise BioTacError(f"Reply bytes must come in pairs. Got {len(payload)} bytes.")
    else:
        words = np.asarray(replies, dtype=np.int64).ravel()
        if words.size and (words.min() < 0 or words.max() > 0xFFFF):
            raise BioTacError(
                f"Reply words must be in 0..0xFFFF. Got {words.min()}..{words.max()} instead."
            )
        payload = words.astype(">u2").tobytes()
    n_words = len(payload) // 2
    if n_words > 0xFF:
        raise BioTacError(f"A frame holds at most 255 words. Got {n_words} instead.")
    body = HEADER.pack(SYNC, int(seq), int(sensor_id), n_words)[2:] + payload
    return SYNC + body + CRC.pack(crc16_ccitt_false(body))


def standard_replies(
    pac: ArrayLike, electrodes: ArrayLike, pdc: int, tac: int, tdc: int
) -> NDArray[np.uint16]:
    """The 44 reply words of a standard frame, with correct parity.

    Args:
        pac: 22 PAC samples, 0..4095.
        electrodes: 19 electrode values E01..E19, 0..4095.
        pdc: Static pressure, 0..4095.
        tac: AC temperature, 0..4095.
        tdc: DC temperature, 0..4095.

    Returns:
        ``(44,)`` uint16 reply words in bridge order.

    Raises:
        BioTacError: A length or value is wrong.
    """
    pac_arr = np.asarray(pac)
    el_arr = np.asarray(electrodes)
    if pac_arr.shape != (N_PAC,):
        raise BioTacError(f"'pac' must hold {N_PAC} values. Got shape {pac_arr.shape}.")
    if el_arr.shape != (N_ELECTRODES,):
        raise BioTacError(
            f"'electrodes' must hold {N_ELECTRODES} values. Got shape {el_arr.shape}."
        )
    values = np.zeros(WORDS_PER_FRAME, dtype=np.int64)
    values[PAC_POSITIONS] = pac_arr
    values[ELECTRODE_POSITIONS] = el_arr
    values[[PDC_POSITION, TAC_POSITION, TDC_POSITION]] = [pdc, tac, tdc]
    if not np.issubdtype(pac_arr.dtype, np.integer) or not np.issubdtype(el_arr.dtype, np.integer):
        raise BioTacError("'pac' and 'electrodes' must be integers in 0..4095.")
    return encode_values(values)


def encode_standard_frame(
    seq: int, sensor_id: int, pac: ArrayLike, electrodes: ArrayLike, pdc: int, tac: int, tdc: int
) -> bytes:
    """A standard 44-word frame carrying 12-bit values (see :func:`standard_replies`)."""
    return encode_frame(seq, sensor_id, standard_replies(pac, electrodes, pdc, tac, tdc))


def encode_frames(seq: ArrayLike, sensor_id: ArrayLike, replies: ArrayLike) -> bytes:
    """Many standard frames at once (vectorised; for simulators and benchmarks).

    Args:
        seq: ``(n,)`` sequence numbers 0..65535.
        sensor_id: ``(n,)`` sensor slots 0..255.
        replies: ``(n, 44)`` reply words.

    Returns:
        The ``n`` frames back to back.

    Raises:
        BioTacError: A shape or value is wrong.
    """
    seq_a = np.asarray(seq, dtype=np.int64).ravel()
    sid = np.asarray(sensor_id, dtype=np.int64).ravel()
    rep = np.asarray(replies, dtype=np.int64)
    n = seq_a.size
    if sid.size != n or rep.shape != (n, WORDS_PER_FRAME):
        raise BioTacError(
            f"encode_frames needs seq (n,), sensor_id (n,), replies (n, 44). Got "
            f"{seq_a.shape}, {sid.shape}, {rep.shape}."
        )
    if n and (seq_a.min() < 0 or seq_a.max() >= SEQ_MODULO or sid.min() < 0 or sid.max() > 255):
        raise BioTacError("encode_frames: 'seq' must be in 0..65535 and 'sensor_id' in 0..255.")
    if n and (rep.min() < 0 or rep.max() > 0xFFFF):
        raise BioTacError("encode_frames: reply words must be in 0..0xFFFF.")
    out = np.empty((n, STANDARD_FRAME_SIZE), dtype=np.uint8)
    out[:, 0], out[:, 1] = 0xAA, 0x55
    out[:, 2], out[:, 3] = seq_a & 0xFF, seq_a >> 8
    out[:, 4], out[:, 5] = sid, WORDS_PER_FRAME
    out[:, 6:94:2] = rep >> 8
    out[:, 7:94:2] = rep & 0xFF
    crc = crc16_ccitt_false_rows(out[:, 2:94]).astype(np.int64)
    out[:, 94], out[:, 95] = crc & 0xFF, crc >> 8
    return out.tobytes()


class Frame(NamedTuple):
    """One decoded standard frame (plain Python values; used by tests and the JSON form).

    ``pac``, ``electrodes``, ``pdc``, ``tac``, ``tdc`` hold 0 where the word is invalid (see
    ``invalid_mask``, bit i = word position i). ``gap`` is the number of frames of this sensor
    missing just before this one; ``seq_reset`` marks a backwards step of ``seq``.
    ``offset`` is the stream position of the frame's first sync byte.
    """

    sensor_id: int
    seq: int
    gap: int
    seq_reset: bool
    pac: tuple[int, ...]
    electrodes: tuple[int, ...]
    pdc: int
    tac: int
    tdc: int
    invalid_mask: int
    parity_errors: int
    error_replies: int
    offset: int


class BridgeFrames(NamedTuple):
    """A batch of decoded standard frames as parallel arrays (``n`` frames).

    Attributes:
        sensor_id: ``(n,)`` uint8, 0..4.
        seq: ``(n,)`` uint16.
        gap: ``(n,)`` int64, frames of that sensor missing just before this one.
        seq_reset: ``(n,)`` bool, ``seq`` stepped backwards (bridge restart): no gap counted.
        words: ``(n, 44)`` uint16 reply words as received.
        pac: ``(n, 22)`` uint16 PAC samples (0 where invalid).
        electrodes: ``(n, 19)`` uint16 E01..E19 (0 where invalid).
        pdc, tac, tdc: ``(n,)`` uint16 (0 where invalid).
        invalid_mask: ``(n,)`` uint64, bit i set when word i failed parity or was an error reply.
        parity_errors: ``(n,)`` uint8, words of the frame failing parity.
        error_replies: ``(n,)`` uint8, BioTac error replies in the frame.
        offset: ``(n,)`` int64 stream position of each frame's first byte.
    """

    sensor_id: NDArray[np.uint8]
    seq: NDArray[np.uint16]
    gap: NDArray[np.int64]
    seq_reset: NDArray[np.bool_]
    words: NDArray[np.uint16]
    pac: NDArray[np.uint16]
    electrodes: NDArray[np.uint16]
    pdc: NDArray[np.uint16]
    tac: NDArray[np.uint16]
    tdc: NDArray[np.uint16]
    invalid_mask: NDArray[np.uint64]
    parity_errors: NDArray[np.uint8]
    error_replies: NDArray[np.uint8]
    offset: NDArray[np.int64]

    @property
    def n(self) -> int:
        """Number of frames."""
        return int(self.seq.shape[0])

    def rows(self) -> list[Frame]:
        """The frames as :class:`Frame` records."""
        return [
            Frame(
                int(self.sensor_id[k]),
                int(self.seq[k]),
                int(self.gap[k]),
                bool(self.seq_reset[k]),
                tuple(int(v) for v in self.pac[k]),
                tuple(int(v) for v in self.electrodes[k]),
                int(self.pdc[k]),
                int(self.tac[k]),
                int(self.tdc[k]),
                int(self.invalid_mask[k]),
                int(self.parity_errors[k]),
                int(self.error_replies[k]),
                int(self.offset[k]),
            )
            for k in range(self.n)
        ]

    @staticmethod
    def concat(batches: list[BridgeFrames]) -> BridgeFrames:
        """Join batches in order."""
        if not batches:
            return _empty_frames()
        return BridgeFrames(*(np.concatenate(cols) for cols in zip(*batches, strict=True)))


def _empty_frames() -> BridgeFrames:
    """A batch of no frames (its arrays are read-only, so it can be shared)."""
    z = np.zeros(0, dtype=np.uint16)
    return BridgeFrames(
        np.zeros(0, np.uint8),
        z,
        np.zeros(0, np.int64),
        np.zeros(0, bool),
        np.zeros((0, WORDS_PER_FRAME), np.uint16),
        np.zeros((0, N_PAC), np.uint16),
        np.zeros((0, N_ELECTRODES), np.uint16),
        z,
        z,
        z,
        np.zeros(0, np.uint64),
        np.zeros(0, np.uint8),
        np.zeros(0, np.uint8),
        np.zeros(0, np.int64),
    )


@dataclass(frozen=True)
class BridgeCounters:
    """Decoder counters since it was created (monotonic).

    Attributes:
        bytes_total: Bytes fed.
        frames: Standard frames decoded (all sensors).
        skipped_bytes: Bytes that were not part of any CRC-valid frame (garbage, broken frames).
        crc_failures: Sync candidates whose CRC failed (a corrupted frame, or a chance
            ``0xAA 0x55`` in garbage).
        truncated: Sync candidates cut off by the end of the stream or a link reset.
        other_frames: CRC-valid frames with a word count other than 44 (skipped).
        bad_sensor_frames: CRC-valid standard frames naming a slot outside 0..4 (skipped).
        sensor_frames: Standard frames per sensor slot 0..4.
        dropped_frames: Frames missing from sequence gaps, per sensor.
        parity_errors: Words failing their odd-parity check, per sensor.
        error_replies: BioTac error replies, per sensor.
        seq_resets: Backwards steps of the sequence number, per sensor.
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


_EMPTY = _empty_frames()
for _col in _EMPTY:
    _col.flags.writeable = False
_FRAME_COLS = np.arange(STANDARD_FRAME_SIZE)
# Plain ints: comparing an array with an IntEnum member costs several microseconds.
_OK, _PARITY_FAILED, _ERROR_REPLY = (int(v) for v in WordStatus)
_BIT = np.uint64(1) << np.arange(WORDS_PER_FRAME, dtype=np.uint64)


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
    """The counters every bridge decoder keeps, and their snapshot.

    Shared by :class:`BridgeDecoder` and the per-byte ``ReferenceDecoder`` so both report
    through the same code, which the tests compare field by field.
    """

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


class BridgeDecoder(CounterState):
    """Streaming decoder of the bridge byte stream into standard frames (vectorised).

    Feed it chunks as they arrive; each call returns the frames the chunk completed. Chunk
    boundaries never change the result. Bad bytes never raise: they are counted.

    Example::

        dec = BridgeDecoder()
        for chunk in chunks:
            frames = dec.feed(chunk)  # BridgeFrames, frames.n rows
        frames = dec.flush()  # end of stream
        print(dec.counters.summary())
    """

    def __init__(self) -> None:
        self._pending = b""
        self._offset = 0  # stream position of _pending[0]
        self._seq = SequenceTracker()
        self._bytes_total = 0
        self._skipped = 0
        self._crc_failures = 0
        self._truncated = 0
        self._other = 0
        self._bad_sensor = 0

    @property
    def pending_bytes(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._pending)

    def feed(self, chunk: bytes | bytearray | memoryview) -> BridgeFrames:
        """Decode the frames completed by ``chunk``.

        Args:
            chunk: The next bytes of the stream (any length, may be empty).

        Returns:
            The standard frames completed by this chunk, in stream order.
        """
        chunk = bytes(chunk)
        self._bytes_total += len(chunk)
        return self._scan(self._pending + chunk, final=False)

    def flush(self) -> BridgeFrames:
        """End of stream (or link reset): decide on every held-back byte.

        Candidates cut off by the end are counted as ``truncated``; frames behind them are still
        found. The sequence state is kept, so a gap across a reconnection counts as drops.
        """
        return self._scan(self._pending, final=True)

    def _scan(self, data: bytes, final: bool) -> BridgeFrames:
        n = len(data)
        arr = np.frombuffer(data, dtype=np.uint8)
        cands = np.flatnonzero((arr[:-1] == 0xAA) & (arr[1:] == 0x55)) if n >= 2 else arr[:0]
        cands = cands.astype(np.int64)
        if cands.size == 0:
            keep = 1 if (n and data[-1] == 0xAA and not final) else 0
            self._skipped += n - keep
            self._offset += n - keep
            self._pending = data[n - keep :]
            return _EMPTY
        hdr = cands + HEADER_SIZE <= n
        nw = np.full(cands.size, -1, dtype=np.int64)
        nw[hdr] = arr[cands[hdr] + 5]
        total = FRAME_OVERHEAD + 2 * nw
        complete = hdr & (cands + total <= n)
        crc_ok = np.zeros(cands.size, dtype=bool)
        std = np.flatnonzero(complete & (nw == WORDS_PER_FRAME))
        if std.size:
            starts = cands[std]
            rows = arr[starts[:, None] + _FRAME_COLS]
            got = rows[:, 94].astype(np.uint16) | (rows[:, 95].astype(np.uint16) << np.uint16(8))
            crc_ok[std] = crc16_ccitt_false_rows(rows[:, 2:94]) == got
        other = np.flatnonzero(complete & (nw != WORDS_PER_FRAME))
        for length in (
            np.unique(nw[other]) if other.size else ()
        ):  # rare: reserved frames or chance syncs in garbage
            idx = other[nw[other] == length]
            size = FRAME_OVERHEAD + 2 * int(length)
            rows = arr[cands[idx][:, None] + np.arange(size)]
            got = rows[:, -2].astype(np.uint16) | (rows[:, -1].astype(np.uint16) << np.uint16(8))
            crc_ok[idx] = crc16_ccitt_false_columns(rows[:, 2:-2]) == got
        valid = complete & crc_ok
        v_idx = np.flatnonzero(valid)
        v_start, v_end = cands[v_idx], cands[v_idx] + total[v_idx]
        if v_idx.size > 1 and np.any(v_end[:-1] > v_start[1:]):
            acc_idx, stop = self._walk(cands, complete, valid, total, final)
        else:
            acc_idx, stop = v_idx, -1
            if not final and not complete.all():
                for i in np.flatnonzero(~complete):
                    j = np.searchsorted(v_start, cands[i], side="right") - 1
                    if j < 0 or cands[i] >= v_end[j]:
                        stop = int(i)
                        break
            if stop >= 0:
                acc_idx = acc_idx[acc_idx < stop]
        limit = int(cands[stop]) if stop >= 0 else n
        a_start, a_end = cands[acc_idx], cands[acc_idx] + total[acc_idx]
        # Failed candidates the sequential reading would have tried: before the stop point and
        # not inside an accepted frame.
        failed = np.flatnonzero(~valid & (cands < limit))
        if failed.size:
            if a_start.size:
                j = np.searchsorted(a_start, cands[failed], side="right") - 1
                inside = (j >= 0) & (cands[failed] < a_end[np.maximum(j, 0)])
                failed = failed[~inside]
            self._crc_failures += int(np.count_nonzero(complete[failed]))
            self._truncated += int(np.count_nonzero(~complete[failed]))
        if stop < 0:
            tail_free = a_end[-1] if a_end.size else 0
            if not final and n and arr[-1] == 0xAA and n - 1 >= tail_free:
                limit = n - 1
        self._skipped += limit - int((a_end - a_start).sum())
        frames = self._decode(
            arr, a_start[nw[acc_idx] == WORDS_PER_FRAME] if acc_idx.size else a_start
        )
        self._other += int(np.count_nonzero(nw[acc_idx] != WORDS_PER_FRAME))
        self._pending = data[limit:]
        self._offset += limit
        return frames

    @staticmethod
    def _walk(
        cands: NDArray[np.int64],
        complete: NDArray[np.bool_],
        valid: NDArray[np.bool_],
        total: NDArray[np.int64],
        final: bool,
    ) -> tuple[NDArray[np.int64], int]:
        """Sequential choice of frames when valid candidates overlap (rare)."""
        pos, acc = 0, []
        for i, c in enumerate(cands.tolist()):
            if c < pos:
                continue
            if not complete[i] and not final:
                return np.asarray(acc, dtype=np.int64), i
            if valid[i]:
                acc.append(i)
                pos = c + int(total[i])
        return np.asarray(acc, dtype=np.int64), -1

    def _decode(self, arr: NDArray[np.uint8], starts: NDArray[np.int64]) -> BridgeFrames:
        if not starts.size:
            return _EMPTY
        rows = arr[starts[:, None] + _FRAME_COLS]
        sensor = rows[:, 4].copy()
        good = sensor < MAX_SENSORS
        if not good.all():
            self._bad_sensor += int(np.count_nonzero(~good))
            rows, sensor, starts = rows[good], sensor[good], starts[good]
            if not starts.size:
                return _EMPTY
        seq = rows[:, 2:4].view("<u2")[:, 0].astype(np.uint16)
        words = rows[:, 6:94].view(">u2").astype(np.uint16)
        values = WORD_VALUE[words]
        status = WORD_STATUS[words]
        invalid = status != _OK
        mask = (invalid * _BIT).sum(axis=1, dtype=np.uint64)
        n_par = (status == _PARITY_FAILED).sum(axis=1, dtype=np.uint8)
        n_err = (status == _ERROR_REPLY).sum(axis=1, dtype=np.uint8)
        gap, reset = self._seq.steps(sensor, seq)
        if sensor.size <= SMALL_BATCH:
            for s, p, e in zip(sensor.tolist(), n_par.tolist(), n_err.tolist(), strict=True):
                self._seq.parity[s] += p
                self._seq.errors[s] += e
        else:
            par = np.bincount(sensor, weights=n_par, minlength=MAX_SENSORS)
            err = np.bincount(sensor, weights=n_err, minlength=MAX_SENSORS)
            for s in range(MAX_SENSORS):
                self._seq.parity[s] += int(par[s])
                self._seq.errors[s] += int(err[s])
        return BridgeFrames(
            sensor_id=sensor,
            seq=seq,
            gap=gap,
            seq_reset=reset,
            words=words,
            pac=values[:, PAC_POSITIONS],
            electrodes=values[:, ELECTRODE_POSITIONS],
            pdc=values[:, PDC_POSITION],
            tac=values[:, TAC_POSITION],
            tdc=values[:, TDC_POSITION],
            invalid_mask=mask,
            parity_errors=n_par,
            error_replies=n_err,
            offset=starts + self._offset,
        )
