"""Liveness of the window node's input stream: stalls, lost input, and the windows they spoil.

A stopped driver or blocked link looks downstream like silence then a burst. A *stall* is silence
while input must arrive (BioTac always, NUSkin while the driver streams) beyond ``warn_ns``
(WARN), then ``error_ns`` (ERROR); a *late packet* comes ``late_ns`` over the usual delay (only
counted: it is still in its window); *lost input* is packets missing by ``seq``. Windows
overlapping a fault are ``degraded`` (:meth:`StreamLiveness.fault_in`); lost input no window
covered that could hold an onset is a lost contact. No ROS; the clock is injectable.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

from ext_sense_runtime.diagnostics import Clock, Level
from ext_sense_runtime.stalls import StallCounts, StallTracker
from ext_sense_runtime.stamps import MS

BASELINE_MESSAGES = 2000
"""Messages over which the stream's usual delay (smallest arrival - stamp) is taken."""
RECENT_NS = 10_000 * MS
"""Lost input keeps the status at WARN this long."""
KEEP_FAULTS_NS = 120_000 * MS
"""Faults older than this (stream time) are forgotten: no window reaches that far back."""
MARGIN_NS = 100_000
"""Wake this long after a stall threshold, so the check finds it passed (strictly greater)."""


@dataclass
class Fault:
    """A stall (``start_ns`` to ``end_ns``, stream time) or lost input.

    A lost-input gap that ``may_hold_contact`` and no window ``covered`` is a lost contact once
    settled.
    """

    start_ns: int
    end_ns: int | None
    reason: str
    may_hold_contact: bool = False
    covered: bool = False


@dataclass
class StreamLiveness(StallCounts):
    """One input stream's arrivals (``stream`` names it): when it stalls, runs late or loses input.

    Thresholds as in the module docstring; ``clock`` (monotonic ns) is injectable so tests never
    sleep.
    """

    stream: str
    expected_rate_hz: float
    warn_ns: int
    error_ns: int
    late_ns: int
    clock: Clock = time.monotonic_ns
    messages: int = 0
    late_packets: int = 0
    max_late_ns: int = 0
    """The latest a packet came, over the stream's usual delay, ns."""
    contacts_lost: int = 0
    """Contacts that may have been lost whole: lost input no window covered (see module)."""
    contacts_degraded: int = 0
    """Contacts whose final window missed input (a stall or lost input in it)."""
    degraded_windows: int = 0
    last_arrival_ns: int | None = None
    last_stamp_ns: int | None = None
    faults: list[Fault] = field(default_factory=list)
    words_lost: int = 0
    """Always 0 (kept on /diagnostics): packets carry no word count, their loss is by ``seq``."""
    packets_lost: int = 0
    """Packets missing by their ``seq`` (raw packets input, :meth:`on_lost_packets`)."""
    contact_words: int = 0
    """Lost packets that could hold an onset: the onset detector's activity threshold; 0: lost
    input is not counted as contacts."""
    contact_horizon_ns: int = 0
    """Stream time after a gap by which any window covering it has been cut, ns."""
    debounce_ns: int = 0
    """Shortest time between two onsets: lost gaps closer than this are one contact, ns."""
    last_loss_ns: int | None = None
    """Monotonic time input was last found lost (WARN for :data:`RECENT_NS` after)."""
    _delays: deque[int] = field(default_factory=lambda: deque(maxlen=BASELINE_MESSAGES))
    _unsettled: list[Fault] = field(default_factory=list)
    _last_lost_contact_ns: int | None = None
    stall: StallTracker = field(init=False)
    """The stall in progress (from the last arrival) and the stalls so far."""

    def __post_init__(self) -> None:
        self.stall = StallTracker(self.warn_ns, self.error_ns)

    @property
    def stalled_since_ns(self) -> int | None:
        """Monotonic time the current stall began (the last arrival), ``None`` when not."""
        return self.stall.stalled_since_ns

    def on_message(self, stamp_ns: int, wall_ns: int) -> None:
        """Count one message (header stamp, host time now): ends a stall, records a late packet."""
        now = self.clock()
        silent = self.stall.end(now)
        if silent is not None:
            for fault in self.faults:
                if fault.end_ns is None:
                    fault.end_ns = stamp_ns
                    fault.reason = (
                        f"stall: no input on {self.stream} for {silent / MS:.0f} ms inside the "
                        "window"
                    )
        delay = wall_ns - stamp_ns
        usual = min(self._delays) if self._delays else delay
        self._delays.append(delay)
        if delay - usual > self.late_ns:
            self.late_packets += 1
            self.max_late_ns = max(self.max_late_ns, delay - usual)
        self.messages += 1
        self.last_arrival_ns, self.last_stamp_ns = now, stamp_ns
        self._settle(stamp_ns)
        self.faults = [  # no window reaches back to older faults
            f for f in self.faults if f.end_ns is None or stamp_ns - f.end_ns < KEEP_FAULTS_NS
        ]

    def on_lost_packets(self, before_ns: int, stamp_ns: int, n: int) -> None:
        """``n`` packets are missing between the packet stamped ``before_ns`` and this one.

        Their word count is unknown; a gap of at least ``contact_words`` packets may have held an
        onset, and is a lost contact if no window comes to cover it.
        """
        if n <= 0:
            return
        self.packets_lost += int(n)
        self.last_loss_ns = self.clock()
        gap = Fault(
            int(before_ns),
            int(stamp_ns),
            f"lost input: {n} packet(s) missing on {self.stream} (seq gap)",
            may_hold_contact=bool(self.contact_words) and n >= self.contact_words,
        )
        self.faults.append(gap)
        if gap.may_hold_contact:
            self._unsettled.append(gap)

    def _settle(self, now_stamp_ns: int) -> None:
        """Count the lost contacts of the gaps the stream is ``contact_horizon_ns`` past."""
        while self._unsettled:
            gap = self._unsettled[0]
            if gap.end_ns is None or now_stamp_ns - gap.end_ns < self.contact_horizon_ns:
                return
            self._unsettled.pop(0)
            if gap.covered:
                continue
            last = self._last_lost_contact_ns
            if last is None or gap.start_ns - last >= self.debounce_ns:
                self.contacts_lost += 1
            self._last_lost_contact_ns = gap.end_ns

    def silence_ns(self) -> int:
        """Time since the last message (0 before the first)."""
        return 0 if self.last_arrival_ns is None else self.clock() - self.last_arrival_ns

    def update(self, streaming: bool) -> None:
        """Start a stall when the stream has been silent past ``warn_ns`` while streaming."""
        if self.stall.stalled or self.last_arrival_ns is None:
            return
        if streaming and self.silence_ns() > self.warn_ns:
            self.stall.begin(self.last_arrival_ns)
            start = self.last_stamp_ns if self.last_stamp_ns is not None else 0
            self.faults.append(
                Fault(start, None, f"stall: no input on {self.stream} (still silent)")
            )

    def next_change_ns(self, streaming: bool) -> int | None:
        """Monotonic time at which the status changes if nothing arrives, or ``None``.

        The node arms its one timer for it, so an idle node does not wake.
        """
        if self.last_arrival_ns is None:
            return None
        if self.stalled_since_ns is not None:
            error_at = self.stalled_since_ns + self.error_ns + MARGIN_NS
            return error_at if self.clock() < error_at else None
        if streaming:
            return self.last_arrival_ns + self.warn_ns + MARGIN_NS
        return None

    @property
    def stalled(self) -> bool:
        """Whether a stall is in progress."""
        return self.stall.stalled

    def fault_in(self, start_ns: int, end_ns: int, final: bool = False) -> str:
        """Why a window spanning ``[start_ns, end_ns]`` (stream time) is degraded, or ``""``.

        The lost input inside is then covered; a ``final`` window with a fault is a degraded
        contact.
        """
        inside = [
            f
            for f in self.faults
            if f.start_ns <= end_ns and (f.end_ns is None or f.end_ns >= start_ns)
        ]
        if not inside:
            return ""
        self.degraded_windows += 1
        self.contacts_degraded += int(final)
        for f in inside:
            f.covered = True
        return "; ".join(dict.fromkeys(f.reason for f in inside))

    def check(self) -> tuple[Level, str, dict[str, object]]:
        """The diagnostics check: ERROR or WARN during a stall (naming the stream), else OK."""
        values: dict[str, object] = {
            "stream": self.stream,
            "expected_rate_hz": self.expected_rate_hz,
            "silence_ms": f"{self.silence_ns() / MS:.0f}",
            "stalls": self.stalls,
            "longest_stall_ms": f"{self.longest_stall_ns / MS:.0f}",
            "late_packets": self.late_packets,
            "max_late_ms": f"{self.max_late_ns / MS:.0f}",
            "degraded_windows": self.degraded_windows,
            "contacts_degraded": self.contacts_degraded,
            "contacts_lost": self.contacts_lost,
            "words_lost": self.words_lost,
            "packets_lost": self.packets_lost,
            "warn_ms": self.warn_ns / MS,
            "error_ms": self.error_ns / MS,
        }
        if self.stalled_since_ns is not None:
            silent = self.clock() - self.stalled_since_ns
            level = self.stall.level(self.clock())
            hit = (
                f", {self.contacts_degraded} contact(s) degraded" if self.contacts_degraded else ""
            )
            return level, f"stall: no input on {self.stream} for {silent / MS:.0f} ms{hit}", values
        if self.last_loss_ns is not None and self.clock() - self.last_loss_ns < RECENT_NS:
            what = f"{self.packets_lost} packets (seq gaps)"  # input is lost only by seq gaps
            return Level.WARN, f"lost input: {what} on {self.stream}", values
        if self.last_arrival_ns is None:
            return Level.OK, f"waiting for {self.stream}", values
        return Level.OK, "streaming", values
