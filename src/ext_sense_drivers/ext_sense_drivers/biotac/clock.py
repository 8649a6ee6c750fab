"""Sample times of BioTac frames in integer nanoseconds.

The BioTac samples 4400 words/s; a standard frame is 44 words, so frames come at 100 Hz per
sensor and PAC (every other word) at 2200 Hz. PAC sample ``i`` of a frame is taken
``i / 2200`` s after the frame's first sample: :func:`pac_offset_ns` gives that offset in
nanoseconds, rounded half up from the exact rational ``i * 1e9 / 2200`` (error <= 0.5 ns). Since
22 samples span exactly 10 ms, sample ``j`` counted from any frame start is at
``frame_start + round(j * 1e9 / 2200)`` with the same rounding, so offsets never accumulate
error across frames. (The public ROS 1 driver computed these offsets in the wrong unit.)

:class:`FrameClock` turns host arrival times of frames into first-sample times. The bridge
clock paces frames every ``frame_period_ns``; the host sees each frame ``lead_ns`` (frame span +
transmission) plus a variable latency after its first sample. Counting frames by sequence
number, ``arrival - k * period`` is the latency plus a constant; its minimum over the last
``window`` frames is the least-delayed frame's, which is the best estimate of the constant.
Error bound (see ``docs/biotac_bridge.md``): the stamp is late by the smallest excess latency
of any frame in the window, plus ``skew * window * period`` for a bridge clock off by ``skew``;
it is never early by more than the clock skew term.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import NDArray

from ext_sense_drivers.biotac.errors import BioTacError
from ext_sense_runtime.stamps import S

WORD_RATE_HZ = 4400
PAC_RATE_HZ = 2200
FRAME_RATE_HZ = 100
FRAME_PERIOD_NS = S // FRAME_RATE_HZ  # 10_000_000, exact
PAC_PERIOD_NS = S // PAC_RATE_HZ  # 454_545: the message field (floor, 0.45 ns short)


def pac_offset_ns(i: int, rate_hz: int = PAC_RATE_HZ) -> int:
    """Offset of PAC sample ``i`` from the frame's first sample, integer ns (half up).

    Args:
        i: Sample index (any integer >= 0; indices past 21 run into the following frames).
        rate_hz: PAC sampling rate in Hz (integer).

    Returns:
        ``round(i * 1e9 / rate_hz)`` computed exactly in integers.

    Raises:
        BioTacError: ``i`` is negative or ``rate_hz`` is not positive.
    """
    if int(i) < 0:
        raise BioTacError(f"The sample index 'i' must be >= 0. Got {i} instead.")
    if int(rate_hz) <= 0:
        raise BioTacError(f"The 'rate_hz' parameter must be > 0. Got {rate_hz} instead.")
    return (2 * int(i) * S + int(rate_hz)) // (2 * int(rate_hz))


def pac_offsets_ns(n: int = 22, rate_hz: int = PAC_RATE_HZ) -> NDArray[np.int64]:
    """Offsets of PAC samples ``0..n-1`` from the frame's first sample, integer ns.

    Returns:
        ``(n,)`` int64, e.g. ``[0, 454545, 909091, ..., 9545455]`` for one standard frame.
    """
    if int(rate_hz) <= 0:
        raise BioTacError(f"The 'rate_hz' parameter must be > 0. Got {rate_hz} instead.")
    i = np.arange(int(n), dtype=np.int64)
    return (2 * i * S + int(rate_hz)) // (2 * int(rate_hz))


def pac_times_ns(first_sample_ns: NDArray[np.int64] | int) -> NDArray[np.int64]:
    """Absolute times of the 22 PAC samples of frames with the given first-sample times.

    Args:
        first_sample_ns: ``(n,)`` (or scalar) first-sample times, integer ns.

    Returns:
        ``(n, 22)`` (or ``(22,)``) int64 sample times.
    """
    first = np.asarray(first_sample_ns, dtype=np.int64)
    return first[..., None] + pac_offsets_ns()


class FrameClock:
    """First-sample times of one sensor's frames from their host arrival times.

    Args:
        frame_period_ns: Bridge frame period (10 ms at the standard 100 frames/s), > 0.
        lead_ns: Time from a frame's first sample to its least-delayed arrival at the host:
            the frame span (10 ms) plus its transmission time, plus any known fixed latency.
        window: Frames over which the minimum latency is tracked (200 = 2 s), >= 1.

    Raises:
        BioTacError: A parameter is out of range.
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
        """Account one frame and return its first-sample time.

        Args:
            arrival_ns: Host arrival time of the frame (its read), integer ns.
            gap: Frames missing just before this one (from the sequence numbers), >= 0.
            restart: The sequence restarted: begin a new model with this frame.

        Returns:
            Estimated host time of the frame's first sample (PAC sample 0), integer ns.
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
