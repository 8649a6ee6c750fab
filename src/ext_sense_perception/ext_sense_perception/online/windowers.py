"""Online, causal contact windows: the shared windower part and the NUSkin windower (no ROS).

A windower is fed the stream in arrival order and returns every window that became complete
(and every provisional, anytime one whose shortened post-onset time passed). Onsets are detected
from the signal (NUSkin here, BioTac in :mod:`.pac_windower`) or given with
:meth:`WindowerBase.mark_onset` (food: the arm's motion start).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.stuck_taxels import StuckTaxels
from ext_sense_perception.online.window import ContactWindow, WindowConfig, bin_events
from ext_sense_runtime.diagnostics import Level
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS


class WindowerCounters(NamedTuple):
    """What a windower did and dropped since it was made (monotonic)."""

    onsets: int = 0
    windows: int = 0
    provisional_windows: int = 0
    truncated_windows: int = 0
    bad_taxel_events: int = 0
    late_events: int = 0
    gap_samples: int = 0
    invalid_samples: int = 0
    joined_mid_stream_windows: int = 0
    one_taxel_bursts: int = 0
    stuck_taxel_windows: int = 0


class _Pending:
    """A detected onset whose window is not yet complete."""

    __slots__ = ("done", "onset_ns")

    def __init__(self, onset_ns: int) -> None:
        self.onset_ns = onset_ns
        self.done: set[int] = set()


class WindowerBase:
    """Onset bookkeeping and window scheduling shared by both sensors."""

    def __init__(self, config: WindowConfig) -> None:
        self.config = config
        self._pending: list[_Pending] = []
        self._next_allowed_ns: int | None = None
        self._now_ns: int | None = None
        self._first_ns: int | None = None
        self._counts = dict.fromkeys(WindowerCounters._fields, 0)

    @property
    def counters(self) -> WindowerCounters:
        """Counters since construction."""
        return WindowerCounters(**self._counts)

    def _joined(self, t_ns: int) -> None:
        """Note that data from ``t_ns`` on was fed (the first call fixes ``_first_ns``)."""
        if self._first_ns is None:
            self._first_ns = int(t_ns)

    @property
    def pending_onsets(self) -> tuple[int, ...]:
        """Onsets whose final window is not yet emitted, ns."""
        return tuple(p.onset_ns for p in self._pending)

    def mark_onset(self, onset_ns: int) -> bool:
        """Start a window at an onset known from outside; False if debounced."""
        return self._add_onset(int(onset_ns))

    def _add_onset(self, onset_ns: int) -> bool:
        if self._next_allowed_ns is not None and onset_ns < self._next_allowed_ns:
            return False
        self._pending.append(_Pending(onset_ns))
        self._next_allowed_ns = onset_ns + self.config.debounce_ns
        self._counts["onsets"] += 1
        return True

    def advance(self, now_ns: int) -> list[ContactWindow]:
        """Declare the stream complete up to ``now_ns`` and return the windows that became due.

        An earlier ``now_ns`` than the current stream time is ignored.
        """
        now_ns = int(now_ns)
        if self._now_ns is None or now_ns > self._now_ns:
            self._now_ns = now_ns
        return self._emit_due()

    def flush(self) -> list[ContactWindow]:
        """Close every pending window (the stream stopped), zero-padded and ``truncated``."""
        out = self._emit_due()
        for pending in self._pending:
            out.append(
                self._make(pending.onset_ns, self.config.post_ns, provisional=False, truncated=True)
            )
            self._counts["windows"] += 1
            self._counts["truncated_windows"] += 1
        self._pending.clear()
        return out

    def _emit_due(self) -> list[ContactWindow]:
        out: list[ContactWindow] = []
        if self._now_ns is None:
            return out
        cfg = self.config
        still: list[_Pending] = []
        for pending in self._pending:
            for post in cfg.anytime_post_ns:
                if post not in pending.done and pending.onset_ns + post <= self._now_ns:
                    pending.done.add(post)
                    out.append(
                        self._make(pending.onset_ns, post, provisional=True, truncated=False)
                    )
                    self._counts["provisional_windows"] += 1
            if pending.onset_ns + cfg.post_ns <= self._now_ns:
                out.append(
                    self._make(pending.onset_ns, cfg.post_ns, provisional=False, truncated=False)
                )
                self._counts["windows"] += 1
            else:
                still.append(pending)
        self._pending = still
        self._prune()
        return out

    def _keep_from_ns(self) -> int | None:
        """Oldest time the buffer must still hold."""
        if self._now_ns is None:
            return None
        cfg = self.config
        lookback = (
            max(cfg.pre_ns, 0) + cfg.history_ns + cfg.activity_window_ns + cfg.pac_energy_window_ns
        )
        keep = self._now_ns - lookback
        for pending in self._pending:
            keep = min(keep, pending.onset_ns - cfg.pre_ns)
        return keep

    def _make(
        self, onset_ns: int, post_ns: int, *, provisional: bool, truncated: bool
    ) -> ContactWindow:
        cfg = self.config
        period = cfg.period_ns
        n = cfg.n_samples(post_ns)
        start = onset_ns - cfg.pre_ns
        channels, data = self._cut(start, n)
        # A window reaching before the first data fed is missing its head: the consumer joined
        # mid-stream (started, or its subscription matched, while the rod rang), so the onset
        # found may be the tail of a contact already under way (measured: +184 ms, 14 cm off).
        head_missing = self._first_ns is not None and start < self._first_ns
        self._counts["joined_mid_stream_windows"] += int(head_missing)
        reasons = []
        if head_missing:
            ahead = (self._first_ns - start) / MS
            reasons.append(
                f"joined mid-stream: the window begins {ahead:.0f} ms before the first input"
            )
        stuck = self._stuck_ids()
        if stuck:  # the model never saw a taxel at its ceiling: not a normal estimate
            self._counts["stuck_taxel_windows"] += 1
            reasons.append(
                f"stuck taxel(s) {', '.join(map(str, stuck))} in the window (masked from onset "
                "detection)"
            )
        return ContactWindow(
            task=cfg.task.label,
            sensor=cfg.sensor.label,
            onset_ns=int(onset_ns),
            pre_onset_ns=int(cfg.pre_ns),
            post_onset_ns=int(post_ns),
            sample_period_ns=int(period),
            channels=channels,
            data=data,
            provisional=provisional,
            truncated=truncated,
            degraded=bool(reasons),
            degraded_reason="; ".join(reasons),
        )

    def _stuck_ids(self) -> tuple[int, ...]:
        """Taxels masked as stuck now (none for sensors without taxels)."""
        return ()

    def _cut(self, start_ns: int, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _prune(self) -> None:
        raise NotImplementedError


class EventWindower(WindowerBase):
    """Contact windows from a NUSkin event stream (onset rule: :class:`~.window.WindowConfig`).

    The onset is the first event of the first qualifying burst. Stuck taxels
    (:class:`.stuck_taxels.StuckTaxels`) are left out of it until they quiet, and windows cut while
    one is stuck are degraded.
    """

    def __init__(self, config: WindowConfig | None = None) -> None:
        config = config or WindowConfig.for_task(Task.TAP_LOCALIZATION, Sensor.NUSKIN)
        if config.sensor is not Sensor.NUSKIN:
            raise PerceptionError(
                "The 'config.sensor' parameter must be nuskin for EventWindower. Got "
                f"{config.sensor.label!r} instead."
            )
        super().__init__(config)
        self._chunks: list[EventBlock] = []
        self._recent = np.empty(0, dtype=np.int64)
        self._recent_taxel = np.empty(0, dtype=np.uint16)
        self.stuck = StuckTaxels(config.n_taxels, config.stuck_rate_hz, config.stuck_after_ns)
        """Per-taxel rates; the taxels stuck at their ceiling, masked from onset detection."""
        self.stuck_changed = False
        """Whether the stuck taxels changed in the last :meth:`feed` (the node reports it)."""

    def feed(self, events: EventBlock, now_ns: int | None = None) -> list[ContactWindow]:
        """Add a block of events (arrival order, one clock) and return the windows that became due.

        Taxel ids outside 1..n_taxels are counted in ``bad_taxel_events`` and dropped; ``now_ns`` is
        the stream time after the block (default: the newest event). PerceptionError: the block's
        arrays differ in length or its times are not integers.
        """
        n = events.t_ns.shape
        if any(np.shape(a) != n for a in events) or len(n) != 1:
            raise PerceptionError(
                "The events' arrays must be 1-D of one length. Got shapes "
                f"{[np.shape(a) for a in events]} instead."
            )
        if events.t_ns.dtype.kind not in "iu":
            raise PerceptionError(
                "The events' 't_ns' must be integer nanoseconds. Got dtype "
                f"{events.t_ns.dtype} instead."
            )
        tax = events.taxel
        ok = (tax >= 1) & (tax <= self.config.n_taxels)
        if not ok.all():
            self._counts["bad_taxel_events"] += int((~ok).sum())
            events = events.select(ok)
        out: list[ContactWindow] = []
        self.stuck_changed = False
        if events.size:
            events = events.sorted_by_time()
            t = events.t_ns
            self._joined(int(t[0]))
            if self._now_ns is not None and t[0] < self._now_ns - self.config.history_ns:
                late = t < self._now_ns - self.config.history_ns
                self._counts["late_events"] += int(late.sum())
            self._chunks.append(events)
            self.stuck_changed = self.stuck.feed(t, events.taxel)
            if not self.config.external_onsets:
                keep = self.stuck.unmasked(events.taxel)
                if keep is None:
                    self._detect(t, events.taxel)
                else:
                    self._detect(t[keep], events.taxel[keep])
            newest = int(t[-1])
            if self._now_ns is None or newest > self._now_ns:
                self._now_ns = newest
        if now_ns is not None:
            self.stuck_changed |= self.stuck.advance(int(now_ns))
            self._joined(int(now_ns))
            out.extend(self.advance(now_ns))
        else:
            out.extend(self._emit_due())
        return out

    def _detect(self, t: np.ndarray, taxel: np.ndarray) -> None:
        """Find onsets among new events ``t`` (sorted) of ``taxel``, after the recent ones."""
        if not t.size:
            return
        cfg = self.config
        k = cfg.activity_min_events
        both = np.concatenate([self._recent, t])
        tax = np.concatenate([self._recent_taxel, taxel])
        first_new = len(self._recent)
        new_t = both[first_new:]
        lo = np.searchsorted(both, new_t - cfg.activity_window_ns, side="right")
        ends = np.arange(first_new, len(both))
        hits = np.flatnonzero(ends - lo + 1 >= k)
        m = min(cfg.activity_min_taxels, k)
        if len(hits) and m > 1:  # more than one taxel: decided for all bursts at once
            idx = np.arange(len(tax))
            change = np.maximum.accumulate(
                np.where(np.concatenate(([False], tax[1:] != tax[:-1])), idx, 0)
            )
            wide = change[ends[hits]] > lo[hits]
            self._counts["one_taxel_bursts"] += int(len(hits) - np.count_nonzero(wide))
            hits = hits[wide]
        starts = both[lo[hits]]  # onset candidates: first event of each qualifying burst
        while len(hits):
            if self._next_allowed_ns is not None:
                later = starts >= self._next_allowed_ns
                hits, starts = hits[later], starts[later]
                if not len(hits):
                    break
            h = hits[0]
            if m <= 2 or np.unique(tax[lo[h] : ends[h] + 1]).size >= m:
                self._add_onset(int(starts[0]))
            hits, starts = hits[1:], starts[1:]
        cut = np.searchsorted(both, both[-1] - cfg.activity_window_ns, side="right")
        self._recent, self._recent_taxel = both[cut:], tax[cut:]

    def _stuck_ids(self) -> tuple[int, ...]:
        return self.stuck.ids

    def stuck_status(self) -> tuple[Level, str, dict[str, object]]:
        """The window node's ``taxels`` check: WARN naming the stuck taxels while any is."""
        guard = self.stuck
        ids = guard.ids
        rate = max((guard.last_rate_hz[i] for i in ids), default=0.0)
        stuck_s = max((guard.stuck_for_ns(i) for i in ids), default=0) / 1e9
        values: dict[str, object] = {
            "stuck_taxel_ids": ",".join(map(str, ids)),
            "stuck_taxel_rate_events_per_s": f"{rate:.0f}",
            "stuck_for_s": f"{stuck_s:.1f}",
            "stuck_threshold_events_per_s": f"{guard.rate_hz:g}",
            "stuck_after_ms": f"{guard.after_ns / MS:g}",
            "masked_events": guard.masked_events,
            "one_taxel_bursts_refused": self._counts["one_taxel_bursts"],
            "windows_with_stuck_taxels": self._counts["stuck_taxel_windows"],
        }
        if not ids:
            return Level.OK, "ok", values
        return (
            Level.WARN,
            f"stuck taxel(s) {', '.join(map(str, ids))}: {rate:.0f} events/s for {stuck_s:.1f} s; "
            "masked from onset detection until they quiet",
            values,
        )

    def _cut(self, start_ns: int, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.config
        end_ns = start_ns + n_samples * cfg.period_ns
        self._compact()
        parts = [c for c in self._chunks if c.t_ns[-1] >= start_ns and c.t_ns[0] < end_ns]
        data = bin_events(
            EventBlock.concat(parts), start_ns, n_samples, cfg.period_ns, cfg.n_taxels
        )
        return np.arange(1, cfg.n_taxels + 1, dtype=np.uint16), data

    def _compact(self) -> None:
        """Join the buffered chunks into one block, without the events no window can need.

        The buffer holds a chunk per packet (about 150 for a tap window); joined once here, the next
        cut joins only the chunks that came since.
        """
        if len(self._chunks) < 2:
            return
        joined = EventBlock.concat(self._chunks)
        keep = self._keep_from_ns()
        if keep is not None and joined.size and int(joined.t_ns.min()) < keep:
            joined = joined.select(joined.t_ns >= keep)
        self._chunks = [joined] if joined.size else []

    def _prune(self) -> None:
        keep = self._keep_from_ns()
        if keep is None:
            return
        while self._chunks and self._chunks[0].t_ns[-1] < keep:
            self._chunks.pop(0)
