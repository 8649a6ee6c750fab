"""The compact simulator dataset ``dataset.npz`` (keys: docs/simulator.md, docs/conventions.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ext_sense_runtime.enums import Sensor, Task
from ext_sense_sim.effects.base import Signals, TimeBase
from ext_sense_sim.scene import Scene
from ext_sense_sim.trial_events import TrialEvents, concat

FINGER_TAXELS = np.arange(1, 81, dtype=np.uint16).reshape(2, 40)
BIOTAC_KEYS = ("pac", "pac_t0_ns", "pdc", "tac", "tdc", "electrodes")


class DatasetCollector:
    """Gathers the labels and sensor data of every batch of a run.

    Args:
        scene: The scene being run.
        seed: The run's seed (stored in the file).
    """

    def __init__(self, scene: Scene, seed: int) -> None:
        self.scene = scene
        self.seed = int(seed)
        self._labels: list = []
        self._events: list[TrialEvents] = []
        self._biotac: list[dict[str, np.ndarray]] = []

    def add(self, tb: TimeBase, signals: Signals) -> None:
        """Take the labels and sensor signal of one batch."""
        self._labels.append(signals["labels"])
        if self.scene.sensor is Sensor.NUSKIN:
            trial, events = signals["events"]
            self._events.append(((trial + tb.first_trial).astype(np.int32), events))
        else:
            self._biotac.append(signals["biotac"])

    def arrays(self) -> dict[str, np.ndarray]:
        """Everything collected so far as the dataset's arrays."""
        scene = self.scene
        onset = np.concatenate([lab.onset_ns for lab in self._labels]).astype(np.int64)
        n = onset.size
        regression = scene.task is Task.TAP_LOCALIZATION
        if regression:
            y = np.concatenate([lab.y_m for lab in self._labels]).astype(np.float64)
        else:
            y = np.concatenate([lab.class_label for lab in self._labels]).astype(str)
        rod = scene.geometry.length_m if scene.geometry.kind == "rod" else np.nan
        out: dict[str, np.ndarray] = {
            "task": np.array(scene.task.label),
            "sensor": np.array(scene.sensor.label),
            "label_kind": np.array("regression" if regression else "classification"),
            "scene": np.array(scene.name),
            "seed": np.array(self.seed, dtype=np.int64),
            "y": y,
            "trial": np.arange(n, dtype=np.int32),
            "onset_ns": onset,
            "rod_length_m": np.full(n, rod, dtype=np.float64),
            "trial_ns": np.array(round(scene.trial_s * 1e9), dtype=np.int64),
            "object_kind": np.array(scene.geometry.kind),
            "object_length_m": np.array(scene.geometry.length_m, dtype=np.float64),
            "finger_taxels": FINGER_TAXELS,
        }
        if scene.sensor is Sensor.NUSKIN:
            trial, ev = concat(self._events)
            out.update(
                ev_trial=trial.astype(np.int32),
                ev_t_ns=ev.t_ns.astype(np.int64),
                ev_taxel=ev.taxel.astype(np.uint16),
                ev_polarity=ev.polarity.astype(np.int8),
                ev_value=ev.value.astype(np.uint16),
            )
        else:
            for key in BIOTAC_KEYS:
                out[key] = np.concatenate([b[key] for b in self._biotac])
        return out

    def write_npz(self, path: Path) -> Path:
        """Write ``dataset.npz`` (compressed) and return its path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **self.arrays())
        return path
