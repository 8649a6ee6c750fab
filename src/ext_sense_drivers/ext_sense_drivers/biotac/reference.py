"""A plain per-byte decoder of the bridge stream: the oracle for the tests and the benchmark.

It reads the stream as the protocol is written down; ``BridgeDecoder`` must give identical
frames and counters for any stream cut into any chunks.
"""

from __future__ import annotations

from ext_sense_drivers.biotac.counters import CounterState, SequenceTracker
from ext_sense_drivers.biotac.crc import crc16_ccitt_false
from ext_sense_drivers.biotac.frame_layout import FRAME_OVERHEAD, HEADER_SIZE, MAX_SENSORS
from ext_sense_drivers.biotac.frames import Frame
from ext_sense_drivers.biotac.words import (
    ELECTRODE_POSITIONS,
    PAC_POSITIONS,
    PDC_POSITION,
    TAC_POSITION,
    TDC_POSITION,
    WORDS_PER_FRAME,
    decode_word,
)

_PAC = [int(p) for p in PAC_POSITIONS]
_ELECTRODES = [int(p) for p in ELECTRODE_POSITIONS]


class ReferenceDecoder(CounterState):
    """Per-byte streaming decoder with the semantics of ``BridgeDecoder`` (slow, obvious)."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._offset = 0
        self._seq = SequenceTracker()
        self._bytes_total = 0
        self._skipped = 0
        self._crc_failures = 0
        self._truncated = 0
        self._other = 0
        self._bad_sensor = 0

    def feed(self, chunk: bytes) -> list[Frame]:
        """Decode the frames completed by ``chunk``."""
        self._bytes_total += len(chunk)
        self._buf.extend(chunk)
        return self._scan(final=False)

    def flush(self) -> list[Frame]:
        """End of stream: decide on every held-back byte."""
        return self._scan(final=True)

    def _skip(self, n: int) -> None:
        del self._buf[:n]
        self._offset += n
        self._skipped += n

    def _scan(self, final: bool) -> list[Frame]:
        out: list[Frame] = []
        buf = self._buf
        while True:
            i = 0
            while i + 1 < len(buf) and not (buf[i] == 0xAA and buf[i + 1] == 0x55):
                i += 1
            if i + 1 >= len(buf):  # no sync pair: keep a last 0xAA that may start one
                keep = 1 if (buf and buf[-1] == 0xAA and not final) else 0
                self._skip(len(buf) - keep)
                return out
            self._skip(i)
            if len(buf) < HEADER_SIZE:
                if not final:
                    return out
                self._truncated += 1
                self._skip(1)
                continue
            n_words = buf[5]
            total = FRAME_OVERHEAD + 2 * n_words
            if len(buf) < total:
                if not final:
                    return out
                self._truncated += 1
                self._skip(1)
                continue
            crc = 0xFFFF
            crc = crc16_ccitt_false(bytes(buf[2 : total - 2]), crc)
            if crc != buf[total - 2] | (buf[total - 1] << 8):
                self._crc_failures += 1
                self._skip(1)
                continue
            frame_bytes = bytes(buf[:total])
            offset = self._offset
            del buf[:total]
            self._offset += total
            if n_words != WORDS_PER_FRAME:
                self._other += 1
                continue
            frame = self._frame(frame_bytes, offset)
            if frame is not None:
                out.append(frame)

    def _frame(self, data: bytes, offset: int) -> Frame | None:
        sensor = data[4]
        if sensor >= MAX_SENSORS:
            self._bad_sensor += 1
            return None
        seq = data[2] | (data[3] << 8)
        values, mask, n_par, n_err = [], 0, 0, 0
        for k in range(WORDS_PER_FRAME):
            value, parity_failed, error = decode_word((data[6 + 2 * k] << 8) | data[7 + 2 * k])
            values.append(value)
            if parity_failed or error:
                mask |= 1 << k
            n_par += parity_failed
            n_err += error
        gap, reset = self._seq.step(sensor, seq)
        self._seq.parity[sensor] += n_par
        self._seq.errors[sensor] += n_err
        return Frame(
            sensor_id=sensor,
            seq=seq,
            gap=gap,
            seq_reset=reset,
            pac=tuple(values[p] for p in _PAC),
            electrodes=tuple(values[p] for p in _ELECTRODES),
            pdc=values[PDC_POSITION],
            tac=values[TAC_POSITION],
            tdc=values[TDC_POSITION],
            invalid_mask=mask,
            parity_errors=n_par,
            error_replies=n_err,
            offset=offset,
        )
