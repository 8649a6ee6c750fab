"""Trials for the emulated devices: simulated one by one, or laid out at once.

:func:`plan_trials` feeds real-time streaming; :func:`lay_out_stream` lays trials on one stream
clock to train on. SciPy is imported only where trials are simulated.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import NamedTuple

import numpy as np

from ext_sense_runtime.enums import Sensor
from ext_sense_runtime.records import GroundTruth
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import Scene

WIRE_EFFECT = {Sensor.NUSKIN: "nuskin_wire", Sensor.BIOTAC: "biotac_wire"}


def require_wire(scene: Scene) -> None:
    """Raise :class:`SceneError` unless the scene lists its sensor's wire effect."""
    wire = WIRE_EFFECT[scene.sensor]
    if wire not in scene.effect_names:
        raise SceneError(
            f"Scene '{scene.name}' cannot be streamed: it needs effect '{wire}', which its "
            f"effects list lacks."
        )


class PlannedTrial(NamedTuple):
    """One simulated trial ready to stream: its chunks and its truth (times from its start)."""

    trial: int
    chunks: list[tuple[int, bytes]]
    onset_ns: int
    tap_position_m: float
    class_label: str


def plan_trials(scene: Scene, seed: int) -> Iterator[PlannedTrial]:
    """Simulate trials one by one, forever; the scene must list its sensor's wire effect."""
    from ext_sense_sim.engine import Simulator  # here: see the module docstring

    require_wire(scene)
    single = dataclasses.replace(scene, batch_size=1)
    sim = Simulator(single)
    seeds = np.random.SeedSequence(int(seed))
    k = 0
    while True:
        rng = np.random.default_rng(seeds.spawn(1)[0])
        _, signals = sim.run_batch(k, 1, rng)
        labels = signals["labels"]
        yield PlannedTrial(
            k,
            signals["wire"][0].chunks(),
            int(labels.onset_ns[0]),
            float(labels.y_m[0]),
            str(labels.class_label[0]),
        )
        k += 1


class LaidOutStream(NamedTuple):
    """A run of trials laid on one stream clock: ``(t_ns, bytes)`` writes and ground truths.

    A truth's ``onset_ns`` is the time of the write holding the trial's first bytes at or after
    its true onset, as ``stream`` stamps it live.
    """

    writes: list[tuple[int, bytes]]
    truths: list[GroundTruth]


def lay_out_stream(scene: Scene, seed: int, trials: int, period_s: float = 1.0) -> LaidOutStream:
    """The device bytes of ``trials`` trials, ``period_s`` apart, without real-time waiting.

    The same wire effect and trial spacing as :func:`~ext_sense_sim.streaming.stream`, simulated
    in the scene's batches, so a model can be trained on exactly what the driver decodes live.
    """
    from ext_sense_sim.engine import Simulator  # here: see the module docstring

    require_wire(scene)
    period_ns = round(max(period_s, scene.trial_s) * 1e9)
    rod = scene.geometry.length_m if scene.geometry.kind == "rod" else float("nan")
    writes: list[tuple[int, bytes]] = []
    truths: list[GroundTruth] = []
    for tb, signals in Simulator(scene).batches(trials, seed):
        labels = signals["labels"]
        for i, wstream in enumerate(signals["wire"]):
            k = tb.first_trial + i
            t0 = k * period_ns
            chunks = wstream.chunks()
            times = np.array([c[0] for c in chunks], dtype=np.int64)
            j = int(np.searchsorted(times, int(labels.onset_ns[i])))
            writes.extend((t0 + int(t), b) for t, b in chunks)
            if j < times.size:
                truths.append(
                    GroundTruth(
                        k,
                        t0 + int(times[j]),
                        scene.task.label,
                        float(labels.y_m[i]),
                        str(labels.class_label[i]),
                        rod,
                    )
                )
    return LaidOutStream(writes, truths)
