"""Running a scene: build the listed effects, check their chain, simulate trials in batches.

Only the listed effects are built and run, each counting its calls and time; a chain that misses
a signal fails before anything runs, naming the effect that would give it.
"""

from __future__ import annotations

import time as _time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ext_sense_runtime.enums import Sensor
from ext_sense_sim.effects import REGISTRY
from ext_sense_sim.effects.base import Effect, Signals, TimeBase
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import Scene

SENSOR_SIGNAL = {Sensor.NUSKIN: "events", Sensor.BIOTAC: "biotac"}
"""The signal each sensor's dataset is made of."""


@dataclass
class EffectStats:
    """Calls, wall time and CPU time (of the calling thread) of one effect over a run."""

    calls: int = 0
    seconds: float = 0.0
    cpu_seconds: float = 0.0


def provider_of(signal: str) -> list[str]:
    """Names of the effects able to give ``signal`` (for error messages)."""
    return [
        name for name, cls in REGISTRY.items() if signal in cls.gives and signal not in cls.needs
    ]


class Simulator:
    """The effects of one scene, built and checked (see module docstring)."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.effects: list[Effect] = []
        available: set[str] = set()
        for name, params in scene.effects:
            if name not in REGISTRY:
                raise SceneError(
                    f"Scene '{scene.name}': unknown effect {name!r}; known: {sorted(REGISTRY)}."
                )
            cls = REGISTRY[name]
            for signal in cls.needs:
                if signal not in available:
                    raise SceneError(
                        f"Scene '{scene.name}': effect '{name}' needs the signal '{signal}', "
                        f"given by effect {' or '.join(repr(p) for p in provider_of(signal))}, "
                        f"which the scene does not list before it."
                    )
            self.effects.append(cls(params, scene))
            available.update(cls.gives)
        for signal in (SENSOR_SIGNAL[scene.sensor], "labels"):
            if signal not in available:
                raise SceneError(
                    f"Scene '{scene.name}' ({scene.sensor.label}, {scene.task.label}) needs "
                    f"effect {' or '.join(repr(p) for p in provider_of(signal))} (gives "
                    f"'{signal}'), which its effects list lacks."
                )
        self.available = frozenset(available)
        self.stats: dict[str, EffectStats] = {e.name: EffectStats() for e in self.effects}

    def run_batch(
        self, first: int, n_trials: int, rng: np.random.Generator
    ) -> tuple[TimeBase, Signals]:
        """Simulate ``n_trials`` trials starting at run index ``first``."""
        tb = TimeBase(self.scene.rate_hz, self.scene.n_samples, n_trials, first)
        signals = Signals()
        for effect in self.effects:
            start, cpu = _time.perf_counter(), _time.thread_time()
            effect.run(signals, tb, rng)
            stat = self.stats[effect.name]
            stat.calls += 1
            stat.seconds += _time.perf_counter() - start
            stat.cpu_seconds += _time.thread_time() - cpu
        return tb, signals

    def batches(self, trials: int, seed: int) -> Iterator[tuple[TimeBase, Signals]]:
        """All trials of a run in batches; batch b draws from child b of ``SeedSequence(seed)``."""
        if trials < 1:
            raise SceneError(f"The 'trials' argument must be >= 1. Got {trials} instead.")
        size = self.scene.batch_size
        n_batches = -(-trials // size)
        children = np.random.SeedSequence(int(seed)).spawn(n_batches)
        for b, child in enumerate(children):
            first = b * size
            yield self.run_batch(first, min(size, trials - first), np.random.default_rng(child))
