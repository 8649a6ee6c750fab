"""Liveness of a driver's streams: silence where the device must be sending is a stall.

A powered NUSkin receiver sends its idle stream all the time and a BioTac bridge every
sensor's frames at 100 Hz, so silence while the link is up means the device stopped, which
only the driver can tell. :class:`StreamWatch` follows one stream (WARN past ``warn_ns``,
ERROR past ``error_ns``); :class:`DriverLiveness` reports a driver's watches as one status.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from ext_sense_runtime.diagnostics import Clock, Level
from ext_sense_runtime.stalls import StallCounts, StallTracker
from ext_sense_runtime.stamps import MS, S

NUSKIN_IDLE_WORDS_PER_S = 540.0
"""The NUSkin receiver's idle stream, words/s (real food-poking captures before contact)."""

MIN_INTERVALS = 3
"""Silence shorter than this many expected intervals is never a stall (for low rates)."""


@dataclass
class StreamWatch(StallCounts):
    """The silence of one stream that must keep arriving while the link is up.

    ``stream`` names it in messages ("receiver words from /dev/ttyACM0"); ``expected_rate_hz``
    0 disables the check; silence past ``warn_ns`` is a WARN, past ``error_ns`` an ERROR.
    """

    stream: str
    expected_rate_hz: float
    warn_ns: int
    error_ns: int
    clock: Clock = time.monotonic_ns
    items: int = 0
    last_data_ns: int | None = None
    streaming_since_ns: int | None = None
    """When streaming last began (link up and node active), ``None`` while not streaming."""
    stall: StallTracker = field(init=False)
    """The stall in progress (its silence's start) and the stalls so far."""

    def __post_init__(self) -> None:
        if not self.expected_rate_hz >= 0:  # also refuses NaN
            raise ValueError(
                f"The 'expected_rate_hz' parameter must be >= 0. Got {self.expected_rate_hz} "
                "instead."
            )
        if not 0 < self.warn_ns <= self.error_ns:
            raise ValueError(
                "The stall thresholds must satisfy 0 < warn <= error. Got warn "
                f"{self.warn_ns / MS:g} ms, error {self.error_ns / MS:g} ms instead."
            )
        if self.expected_rate_hz > 0:  # a slow stream's normal gap is no stall
            floor = round(MIN_INTERVALS * S / self.expected_rate_hz)
            self.warn_ns = max(self.warn_ns, floor)
            self.error_ns = max(self.error_ns, self.warn_ns)
        self.stall = StallTracker(self.warn_ns, self.error_ns)

    @property
    def checked(self) -> bool:
        """Whether silence is checked at all (``expected_rate_hz > 0``)."""
        return self.expected_rate_hz > 0

    def on_data(self, n: int, t_ns: int | None = None) -> None:
        """``n`` items arrived, the last at monotonic ``t_ns`` (default: now). Ends a stall."""
        if n <= 0:
            return
        t = self.clock() if t_ns is None else int(t_ns)
        self.items += int(n)
        self.last_data_ns = t if self.last_data_ns is None else max(self.last_data_ns, t)
        self.stall.end(t)

    def set_streaming(self, streaming: bool) -> None:
        """Whether data must be arriving now (link connected, node active).

        Silence counts from the later of the last data and the start of streaming; leaving
        streaming ends a stall (a lost link is the ``link`` status's to report).
        """
        if not streaming:
            self.streaming_since_ns = None
            self.stall.drop()
            return
        now = self.clock()
        if self.streaming_since_ns is None:
            self.streaming_since_ns = now
        if self.checked and not self.stall.stalled and self.silence_ns() > self.warn_ns:
            self.stall.begin(now - self.silence_ns())

    def silence_ns(self) -> int:
        """Time since the last data or the start of streaming (0 while not streaming)."""
        if self.streaming_since_ns is None:
            return 0
        since = self.streaming_since_ns
        if self.last_data_ns is not None:
            since = max(since, self.last_data_ns)
        return max(0, self.clock() - since)

    def level(self) -> Level:
        """OK, WARN (silent past ``warn_ns``) or ERROR (past ``error_ns``) while streaming."""
        return self.stall.level(self.clock())


class DriverLiveness:
    """A driver's watches (one per stream) as one ``liveness`` diagnostics status."""

    def __init__(self, watches: Sequence[StreamWatch]) -> None:
        self.watches = list(watches)
        self._reported = Level.OK

    def set_streaming(self, streaming: bool) -> None:
        """Pass the node's streaming state to every watch (call it every few tens of ms)."""
        for watch in self.watches:
            watch.set_streaming(streaming)

    def level(self) -> Level:
        """The worst watch's level."""
        return max((w.level() for w in self.watches), default=Level.OK)

    def changed(self) -> bool:
        """Whether the level differs from the last time this returned True (publish now)."""
        level = self.level()
        if level == self._reported:
            return False
        self._reported = level
        return True

    def check(self) -> tuple[Level, str, dict[str, object]]:
        """The diagnostics check: naming every silent stream and for how long."""
        values: dict[str, object] = {}
        silent = []
        for i, w in enumerate(self.watches):
            key = f"stream_{i}" if len(self.watches) > 1 else "stream"
            values[key] = w.stream
            values[f"{key}_expected_rate_hz"] = w.expected_rate_hz
            values[f"{key}_silence_ms"] = f"{w.silence_ns() / MS:.0f}"
            values[f"{key}_stalls"] = w.stalls
            values[f"{key}_longest_stall_ms"] = f"{w.longest_stall_ns / MS:.0f}"
            if w.level() > Level.OK:
                silent.append(w)
        if self.watches:
            values["warn_ms"] = f"{self.watches[0].warn_ns / MS:g}"
            values["error_ms"] = f"{self.watches[0].error_ns / MS:g}"
        if silent:
            level = max(w.level() for w in silent)
            names = "; ".join(
                f"no {w.stream} for {w.silence_ns() / MS:.0f} ms "
                f"(expected >= {w.expected_rate_hz:g}/s)"
                for w in silent
            )
            return level, f"stall: {names}", values
        if not any(w.checked for w in self.watches):
            return Level.OK, "not checked: the source is silent when idle", values
        if all(w.streaming_since_ns is None for w in self.watches):
            return Level.OK, "not streaming", values
        return Level.OK, "streaming", values
