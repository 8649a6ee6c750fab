"""NUSkin transduction: taxel pressure to positive and negative events.

Model. The piezoresistive layer and its amplifier pass pressure up to ``bandwidth_hz`` (a
second-order Butterworth low-pass); the taxel's 10-bit reading is ``offset_counts + p /
pa_per_count``. Each taxel is a send-on-delta encoder on it: an event when the reading has moved
``threshold_pa`` from its reference, which then jumps to the reading (``reference: reset``: one
event per change, whatever its size) or steps one threshold (``step``: ``n`` events for ``n``
thresholds); then the taxel is refractory for ``refractory_s`` (the ACES signature length). The
value field is the reading at the event (0..1023); event times fall uniformly inside their
sample, never closer than the refractory period. ``offset_spread`` spreads the resting readings
(log-normal, fixed per sensor); ``clip_reading`` clips the reading the encoder sees to 0..1023.
Why these choices and the calibrated values: docs/simulator.md.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from scipy.signal import butter, lfilter, lfilter_zi

from ext_sense_runtime.records import EventBlock
from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.errors import SceneError
from ext_sense_sim.trial_events import by_trial


def front_end(pressure: np.ndarray, bandwidth_hz: float, rate_hz: float) -> np.ndarray:
    """Second-order Butterworth low-pass of ``(..., n_samples)`` pressure, from steady state.

    The cut-off is clipped below Nyquist; the result has the input's shape and dtype.
    """
    wn = min(bandwidth_hz / (rate_hz / 2), 0.99)
    b, a = butter(2, wn)
    zi = lfilter_zi(b, a)
    # the steady state of the first millisecond, not of one noisy sample (whose offset would
    # ring out through the encoder as a burst of start-up events)
    x0 = pressure[..., : max(1, int(rate_hz / 1000))].mean(axis=-1, keepdims=True)
    out, _ = lfilter(b, a, pressure, axis=-1, zi=zi * x0)
    return out.astype(pressure.dtype, copy=False)


_BLOCK = 32


def level_crossing(
    signal: np.ndarray, threshold: float, refractory: int, reset: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Send-on-delta encoding with a refractory period, vectorised across channels.

    ``signal`` is time-major ``(n_samples, n_channels)``; ``refractory`` is in samples (>= 1);
    ``reset`` jumps the reference to the signal at each event, else it steps one threshold.
    Returns ``(sample, channel, polarity)`` of every event in time order.
    """
    n_samples, n_channels = signal.shape
    ref = signal[0].astype(np.float64)
    ready = np.zeros(n_channels, dtype=np.int64)
    thr = float(threshold)
    samples, channels, polarities = [], [], []
    # A channel whose block range stays within one threshold of its reference cannot fire in
    # that block (its reference only moves when it fires), so only candidates are stepped.
    for b in range(1, n_samples, _BLOCK):
        seg = signal[b : b + _BLOCK]
        cand = np.flatnonzero((seg.max(axis=0) - ref >= thr) | (ref - seg.min(axis=0) >= thr))
        if cand.size == 0:
            continue
        sub, r, rd = seg[:, cand], ref[cand], ready[cand]
        for k in range(seg.shape[0]):
            diff = sub[k] - r
            fire = np.flatnonzero((np.abs(diff) >= thr) & (rd <= b + k))
            if fire.size:
                sign = np.where(diff[fire] > 0, 1, -1)
                if reset:
                    r[fire] = sub[k, fire]
                else:
                    r[fire] += thr * sign
                rd[fire] = b + k + refractory
                samples.append(np.full(fire.size, b + k, dtype=np.int64))
                channels.append(cand[fire])
                polarities.append(sign.astype(np.int8))
        ref[cand], ready[cand] = r, rd
    if not samples:
        return np.zeros(0, np.int64), np.zeros(0, np.intp), np.zeros(0, np.int8)
    k, ch, pol = np.concatenate(samples), np.concatenate(channels), np.concatenate(polarities)
    order = np.argsort(k, kind="stable")
    return k[order], ch[order], pol[order]


def refractory_safe_jitter(
    k: np.ndarray, channel: np.ndarray, refractory: int, rng: np.random.Generator
) -> np.ndarray:
    """Uniform offsets in [0, 1) of events inside their sample that keep the refractory period.

    Within chains of one channel's events exactly ``refractory`` samples apart the offsets are
    made non-decreasing, so no two come closer than the refractory period.
    """
    u = rng.uniform(0.0, 1.0, size=k.size)
    if k.size < 2:
        return u
    order = np.lexsort((k, channel))
    ks, cs = k[order], channel[order]
    chained = np.r_[False, (cs[1:] == cs[:-1]) & (ks[1:] - ks[:-1] == refractory)]
    group = np.cumsum(~chained)  # a new group wherever the chain breaks
    v = u[order] + 2.0 * group
    fixed = np.maximum.accumulate(v) - 2.0 * group
    out = np.empty_like(u)
    out[order] = fixed
    return out


class NuskinTransduction(Effect):
    """Pressure to NUSkin events (see module docstring). Gives ``events``."""

    name = "nuskin_transduction"
    needs = ("taxel_pressure",)
    gives = ("events",)
    defaults: ClassVar[dict[str, Any]] = {
        "threshold_pa": 1000.0,
        "refractory_s": 0.00025,
        "bandwidth_hz": 1500.0,
        "offset_counts": 70.0,
        "pa_per_count": 1000.0,
        "reference": "reset",
        "clip_reading": False,
        "offset_spread": 0.0,
    }

    def setup(self) -> None:
        """Each taxel's resting reading (fixed per sensor by the scene's seed)."""
        offset = self.scalar("offset_counts", 0, 1023)
        spread = self.scalar("offset_spread", 0.0, 3.0)
        self.offsets = np.full(80, offset)
        if spread > 0:
            sensor_rng = np.random.default_rng([int(self.context.seed), 13])
            factor = np.exp(spread * sensor_rng.standard_normal(80))
            self.offsets = np.clip(offset * factor, 0, 1023)

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Give ``events`` (``(trial, EventBlock)``, batch-local trials, see ``trial_events``)."""
        pressure = signals.need("taxel_pressure", self.name)
        _n_trials, n_taxels, n_samples = pressure.shape
        per_count = self.scalar("pa_per_count", 1e-9)
        # each row of the (trials * taxels, samples) reading gets its taxel's offset
        offset = np.tile(np.resize(self.offsets, n_taxels), _n_trials)[:, None]
        filtered = front_end(pressure, self.scalar("bandwidth_hz", 1.0), time.rate_hz)
        if self.flag("clip_reading"):
            # the 10-bit reading bounds what the encoder sees (pressure-equivalent units)
            flat = filtered.reshape(-1, n_samples)
            np.clip(flat, -offset * per_count, (1023 - offset) * per_count, out=flat)
        time_major = np.ascontiguousarray(filtered.reshape(-1, n_samples).T)
        refractory = max(1, math.ceil(self.scalar("refractory_s", 0.0) * time.rate_hz - 1e-9))
        mode = self.params["reference"]
        if mode not in ("reset", "step"):
            raise SceneError(
                f"Effect '{self.name}': parameter 'reference' must be 'reset' or 'step'. "
                f"Got {mode!r} instead."
            )
        k, channel, polarity = level_crossing(
            time_major, self.scalar("threshold_pa", 1e-9), refractory, reset=mode == "reset"
        )
        value = offset[channel, 0] + time_major[k, channel] / per_count
        jitter = refractory_safe_jitter(k, channel, refractory, rng)
        t_ns = np.round((k + jitter) * (1e9 / time.rate_hz)).astype(np.int64)
        events = EventBlock(
            t_ns,
            (channel % n_taxels + 1).astype(np.uint16),
            polarity,
            np.clip(np.round(value), 0, 1023).astype(np.uint16),
        )
        signals["events"] = by_trial(channel // n_taxels, events)
