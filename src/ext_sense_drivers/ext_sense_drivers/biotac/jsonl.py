"""The JSON-lines form of BioTac frames used by ``ext-sense biotac decode`` and ``encode``.

One object per frame (:data:`KEYS`), raw 12-bit counts, ``null`` for a bad word. ``encode``
reads the same shape: ``seq`` may be left out (it counts per sensor), ``parity_errors`` is
ignored, ``null`` is sent as a word failing parity. Malformed input raises only
:class:`BioTacError`, one line starting with where it is (``"values.jsonl, line 3: ..."``).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import numpy as np

from ext_sense_drivers.biotac.encoder import encode_frame
from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_drivers.biotac.frame_layout import MAX_SENSORS, SEQ_MODULO
from ext_sense_drivers.biotac.frames import BridgeFrames
from ext_sense_drivers.biotac.words import (
    ELECTRODE_POSITIONS,
    MAX_VALUE,
    N_ELECTRODES,
    N_PAC,
    PAC_POSITIONS,
    PDC_POSITION,
    TAC_POSITION,
    TDC_POSITION,
    WORDS_PER_FRAME,
    encode_values,
)

KEYS = ("sensor_id", "seq", "pac", "electrodes", "pdc", "tac", "tdc", "parity_errors")
_SHOW_CHARS = 40


def _show(value: Any) -> str:
    """A value for an error message: its repr, cut to a few dozen characters, on one line."""
    try:
        text = repr(value)
    except RecursionError:  # a list nested too deep to print
        return f"a deeply nested {type(value).__name__}"
    return text if len(text) <= _SHOW_CHARS else text[: _SHOW_CHARS - 3] + "..."


def parse_line(raw: bytes, where: str = "line") -> dict[str, Any]:
    """The JSON object on one line of bytes (BioTacError, prefixed ``where``, if it is none)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        bad = raw[err.start : err.start + 1]
        raise BioTacError(f"{where}: not UTF-8 (byte {bad!r} at column {err.start + 1}).") from err
    try:
        record = json.loads(text)
    except json.JSONDecodeError as err:
        raise BioTacError(f"{where}: not JSON: {err.msg} (column {err.colno}).") from err
    except RecursionError as err:
        raise BioTacError(f"{where}: JSON nested too deeply to read.") from err
    except ValueError as err:  # e.g. an integer of more digits than Python converts
        raise BioTacError(f"{where}: unreadable JSON: {str(err).splitlines()[0]}") from err
    if not isinstance(record, dict):
        raise BioTacError(f"{where}: expected a JSON object. Got {type(record).__name__}.")
    return record


def frames_to_records(frames: BridgeFrames) -> Iterator[dict[str, Any]]:
    """The JSON objects of a batch of decoded frames, in order."""
    bits = (frames.invalid_mask[:, None] >> np.arange(WORDS_PER_FRAME, dtype=np.uint64)) & 1
    invalid = bits.astype(bool)
    for k in range(frames.n):
        bad = invalid[k]

        def val(value: int, pos: int, bad: np.ndarray = bad) -> int | None:
            return None if bad[pos] else int(value)

        yield {
            "sensor_id": int(frames.sensor_id[k]),
            "seq": int(frames.seq[k]),
            "pac": [val(v, p) for v, p in zip(frames.pac[k], PAC_POSITIONS, strict=True)],
            "electrodes": [
                val(v, p) for v, p in zip(frames.electrodes[k], ELECTRODE_POSITIONS, strict=True)
            ],
            "pdc": val(frames.pdc[k], PDC_POSITION),
            "tac": val(frames.tac[k], TAC_POSITION),
            "tdc": val(frames.tdc[k], TDC_POSITION),
            "parity_errors": int(frames.parity_errors[k]),
        }


def _field(record: dict[str, Any], key: str, size: int | None, where: str) -> list[Any]:
    if key not in record:
        raise BioTacError(f"{where}: the key '{key}' is missing.")
    value = record[key]
    if size is None:
        value = [value]
    elif not isinstance(value, list) or len(value) != size:
        got = f"{len(value)} values" if isinstance(value, list) else type(value).__name__
        raise BioTacError(f"{where}: '{key}' must be a list of {size} values. Got {got} instead.")
    for v in value:
        if v is not None and (
            isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= MAX_VALUE
        ):
            raise BioTacError(
                f"{where}: '{key}' values must be integers in 0..{MAX_VALUE} or null. "
                f"Got {_show(v)} instead."
            )
    return value


def record_to_frame(
    record: dict[str, Any], next_seq: list[int] | None = None, where: str = "record"
) -> bytes:
    """One bridge frame from a JSON object (BioTacError for a missing key or a bad value).

    ``next_seq`` holds per-sensor next sequence numbers, used and advanced when ``seq`` is absent;
    ``where`` prefixes error messages (``"line 3"``).
    """
    if not isinstance(record, dict):
        raise BioTacError(f"{where}: expected a JSON object. Got {type(record).__name__}.")
    if "sensor_id" not in record:
        raise BioTacError(f"{where}: the key 'sensor_id' is missing.")
    sensor = record["sensor_id"]
    if isinstance(sensor, bool) or not isinstance(sensor, int) or not 0 <= sensor < MAX_SENSORS:
        raise BioTacError(
            f"{where}: 'sensor_id' must be an integer in 0..{MAX_SENSORS - 1}. Got {_show(sensor)}."
        )
    counters = next_seq if next_seq is not None else [0] * MAX_SENSORS
    seq = record.get("seq")
    if seq is None:
        seq = counters[sensor]
    elif isinstance(seq, bool) or not isinstance(seq, int) or not 0 <= seq < SEQ_MODULO:
        raise BioTacError(
            f"{where}: 'seq' must be an integer in 0..65535. Got {_show(seq)} instead."
        )
    counters[sensor] = (seq + 1) % SEQ_MODULO
    values: list[Any] = [None] * WORDS_PER_FRAME
    for key, positions in (("pac", PAC_POSITIONS), ("electrodes", ELECTRODE_POSITIONS)):
        size = N_PAC if key == "pac" else N_ELECTRODES
        for pos, v in zip(positions, _field(record, key, size, where), strict=True):
            values[int(pos)] = v
    for key, pos in (("pdc", PDC_POSITION), ("tac", TAC_POSITION), ("tdc", TDC_POSITION)):
        values[pos] = _field(record, key, None, where)[0]
    missing = np.array([v is None for v in values])
    words = encode_values(np.array([0 if v is None else v for v in values], dtype=np.int64))
    words[missing] ^= np.uint16(0x0100)  # flip b0's parity bit: the word fails its check
    return encode_frame(seq, sensor, words)
