"""Sensor noise on the taxel pressures and spurious events on the NUSkin event stream.

``sensor_noise``: white Gaussian pressure noise (``white_pa``, scaled per taxel by a fixed
log-normal ``white_spread``) before the front end; ``chatty_taxels`` taxels fixed per sensor get
``chatty_pa * 0.9**i`` instead (readings on a count boundary); ``drift_pa``: noise low-passed at
``drift_hz`` that moves resting readings across count boundaries. ``spurious_events``: Poisson
events per taxel at ``rate_hz`` with random polarity (line glitches the receiver still decodes),
valued as the taxel's last real event or ``value_counts``.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from scipy.signal import lfilter

from ext_sense_runtime.records import EventBlock
from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.trial_events import last_values, merge


class SensorNoise(Effect):
    """White pressure noise per taxel (see module docstring)."""

    name = "sensor_noise"
    needs = ("taxel_pressure",)
    gives = ("taxel_pressure",)
    defaults: ClassVar[dict[str, Any]] = {
        "white_pa": 150.0,
        "white_spread": 0.0,
        "drift_pa": 0.0,
        "drift_hz": 2.0,
        "chatty_taxels": 0,
        "chatty_pa": 0.0,
    }

    def setup(self) -> None:
        """Each taxel's noise scale and the chatty taxels of this sensor (fixed per scene seed)."""
        spread = self.scalar("white_spread", 0.0, 3.0)
        self.scale = None
        if spread > 0:
            spread_rng = np.random.default_rng([int(self.context.seed), 12])
            self.scale = np.exp(spread * spread_rng.standard_normal(80)).astype(np.float32)
        count = int(self.scalar("chatty_taxels", 0, 80))
        self.chatty = np.zeros(0, dtype=np.intp)
        if count:
            sensor_rng = np.random.default_rng([int(self.context.seed), 11])
            self.chatty = np.sort(sensor_rng.choice(80, size=count, replace=False))

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Add noise to ``taxel_pressure`` in place."""
        pressure = signals.need("taxel_pressure", self.name)
        sigma = self.scalar("white_pa", 0.0)
        if sigma > 0:
            noise = rng.standard_normal(pressure.shape, dtype=np.float32) * np.float32(sigma)
            if self.scale is not None and pressure.shape[1] == 80:
                noise *= self.scale[None, :, None]
            pressure += noise
        drift = self.scalar("drift_pa", 0.0)
        if drift > 0:
            pole = math.exp(-2.0 * math.pi * self.scalar("drift_hz", 1e-3, 1e3) * time.dt)
            kick = rng.standard_normal(pressure.shape, dtype=np.float32)
            kick[..., 0] /= math.sqrt(1.0 - pole**2)  # start in the filter's steady state
            slow = lfilter([math.sqrt(1.0 - pole**2)], [1.0, -pole], kick, axis=-1)
            pressure += (slow * drift).astype(np.float32)
        chatty = self.scalar("chatty_pa", 0.0)
        if self.chatty.size and chatty > 0 and pressure.shape[1] == 80:
            level = chatty * 0.9 ** np.arange(self.chatty.size)
            extra = np.sqrt(np.maximum(level**2 - sigma**2, 0.0)).astype(np.float32)
            shape = (pressure.shape[0], self.chatty.size, pressure.shape[2])
            noise = rng.standard_normal(shape, dtype=np.float32)
            pressure[:, self.chatty] += noise * extra[None, :, None]


class SpuriousEvents(Effect):
    """Poisson spurious events per taxel (see module docstring)."""

    name = "spurious_events"
    needs = ("events",)
    gives = ("events",)
    defaults: ClassVar[dict[str, Any]] = {"rate_hz": 2.0, "value_counts": 100}

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Merge spurious events into ``events``."""
        trial_events = signals.need("events", self.name)
        rate = self.scalar("rate_hz", 0.0, 1e5)
        duration_ns = round(time.n_samples * time.dt * 1e9)
        n_taxels = 80
        counts = rng.poisson(rate * time.n_samples * time.dt, size=(time.n_trials, n_taxels))
        total = int(counts.sum())
        if total == 0:
            return
        trial = np.repeat(np.repeat(np.arange(time.n_trials), n_taxels), counts.ravel())
        taxel = np.repeat(np.tile(np.arange(1, n_taxels + 1), time.n_trials), counts.ravel())
        t_ns = rng.integers(0, duration_ns, size=total, dtype=np.int64)
        polarity = rng.choice(np.array([-1, 1], dtype=np.int8), size=total)
        value = np.full(total, int(self.scalar("value_counts", 0, 1023)), dtype=np.uint16)
        last = last_values(*trial_events, time.n_trials)
        known = last[trial, taxel - 1]
        value = np.where(known > 0, known, value).astype(np.uint16)
        extra = EventBlock(t_ns, taxel.astype(np.uint16), polarity, value)
        signals["events"] = merge(trial_events, (trial.astype(np.int32), extra))
