"""The display-rate gate: pictures go out at most ``rate_hz`` times a second.

The view's cost stays flat whatever the sensor does; the latest thing to show waits for the
next frame, never dropped for a newer one unseen.
"""

from __future__ import annotations

from ext_sense.view.errors import ViewError


class DisplayPacer:
    """Allows one frame per ``1 / rate_hz`` seconds of the caller's clock (integer ns).

    Frames are at least 0.8 periods apart: at most ``1.25 * rate_hz`` (in (0, 120]) a second.
    """

    def __init__(self, rate_hz: float) -> None:
        if not 0 < rate_hz <= 120:
            raise ViewError(f"The 'rate_hz' parameter must be in (0, 120]. Got {rate_hz} instead.")
        self.period_ns = int(1e9 / rate_hz)
        self._next_ns: int | None = None
        self.frames = 0

    def ready(self, now_ns: int) -> bool:
        """Whether a frame may go out now; if so, the next one is a period later."""
        if self._next_ns is not None and now_ns < self._next_ns:
            return False
        # from now (no catch-up burst), a fifth early (a timer's jitter skips no frame)
        self._next_ns = now_ns + self.period_ns - self.period_ns // 5
        self.frames += 1
        return True
