"""The BioTac windower: contact windows from PAC samples (no ROS)."""

from __future__ import annotations

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.window import ContactWindow, WindowConfig
from ext_sense_perception.online.windowers import WindowerBase
from ext_sense_perception.profiles import PAC_PERIOD_NS
from ext_sense_runtime.enums import Sensor, Task


class PacWindower(WindowerBase):
    """Contact windows from BioTac PAC samples (one or more sensors, 2200 Hz).

    Onset rule: :class:`~.window.WindowConfig`, the deviation averaged over sensors, the noise
    tracked while no window is pending. Gaps and invalid samples hold the last value (counted).
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
        # imported here: scipy.signal takes about 1 s, which NUSkin nodes need not pay
        from scipy.signal import lfilter

        self._lfilter = lfilter
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
        """Add PAC samples, ``(n,)`` or ``(n_sensors, n)`` raw counts; the windows that became due.

        ``period_ns`` is fixed for the stream's life; samples ``valid`` marks False hold the
        previous value. PerceptionError: a wrong shape, NaN/inf, or a changed sample period.
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
            self._joined(self._t_first)
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
            self._append(x, detect=not self.config.external_onsets)
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
            base[s], _ = self._lfilter([a], [1.0, -(1.0 - a)], x[s], zi=zi)
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
