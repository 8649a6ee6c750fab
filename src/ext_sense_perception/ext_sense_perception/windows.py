"""Online, causal contact windows for both sensors (no ROS).

A windower is fed the sensor stream in arrival order and returns every contact window that
became complete (or, for anytime estimates, every provisional window whose shortened
post-contact time has passed). Contact onset is detected causally from the signal itself
(NUSkin: event activity; BioTac: PAC energy) or given from outside with :meth:`mark_onset`
(food: the start of the arm's motion). A history of the stream is kept so the signal before the
onset is in the window.

The returned :class:`ContactWindow` carries the fields of ``ext_sense_msgs/ContactWindow``:
NUSkin windows hold signed event counts per taxel and bin (+1 per positive, -1 per negative
spike, +1 for polarity 0) at a fine bin (0.25 ms by default), from which every feature set in
:mod:`ext_sense_perception.features` can be computed; BioTac windows hold the raw PAC samples.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
from scipy.signal import lfilter

from ext_sense_perception.errors import PerceptionError
from ext_sense_runtime.enums import Sensor, Task

MS = 1_000_000
NUSKIN_TAXELS = 80
PAC_RATE_HZ = 2200.0
PAC_PERIOD_NS = 454_545


class ContactWindow(NamedTuple):
    """A segment of sensor signal around one contact.

    ``data`` has shape ``(n_channels, n_samples)``; sample ``k`` covers
    ``[onset_ns - pre_onset_ns + k * sample_period_ns, ... + sample_period_ns)``. A negative
    ``pre_onset_ns`` means the window starts after the onset (food: 2 s after motion start).
    """

    task: str
    sensor: str
    onset_ns: int
    pre_onset_ns: int
    post_onset_ns: int
    sample_period_ns: int
    channels: np.ndarray
    data: np.ndarray
    provisional: bool = False
    truncated: bool = False

    @property
    def post_ns(self) -> int:
        """Post-contact signal the window holds (the decision latency floor), ns."""
        return self.post_onset_ns

    @property
    def start_ns(self) -> int:
        """Time of the first sample, ns."""
        return self.onset_ns - self.pre_onset_ns


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


@dataclass(frozen=True)
class WindowConfig:
    """How windows are cut, for one task and sensor.

    Attributes:
        task: The task the windows are for.
        sensor: The sensor the windows are cut from.
        pre_ns: Signal kept before the onset, ns (negative: the window starts after it).
        post_ns: Signal after the onset, ns; the window is complete at ``onset + post_ns``.
        bin_ns: NUSkin bin width, ns (BioTac windows use the PAC sample period instead).
        provisional_post_ns: Shorter post-onset times at which provisional windows are also
            emitted for anytime estimates, ns; each must be below ``post_ns``.
        debounce_ns: Minimum time from one onset to the next, ns.
        onset_source: ``"signal"`` (detected from the stream) or ``"external"``
            (:meth:`mark_onset` only, e.g. the arm's motion start for food).
        activity_window_ns: NUSkin onset: the sliding window events are counted in, ns.
        activity_min_events: NUSkin onset: events within ``activity_window_ns`` that mean contact.
        pac_energy_window_ns: BioTac onset: the sliding window of the PAC energy, ns.
        pac_threshold_sigma: BioTac onset: threshold as a multiple of the PAC noise RMS.
        pac_min_rms: BioTac onset: threshold floor of the PAC RMS deviation, ADC counts.
        pac_baseline_tau_ns: BioTac: time constant of the PAC baseline (DC) tracker, ns.
        n_taxels: NUSkin taxels (ids 1..n_taxels become channels).
        history_ns: Extra stream history kept for late external onsets, ns.
    """

    task: Task = Task.TAP_LOCALIZATION
    sensor: Sensor = Sensor.NUSKIN
    pre_ns: int = 50 * MS
    post_ns: int = 250 * MS
    bin_ns: int = 250_000
    provisional_post_ns: tuple[int, ...] = (25 * MS, 50 * MS, 100 * MS, 150 * MS)
    debounce_ns: int = 500 * MS
    onset_source: str = "signal"
    activity_window_ns: int = 2 * MS
    activity_min_events: int = 8
    pac_energy_window_ns: int = 5 * MS
    pac_threshold_sigma: float = 6.0
    pac_min_rms: float = 8.0
    pac_baseline_tau_ns: int = 50 * MS
    n_taxels: int = NUSKIN_TAXELS
    history_ns: int = 100 * MS

    def __post_init__(self) -> None:
        object.__setattr__(self, "task", Task.parse(self.task, PerceptionError))
        object.__setattr__(self, "sensor", Sensor.parse(self.sensor, PerceptionError))
        object.__setattr__(
            self, "provisional_post_ns", tuple(sorted(int(p) for p in self.provisional_post_ns))
        )
        _check(
            self.post_ns > 0 and self.post_ns <= 60_000 * MS,
            "post_ns",
            "in (0, 60 s]",
            self.post_ns,
        )
        _check(-self.pre_ns < self.post_ns, "pre_ns", f"> -post_ns ({-self.post_ns})", self.pre_ns)
        _check(self.pre_ns <= 10_000 * MS, "pre_ns", "<= 10 s", self.pre_ns)
        _check(0 < self.bin_ns <= 1000 * MS, "bin_ns", "in (0, 1 s]", self.bin_ns)
        for p in self.provisional_post_ns:
            _check(
                -self.pre_ns < p < self.post_ns,
                "provisional_post_ns",
                f"each in (-pre_ns, {self.post_ns})",
                p,
            )
        _check(self.debounce_ns >= 0, "debounce_ns", ">= 0", self.debounce_ns)
        _check(
            self.onset_source in ("signal", "external"),
            "onset_source",
            "'signal' or 'external'",
            self.onset_source,
        )
        _check(self.activity_window_ns > 0, "activity_window_ns", "> 0", self.activity_window_ns)
        _check(
            self.activity_min_events >= 1, "activity_min_events", ">= 1", self.activity_min_events
        )
        _check(
            self.pac_energy_window_ns > 0, "pac_energy_window_ns", "> 0", self.pac_energy_window_ns
        )
        _check(self.pac_threshold_sigma > 0, "pac_threshold_sigma", "> 0", self.pac_threshold_sigma)
        _check(self.pac_min_rms >= 0, "pac_min_rms", ">= 0", self.pac_min_rms)
        _check(self.pac_baseline_tau_ns > 0, "pac_baseline_tau_ns", "> 0", self.pac_baseline_tau_ns)
        _check(1 <= self.n_taxels <= 65535, "n_taxels", "in [1, 65535]", self.n_taxels)
        _check(self.history_ns >= 0, "history_ns", ">= 0", self.history_ns)

    @classmethod
    def for_task(cls, task: str | Task, sensor: str | Sensor, **overrides: object) -> WindowConfig:
        """The paper's window for a task: 50 ms / 250 ms around contact; food 2 s to 8 s.

        Args:
            task: Task name or enum.
            sensor: Sensor name or enum.
            **overrides: Any field of :class:`WindowConfig`.

        Returns:
            The configuration.
        """
        task, sensor = Task.parse(task, PerceptionError), Sensor.parse(sensor, PerceptionError)
        base = cls(task=task, sensor=sensor)
        if task is Task.FOOD_IDENTIFICATION:
            base = replace(
                base,
                pre_ns=-2000 * MS,
                post_ns=8000 * MS,
                bin_ns=10 * MS,
                provisional_post_ns=(3000 * MS, 4000 * MS, 6000 * MS),
                debounce_ns=8000 * MS,
                onset_source="external",
            )
        return replace(base, **overrides) if overrides else base

    @property
    def period_ns(self) -> int:
        """Sample period of the window data, ns."""
        return self.bin_ns if self.sensor is Sensor.NUSKIN else PAC_PERIOD_NS


def _check(ok: bool, name: str, expected: str, got: object) -> None:
    if not ok:
        raise PerceptionError(f"The {name!r} parameter must be {expected}. Got {got!r} instead.")


def bin_events(
    t_ns: np.ndarray,
    taxel: np.ndarray,
    polarity: np.ndarray,
    start_ns: int,
    n_bins: int,
    bin_ns: int,
    n_taxels: int = NUSKIN_TAXELS,
) -> np.ndarray:
    """Signed event counts per taxel and bin.

    Args:
        t_ns: Event times (n_events,) int64 ns.
        taxel: Taxel ids 1..n_taxels (n_events,); others are ignored.
        polarity: +1 / -1 / 0 per event (0 counts +1).
        start_ns: Start of bin 0, ns.
        n_bins: Number of bins.
        bin_ns: Bin width, ns.
        n_taxels: Rows of the result.

    Returns:
        Counts, shape ``(n_taxels, n_bins)`` float32.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    rel = t - np.int64(start_ns)
    idx = np.floor_divide(rel, np.int64(bin_ns))
    tax = np.asarray(taxel, dtype=np.int64) - 1
    keep = (rel >= 0) & (idx < n_bins) & (tax >= 0) & (tax < n_taxels)
    pol = np.asarray(polarity, dtype=np.int8)[keep]
    weights = np.where(pol < 0, -1.0, 1.0)
    flat = tax[keep] * n_bins + idx[keep]
    counts = np.bincount(flat, weights=weights, minlength=n_taxels * n_bins)
    return counts.reshape(n_taxels, n_bins).astype(np.float32)


class _Pending:
    """A detected onset whose window is not yet complete."""

    __slots__ = ("done", "onset_ns")

    def __init__(self, onset_ns: int) -> None:
        self.onset_ns = onset_ns
        self.done: set[int] = set()


class _WindowerBase:
    """Onset bookkeeping and window scheduling shared by both sensors."""

    def __init__(self, config: WindowConfig) -> None:
        self.config = config
        self._pending: list[_Pending] = []
        self._next_allowed_ns: int | None = None
        self._now_ns: int | None = None
        self._counts = dict.fromkeys(WindowerCounters._fields, 0)

    @property
    def counters(self) -> WindowerCounters:
        """Counters since construction."""
        return WindowerCounters(**self._counts)

    @property
    def now_ns(self) -> int | None:
        """Stream time: the end of the newest data seen, ns (None before any data)."""
        return self._now_ns

    @property
    def pending_onsets(self) -> tuple[int, ...]:
        """Onsets whose final window is not yet emitted, ns."""
        return tuple(p.onset_ns for p in self._pending)

    def mark_onset(self, onset_ns: int) -> bool:
        """Start a window at an onset known from outside (e.g. the arm's motion start).

        Args:
            onset_ns: Onset time, ns (same clock as the stream).

        Returns:
            False when the onset was debounced (too close after the previous one).
        """
        return self._add_onset(int(onset_ns))

    def _add_onset(self, onset_ns: int) -> bool:
        if self._next_allowed_ns is not None and onset_ns < self._next_allowed_ns:
            return False
        self._pending.append(_Pending(onset_ns))
        self._next_allowed_ns = onset_ns + self.config.debounce_ns
        self._counts["onsets"] += 1
        return True

    def advance(self, now_ns: int) -> list[ContactWindow]:
        """Declare that the stream is complete up to ``now_ns`` and emit what became due.

        Args:
            now_ns: Stream time, ns; earlier than the current stream time is ignored.

        Returns:
            The windows that became due, oldest first.
        """
        now_ns = int(now_ns)
        if self._now_ns is None or now_ns > self._now_ns:
            self._now_ns = now_ns
        return self._emit_due()

    def flush(self) -> list[ContactWindow]:
        """Close every pending window now (the stream stopped); their tails are zero-padded.

        Returns:
            The final windows of all pending onsets, marked ``truncated`` when incomplete.
        """
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
            for post in cfg.provisional_post_ns:
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
        n = max(int((cfg.pre_ns + post_ns) // period), 0)
        channels, data = self._cut(onset_ns - cfg.pre_ns, n)
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
        )

    def _cut(self, start_ns: int, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _prune(self) -> None:
        raise NotImplementedError


class EventWindower(_WindowerBase):
    """Contact windows from a NUSkin event stream.

    Onset: the first time ``activity_min_events`` events (any taxel) fall within
    ``activity_window_ns``; the onset is the first event of that burst. Events are kept in a
    buffer of chunks covering the pre-onset signal and every pending window.

    Args:
        config: Window configuration (``sensor`` must be NUSkin).
    """

    def __init__(self, config: WindowConfig | None = None) -> None:
        config = config or WindowConfig.for_task(Task.TAP_LOCALIZATION, Sensor.NUSKIN)
        if config.sensor is not Sensor.NUSKIN:
            raise PerceptionError(
                "The 'config.sensor' parameter must be nuskin for EventWindower. Got "
                f"{config.sensor.label!r} instead."
            )
        super().__init__(config)
        self._chunks: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._recent = np.empty(0, dtype=np.int64)

    def feed(
        self,
        t_ns: np.ndarray,
        taxel: np.ndarray,
        polarity: np.ndarray,
        now_ns: int | None = None,
    ) -> list[ContactWindow]:
        """Add a batch of events and return the windows that became due.

        Args:
            t_ns: Event times (n,) int64 ns (epoch or monotonic, one clock throughout).
            taxel: Taxel ids (n,) 1..n_taxels; others are counted in ``bad_taxel_events``
                and dropped.
            polarity: (n,) int8, +1 / -1 / 0.
            now_ns: Stream time after this batch, ns (e.g. the batch's end); default: the
                newest event.

        Returns:
            Completed and provisional windows, oldest first.

        Raises:
            PerceptionError: when the arrays differ in length or are not one-dimensional.
        """
        t = np.asarray(t_ns)
        tax = np.asarray(taxel)
        pol = np.asarray(polarity)
        if not (t.ndim == tax.ndim == pol.ndim == 1) or not (len(t) == len(tax) == len(pol)):
            raise PerceptionError(
                f"The 't_ns', 'taxel' and 'polarity' parameters must be 1-D of one length. "
                f"Got shapes {t.shape}, {tax.shape}, {pol.shape} instead."
            )
        if t.dtype.kind not in "iu":
            raise PerceptionError(
                f"The 't_ns' parameter must be integer nanoseconds. Got dtype {t.dtype} instead."
            )
        t = t.astype(np.int64, copy=False)
        tax = tax.astype(np.int64, copy=False)
        ok = (tax >= 1) & (tax <= self.config.n_taxels)
        if not ok.all():
            self._counts["bad_taxel_events"] += int((~ok).sum())
            t, tax, pol = t[ok], tax[ok], pol[ok]
        out: list[ContactWindow] = []
        if len(t):
            if np.any(np.diff(t) < 0):
                order = np.argsort(t, kind="stable")
                t, tax, pol = t[order], tax[order], pol[order]
            if self._now_ns is not None and t[0] < self._now_ns - self.config.history_ns:
                late = t < self._now_ns - self.config.history_ns
                self._counts["late_events"] += int(late.sum())
            self._chunks.append((t, tax.astype(np.uint16), pol.astype(np.int8)))
            if self.config.onset_source == "signal":
                self._detect(t)
            newest = int(t[-1])
            if self._now_ns is None or newest > self._now_ns:
                self._now_ns = newest
        if now_ns is not None:
            out.extend(self.advance(now_ns))
        else:
            out.extend(self._emit_due())
        return out

    def _detect(self, t: np.ndarray) -> None:
        cfg = self.config
        k = cfg.activity_min_events
        both = np.concatenate([self._recent, t])
        first_new = len(self._recent)
        new_t = both[first_new:]
        lo = np.searchsorted(both, new_t - cfg.activity_window_ns, side="right")
        counts = np.arange(first_new, len(both)) - lo + 1
        hits = np.flatnonzero(counts >= k)
        starts = both[lo[hits]]  # onset candidates: first event of each qualifying burst
        while len(starts):
            if self._next_allowed_ns is not None:
                starts = starts[starts >= self._next_allowed_ns]
                if not len(starts):
                    break
            self._add_onset(int(starts[0]))
            starts = starts[1:]
        cut = np.searchsorted(both, both[-1] - cfg.activity_window_ns, side="right")
        self._recent = both[cut:]

    def _cut(self, start_ns: int, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.config
        end_ns = start_ns + n_samples * cfg.bin_ns
        parts = [c for c in self._chunks if len(c[0]) and c[0][-1] >= start_ns and c[0][0] < end_ns]
        if parts:
            t = np.concatenate([c[0] for c in parts])
            tax = np.concatenate([c[1] for c in parts])
            pol = np.concatenate([c[2] for c in parts])
        else:
            t = np.empty(0, np.int64)
            tax = np.empty(0, np.uint16)
            pol = np.empty(0, np.int8)
        data = bin_events(t, tax, pol, start_ns, n_samples, cfg.bin_ns, cfg.n_taxels)
        return np.arange(1, cfg.n_taxels + 1, dtype=np.uint16), data

    def _prune(self) -> None:
        keep = self._keep_from_ns()
        if keep is None:
            return
        while self._chunks and (len(self._chunks[0][0]) == 0 or self._chunks[0][0][-1] < keep):
            self._chunks.pop(0)


class PacWindower(_WindowerBase):
    """Contact windows from BioTac PAC samples (one or more sensors, 2200 Hz).

    Onset: the RMS deviation of PAC from its slowly tracked baseline, over
    ``pac_energy_window_ns`` and averaged over sensors, exceeds
    ``max(pac_min_rms, pac_threshold_sigma * noise_rms)``; ``noise_rms`` is tracked while no
    window is pending. Gaps in the frame times are filled by holding the last value
    (``gap_samples``); samples flagged invalid are held too (``invalid_samples``).

    Args:
        config: Window configuration (``sensor`` must be BioTac).
        n_sensors: PAC channels (BioTac sensors) per sample.
    """

    def __init__(self, config: WindowConfig | None = None, n_sensors: int = 1) -> None:
        config = config or WindowConfig.for_task(Task.TAP_LOCALIZATION, Sensor.BIOTAC)
        if config.sensor is not Sensor.BIOTAC:
            raise PerceptionError(
                "The 'config.sensor' parameter must be biotac for PacWindower. Got "
                f"{config.sensor.label!r} instead."
            )
        if n_sensors < 1:
            raise PerceptionError(
                f"The 'n_sensors' parameter must be >= 1. Got {n_sensors!r} instead."
            )
        super().__init__(config)
        self.n_sensors = n_sensors
        self._period = PAC_PERIOD_NS
        self._t_first: int | None = None
        self._n_total = 0  # samples appended since t_first
        self._chunks: list[tuple[int, np.ndarray]] = []  # (first sample index, (n_sensors, n))
        self._baseline: np.ndarray | None = None
        self._last = np.zeros(n_sensors)
        self._tail_sq = np.empty(0)
        self._noise_sq: float | None = None
        alpha = 1.0 - np.exp(-PAC_PERIOD_NS / config.pac_baseline_tau_ns)
        self._alpha = float(alpha)
        self._m = max(1, round(config.pac_energy_window_ns / PAC_PERIOD_NS))

    def feed(
        self,
        t0_ns: int,
        pac: np.ndarray,
        period_ns: int = PAC_PERIOD_NS,
        valid: np.ndarray | None = None,
    ) -> list[ContactWindow]:
        """Add PAC samples (e.g. one frame's 22) and return the windows that became due.

        Args:
            t0_ns: Time of the first sample, ns.
            pac: Samples, shape ``(n,)`` or ``(n_sensors, n)``, raw ADC counts.
            period_ns: Sample period, ns (fixed for the stream's life).
            valid: Optional boolean mask like ``pac``; invalid samples hold the previous value.

        Returns:
            Completed and provisional windows, oldest first.

        Raises:
            PerceptionError: on a wrong shape, NaN/inf, or a changed sample period.
        """
        x = np.asarray(pac, dtype=np.float64)
        if x.ndim == 1:
            x = x[None, :]
        if x.ndim != 2 or x.shape[0] != self.n_sensors:
            raise PerceptionError(
                f"The 'pac' parameter must have shape (n,) or ({self.n_sensors}, n). Got "
                f"{np.shape(pac)} instead."
            )
        if not np.isfinite(x).all():
            raise PerceptionError("The 'pac' parameter must be finite. Got NaN or inf instead.")
        period_ns = int(period_ns)
        if self._t_first is None:
            if period_ns <= 0:
                raise PerceptionError(
                    f"The 'period_ns' parameter must be > 0. Got {period_ns} instead."
                )
            self._period = period_ns
            self._t_first = int(t0_ns)
            self._m = max(1, round(self.config.pac_energy_window_ns / period_ns))
            self._alpha = float(1.0 - np.exp(-period_ns / self.config.pac_baseline_tau_ns))
            self._baseline = x[:, :1].mean(axis=1) if x.shape[1] else None
        elif period_ns != self._period:
            raise PerceptionError(
                f"The 'period_ns' parameter must stay {self._period}. Got {period_ns} instead."
            )
        if valid is not None:
            mask = np.broadcast_to(np.asarray(valid, dtype=bool).reshape(x.shape[0], -1), x.shape)
            if not mask.all():
                x = x.copy()
                for s in range(x.shape[0]):
                    bad = np.flatnonzero(~mask[s])
                    for i in bad:
                        x[s, i] = x[s, i - 1] if i > 0 else self._last[s]
                self._counts["invalid_samples"] += int((~mask).sum())
        # place the samples on the stream's sample grid; fill gaps by holding
        index = round((int(t0_ns) - self._t_first) / self._period)
        if index < self._n_total:
            skip = self._n_total - index
            x = x[:, skip:]
            self._counts["late_events"] += min(skip, x.shape[1] + skip)
            index = self._n_total
        if index > self._n_total:
            gap = index - self._n_total
            self._counts["gap_samples"] += gap
            filler = np.repeat(self._last[:, None], gap, axis=1)
            self._append(filler, detect=False)
        out: list[ContactWindow] = []
        if x.shape[1]:
            self._append(x, detect=self.config.onset_source == "signal")
        self._now_ns = self._t_first + self._n_total * self._period
        out.extend(self._emit_due())
        return out

    def _append(self, x: np.ndarray, *, detect: bool) -> None:
        if self._baseline is None:
            self._baseline = x[:, 0].copy()
        a = self._alpha
        base = np.empty_like(x)
        for s in range(x.shape[0]):
            zi = np.array([(1 - a) * self._baseline[s]])
            base[s], _ = lfilter([a], [1.0, -(1.0 - a)], x[s], zi=zi)
        prev = np.concatenate([self._baseline[:, None], base[:, :-1]], axis=1)
        dev_sq = ((x - prev) ** 2).mean(axis=0)
        self._baseline = base[:, -1].copy()
        self._last = x[:, -1].copy()
        first_index = self._n_total
        self._chunks.append((first_index, x.astype(np.float32)))
        self._n_total += x.shape[1]
        if detect:
            self._detect(dev_sq, first_index)
        self._tail_sq = (
            np.concatenate([self._tail_sq, dev_sq])[-(self._m - 1) :]
            if self._m > 1
            else np.empty(0)
        )

    def _detect(self, dev_sq: np.ndarray, first_index: int) -> None:
        cfg = self.config
        m = self._m
        both = np.concatenate([self._tail_sq, dev_sq])
        csum = np.concatenate([[0.0], np.cumsum(both)])
        n_new = len(dev_sq)
        ends = np.arange(len(both) - n_new, len(both)) + 1
        starts = np.maximum(ends - m, 0)
        energy = (csum[ends] - csum[starts]) / np.maximum(ends - starts, 1)
        noise_sq = self._noise_sq if self._noise_sq is not None else float(np.median(energy))
        thr = max(cfg.pac_min_rms, cfg.pac_threshold_sigma * np.sqrt(noise_sq))
        hits = np.flatnonzero(energy > thr * thr)
        offset = len(both) - n_new
        for h in hits:
            # onset: first sample of the energy window whose deviation exceeds the threshold
            lo = max(starts[h], 0)
            seg = both[lo : ends[h]]
            above = np.flatnonzero(seg > thr * thr)
            k = lo + (above[0] if len(above) else 0) - offset
            onset = self._t_first + (first_index + int(k)) * self._period
            if self._next_allowed_ns is None or onset >= self._next_allowed_ns:
                self._add_onset(int(onset))
        if not self._pending and not len(hits):
            level = float(np.median(energy))
            self._noise_sq = level if self._noise_sq is None else 0.9 * self._noise_sq + 0.1 * level

    def _cut(self, start_ns: int, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
        data = np.zeros((self.n_sensors, n_samples), dtype=np.float32)
        channels = np.arange(self.n_sensors, dtype=np.uint16)
        if self._t_first is None or n_samples == 0:
            return channels, data
        first = -(-(start_ns - self._t_first) // self._period)  # ceil: first sample at/after start
        last = first + n_samples
        for c0, chunk in self._chunks:
            c1 = c0 + chunk.shape[1]
            lo, hi = max(first, c0), min(last, c1)
            if lo < hi:
                data[:, lo - first : hi - first] = chunk[:, lo - c0 : hi - c0]
        return channels, data

    def _prune(self) -> None:
        keep = self._keep_from_ns()
        if keep is None or self._t_first is None:
            return
        keep_index = (keep - self._t_first) // self._period
        while self._chunks and self._chunks[0][0] + self._chunks[0][1].shape[1] < keep_index:
            self._chunks.pop(0)


def make_windower(config: WindowConfig, n_sensors: int = 1) -> EventWindower | PacWindower:
    """The windower for the config's sensor.

    Args:
        config: Window configuration.
        n_sensors: BioTac sensors (ignored for NUSkin).

    Returns:
        An :class:`EventWindower` or a :class:`PacWindower`.
    """
    if config.sensor is Sensor.NUSKIN:
        return EventWindower(config)
    return PacWindower(config, n_sensors=n_sensors)


def window_from_recording(
    config: WindowConfig,
    onset_ns: int,
    *,
    t_ns: np.ndarray | None = None,
    taxel: np.ndarray | None = None,
    polarity: np.ndarray | None = None,
    pac: np.ndarray | None = None,
    pac_t0_ns: int = 0,
    post_ns: int | None = None,
) -> ContactWindow:
    """Cut one window offline from a whole recording at a known onset.

    Same output as the online windowers (used to build training sets from datasets).

    Args:
        config: Window configuration.
        onset_ns: Onset, ns.
        t_ns: NUSkin event times, ns.
        taxel: NUSkin taxel ids.
        polarity: NUSkin polarities.
        pac: BioTac PAC ``(n_sensors, n_samples)`` from ``pac_t0_ns``.
        pac_t0_ns: Time of PAC sample 0, ns.
        post_ns: Post-onset time to cut (default ``config.post_ns``).

    Returns:
        The window.

    Raises:
        PerceptionError: when the sensor's arrays are missing.
    """
    post = config.post_ns if post_ns is None else int(post_ns)
    period = config.period_ns
    n = max(int((config.pre_ns + post) // period), 0)
    start = int(onset_ns) - config.pre_ns
    if config.sensor is Sensor.NUSKIN:
        if t_ns is None or taxel is None:
            raise PerceptionError(
                "The 't_ns' and 'taxel' parameters are needed for a NUSkin window. Got None "
                "instead."
            )
        pol = np.ones(len(t_ns), np.int8) if polarity is None else polarity
        data = bin_events(np.asarray(t_ns), taxel, pol, start, n, period, config.n_taxels)
        channels = np.arange(1, config.n_taxels + 1, dtype=np.uint16)
    else:
        if pac is None:
            raise PerceptionError(
                "The 'pac' parameter is needed for a BioTac window. Got None instead."
            )
        x = np.atleast_2d(np.asarray(pac, dtype=np.float32))
        first = -(-(start - int(pac_t0_ns)) // period)
        data = np.zeros((x.shape[0], n), np.float32)
        lo, hi = max(first, 0), min(first + n, x.shape[1])
        if lo < hi:
            data[:, lo - first : hi - first] = x[:, lo:hi]
        channels = np.arange(x.shape[0], dtype=np.uint16)
    return ContactWindow(
        task=config.task.label,
        sensor=config.sensor.label,
        onset_ns=int(onset_ns),
        pre_onset_ns=int(config.pre_ns),
        post_onset_ns=post,
        sample_period_ns=int(period),
        channels=channels,
        data=data,
        provisional=post < config.post_ns,
        truncated=False,
    )
