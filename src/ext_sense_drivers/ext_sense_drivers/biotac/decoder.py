"""The vectorised streaming decoder of the BioTac bridge protocol.

On a failed CRC it steps one byte past the sync and searches again, so no intact frame behind
garbage is skipped. CRC-valid frames of another word count are skipped and counted
(``other_frames``). Same results and counters as the per-byte ``ReferenceDecoder``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ext_sense_drivers.biotac.counters import SMALL_BATCH, CounterState, SequenceTracker
from ext_sense_drivers.biotac.crc import crc16_ccitt_false_columns, crc16_ccitt_false_rows
from ext_sense_drivers.biotac.frame_layout import (
    FRAME_OVERHEAD,
    HEADER_SIZE,
    MAX_SENSORS,
    STANDARD_FRAME_SIZE,
)
from ext_sense_drivers.biotac.frames import EMPTY_FRAMES, BridgeFrames
from ext_sense_drivers.biotac.words import (
    ELECTRODE_POSITIONS,
    PAC_POSITIONS,
    PDC_POSITION,
    TAC_POSITION,
    TDC_POSITION,
    WORD_STATUS,
    WORD_VALUE,
    WORDS_PER_FRAME,
    WordStatus,
)

_FRAME_COLS = np.arange(STANDARD_FRAME_SIZE)
# Plain ints: comparing an array with an IntEnum member costs several microseconds.
_OK, _PARITY_FAILED, _ERROR_REPLY = (int(v) for v in WordStatus)
_BIT = np.uint64(1) << np.arange(WORDS_PER_FRAME, dtype=np.uint64)


class BridgeDecoder(CounterState):
    """Streaming decoder of the bridge bytes into standard frames; chunking never matters.

    Bad bytes never raise: they are counted.
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
        """The standard frames ``chunk`` (any length) completes, in stream order."""
        chunk = bytes(chunk)
        self._bytes_total += len(chunk)
        return self._scan(self._pending + chunk, final=False)

    def flush(self) -> BridgeFrames:
        """End of stream: decide on every held-back byte (cut-off candidates are ``truncated``).

        The sequence state is kept, so a gap across a reconnection counts as drops.
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
            return EMPTY_FRAMES
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
            return EMPTY_FRAMES
        rows = arr[starts[:, None] + _FRAME_COLS]
        sensor = rows[:, 4].copy()
        good = sensor < MAX_SENSORS
        if not good.all():
            self._bad_sensor += int(np.count_nonzero(~good))
            rows, sensor, starts = rows[good], sensor[good], starts[good]
            if not starts.size:
                return EMPTY_FRAMES
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
