"""Sample times of BioTac frames in integer nanoseconds.

Frames come at 100 Hz per sensor, PAC samples at 2200 Hz: PAC sample ``i`` is
``round(i * 1e9 / 2200)`` ns after the frame's first sample, exactly, so offsets never
accumulate across frames. :class:`FrameClock` turns arrival times into first-sample times:
the least-delayed frame over a window fixes the offset (docs/biotac_bridge.md).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import NDArray

from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_runtime.stamps import S

PAC_RATE_HZ = 2200
FRAME_RATE_HZ = 100
FRAME_PERIOD_NS = S // FRAME_RATE_HZ  # 10_000_000, exact
PAC_PERIOD_NS = S // PAC_RATE_HZ  # 454_545: the message field (floor, 0.45 ns short)


def pac_offset_ns(i: int, rate_hz: int = PAC_RATE_HZ) -> int:
    """PAC sample ``i``'s offset from the frame, ``round(i * 1e9 / rate_hz)`` exactly (half up)."""
    if int(i) < 0:
        raise BioTacError(f"The sample index 'i' must be >= 0. Got {i} instead.")
    if int(rate_hz) <= 0:
        raise BioTacError(f"The 'rate_hz' parameter must be > 0. Got {rate_hz} instead.")
    return (2 * int(i) * S + int(rate_hz)) // (2 * int(rate_hz))


def pac_offsets_ns(n: int = 22, rate_hz: int = PAC_RATE_HZ) -> NDArray[np.int64]:
    """Offsets ``(n,)`` int64 of PAC samples ``0..n-1`` from the frame's first sample."""
    if int(rate_hz) <= 0:
        raise BioTacError(f"The 'rate_hz' parameter must be > 0. Got {rate_hz} instead.")
    i = np.arange(int(n), dtype=np.int64)
    return (2 * i * S + int(rate_hz)) // (2 * int(rate_hz))


def pac_times_ns(first_sample_ns: NDArray[np.int64] | int) -> NDArray[np.int64]:
    """Times ``(n, 22)`` (or ``(22,)``) of the PAC samples of frames starting at ``(n,)`` times."""
    first = np.asarray(first_sample_ns, dtype=np.int64)
    return first[..., None] + pac_offsets_ns()


class FrameClock:
    """First-sample times of one sensor's frames from their host arrival times.

    ``lead_ns`` is a frame's first sample to its least-delayed arrival (frame span, transmission
    and any known latency), tracked over ``window`` frames (BioTacError if out of range).
    """

    def __init__(
        self,
        frame_period_ns: int = FRAME_PERIOD_NS,
        lead_ns: int = FRAME_PERIOD_NS,
        window: int = 200,
    ) -> None:
        if int(frame_period_ns) <= 0:
            raise BioTacError(
                f"The 'frame_period_ns' parameter must be > 0. Got {frame_period_ns} instead."
            )
        if int(lead_ns) < 0:
            raise BioTacError(f"The 'lead_ns' parameter must be >= 0. Got {lead_ns} instead.")
        if int(window) < 1:
            raise BioTacError(f"The 'window' parameter must be >= 1. Got {window} instead.")
        self.frame_period_ns = int(frame_period_ns)
        self.lead_ns = int(lead_ns)
        self.window = int(window)
        self._k: int | None = None
        self._lows: deque[tuple[int, int]] = deque()  # (k, arrival - k * period), increasing

    @property
    def frame_index(self) -> int | None:
        """Frames counted since the model (re)started, including gaps; None before the first."""
        return self._k

    def restart(self) -> None:
        """Forget the history (e.g. the bridge restarted its sequence numbers)."""
        self._k = None
        self._lows.clear()

    def update(self, arrival_ns: int, gap: int = 0, restart: bool = False) -> int:
        """Account one frame arriving at ``arrival_ns``; return its first sample's host time.

        ``gap`` frames are missing before it; ``restart`` begins a new model with it.
        """
        if restart or self._k is None:
            self.restart()
            self._k = 0
        else:
            self._k += 1 + max(0, int(gap))
        k = self._k
        offset = int(arrival_ns) - k * self.frame_period_ns
        lows = self._lows
        while lows and lows[-1][1] >= offset:
            lows.pop()
        lows.append((k, offset))
        while lows[0][0] <= k - self.window:
            lows.popleft()
        return lows[0][1] + k * self.frame_period_ns - self.lead_ns


def transmission_ns(n_bytes: int, baud: int, bits_per_byte: int = 10) -> int:
    """Time ``n_bytes`` take on an 8N1 serial line at ``baud`` bit/s, integer ns (rounded up)."""
    if int(baud) <= 0:
        raise BioTacError(f"The 'baud' parameter must be > 0. Got {baud} instead.")
    return -(-int(n_bytes) * bits_per_byte * S // int(baud))
