"""Sensor noise on the taxel pressures and spurious events on the NUSkin event stream.

Models. ``sensor_noise``: white Gaussian pressure noise of standard deviation ``white_pa`` at
the simulation rate, independent per taxel (thermal and readout noise of the piezoresistive
layer, plus the ambient vibration the gripper picks up), added before the sensor's front end.
``spurious_events``: a Poisson process of rate ``rate_hz`` per taxel of events with random
polarity (line glitches the receiver still decodes as valid words); their value field is the
value of the taxel's last real event, or ``value_counts`` when it had none.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ext_sense_runtime.records import EventBlock
from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.trial_events import last_values, merge


class SensorNoise(Effect):
    """White pressure noise per taxel (see module docstring)."""

    name = "sensor_noise"
    needs = ("taxel_pressure",)
    gives = ("taxel_pressure",)
    defaults: ClassVar[dict[str, Any]] = {"white_pa": 150.0}

    def run(self, signals: Signals, time: TimeBase, rng: np.random.Generator) -> None:
        """Add noise to ``taxel_pressure`` in place."""
        pressure = signals.need("taxel_pressure", self.name)
        sigma = self.scalar("white_pa", 0.0)
        if sigma > 0:
            pressure += rng.standard_normal(pressure.shape, dtype=np.float32) * np.float32(sigma)


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
