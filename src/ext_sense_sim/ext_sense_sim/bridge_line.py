"""The emulated BioTac bridge between trials: every sensor's frame every 10 ms, always.

A real bridge streams at 100 Hz whatever touches the finger, so the window node closes a BioTac
window with the frames after it and takes silence for a stopped device. :class:`BridgeLine`
writes a trial's frames renumbered so each sensor's sequence runs on, and rest frames between.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ext_sense_drivers.biotac.decoder import BridgeDecoder
from ext_sense_drivers.biotac.encoder import encode_frames
from ext_sense_drivers.biotac.frame_layout import SEQ_MODULO

FRAME_PERIOD_NS = 10_000_000
"""One frame per sensor per 10 ms (100 Hz), as the bridge sends them."""
MAX_CATCH_UP_FRAMES = 20
"""Rest frames written at most at once after a pause; older steps are skipped, as dropped."""


class BridgeLine:
    """Writes the simulator's BioTac frames and keeps the bridge streaming between trials.

    Args:
        write: Sends bytes to the link.
        clock: Epoch integer nanoseconds (the streaming clock).
    """

    def __init__(self, write: Callable[[bytes], object], clock: Callable[[], int]) -> None:
        self._write = write
        self._clock = clock
        self._decoder = BridgeDecoder()
        self._next_seq: dict[int, int] = {}
        self._rest: dict[int, np.ndarray] = {}
        self._last_step_ns: int | None = None
        self.rest_frames = 0
        """Rest frames written so far (counted for the device's diagnostics)."""

    def prime(self, data: bytes) -> None:
        """Take each sensor's rest words from frames not written (the first trial's start)."""
        frames = BridgeDecoder().feed(data)
        for k in range(frames.seq.size):
            self._rest.setdefault(int(frames.sensor_id[k]), frames.words[k].copy())

    def write(self, data: bytes) -> int:
        """Write a trial's frames, renumbered; returns the bytes written."""
        frames = self._decoder.feed(data)
        n = frames.seq.size
        if n == 0:
            return 0
        sensors = frames.sensor_id.astype(np.int64)
        for k, s in enumerate(sensors.tolist()):
            self._rest[s] = frames.words[k].copy()
        out = encode_frames(self._number(sensors), sensors, frames.words)
        self._write(out)
        self._last_step_ns = self._clock()
        return len(out)

    def _number(self, sensors: np.ndarray) -> np.ndarray:
        """The next sequence number of each frame's sensor, each sensor's running on."""
        seq = np.empty(sensors.size, dtype=np.int64)
        for k, s in enumerate(sensors.tolist()):
            seq[k] = self._next_seq.get(s, 0)
            self._next_seq[s] = (seq[k] + 1) % SEQ_MODULO
        return seq

    def idle(self) -> int:
        """Write the rest frames due by now (each sensor's, every 10 ms); returns bytes written."""
        if not self._rest:
            return 0
        now = self._clock()
        if self._last_step_ns is None:
            self._last_step_ns = now - FRAME_PERIOD_NS
        steps = (now - self._last_step_ns) // FRAME_PERIOD_NS
        if steps <= 0:
            return 0
        if steps > MAX_CATCH_UP_FRAMES:
            self._last_step_ns += (steps - MAX_CATCH_UP_FRAMES) * FRAME_PERIOD_NS
            steps = MAX_CATCH_UP_FRAMES
        sensors = sorted(self._rest)
        sid = np.tile(np.array(sensors, dtype=np.int64), steps)
        words = np.stack([self._rest[s] for s in sid.tolist()])
        out = encode_frames(self._number(sid), sid, words)
        self._write(out)
        self._last_step_ns += steps * FRAME_PERIOD_NS
        self.rest_frames += sid.size
        return len(out)
