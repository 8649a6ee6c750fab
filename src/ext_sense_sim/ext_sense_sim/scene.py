"""Scenes: YAML files declaring task, object, grasp, sensor, effects, trials and seed.

A scene names every effect it needs, in run order. Shipped scenes live in
``ext_sense_sim/scenes/*.yaml`` and are found by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from ext_sense_runtime.enums import Sensor, Task
from ext_sense_sim.errors import SceneError
from ext_sense_sim.geometry import Geometry, geometry_from

DEFAULT_RATE_HZ = {Sensor.NUSKIN: 16000.0, Sensor.BIOTAC: 17600.0}
"""Simulation rates: NUSkin 16 kHz (the 0.25 ms refractory is 4 samples), BioTac 8 x 2200 Hz."""

DEFAULT_SCENES = {
    ("tap_localization", "nuskin"): "tap_rod30_nuskin",
    ("tap_localization", "biotac"): "tap_rod30_biotac",
    ("handover_stability", "nuskin"): "handover_rod_nuskin",
    ("handover_stability", "biotac"): "handover_plate_biotac",
    ("food_identification", "nuskin"): "food_fork_nuskin",
    ("food_identification", "biotac"): "food_fork_biotac",
}
"""The shipped scene of each ``(task, sensor)`` when none is named."""


@dataclass(frozen=True)
class Scene:
    """A parsed scene; ``effects`` are ``(name, parameters)`` in run order.

    Results depend on the seed and on ``batch_size``, the trials simulated together.
    """

    name: str
    task: Task
    sensor: Sensor
    geometry: Geometry
    effects: tuple[tuple[str, Mapping[str, Any]], ...]
    rate_hz: float
    trial_s: float
    trials: int = 100
    seed: int = 0
    batch_size: int = 50
    description: str = ""
    path: Path | None = field(default=None, compare=False)

    @property
    def effect_names(self) -> tuple[str, ...]:
        """Names of the listed effects, in run order."""
        return tuple(name for name, _ in self.effects)

    @property
    def n_samples(self) -> int:
        """Simulation samples per trial."""
        return round(self.trial_s * self.rate_hz)


def _enum(enum: type, value: Any, key: str) -> Any:
    names = [m.name.lower() for m in enum]
    if not isinstance(value, str) or value.lower() not in names:
        raise SceneError(f"Scene '{key}' must be one of {names}. Got {value!r} instead.")
    return enum[value.upper()]


def _effects(raw: Any) -> tuple[tuple[str, Mapping[str, Any]], ...]:
    if not isinstance(raw, list) or not raw:
        raise SceneError(f"Scene 'effects' must be a non-empty list. Got {raw!r} instead.")
    out = []
    for item in raw:
        if isinstance(item, str):
            out.append((item, {}))
        elif isinstance(item, dict) and len(item) == 1:
            ((name, params),) = item.items()
            if params is not None and not isinstance(params, dict):
                raise SceneError(
                    f"Scene effect '{name}': parameters must be a mapping. Got {params!r}."
                )
            out.append((str(name), dict(params or {})))
        else:
            raise SceneError(
                f"Scene 'effects' items must be a name or {{name: {{params}}}}. Got {item!r}."
            )
    return tuple(out)


def scene_from_dict(data: Mapping[str, Any], name: str, path: Path | None = None) -> Scene:
    """Build a :class:`Scene` from parsed YAML (a :class:`SceneError` names a bad section)."""
    if not isinstance(data, Mapping):
        raise SceneError(f"Scene '{name}' must be a YAML mapping. Got {type(data).__name__}.")
    task = _enum(Task, data.get("task"), "task")
    sensor = _enum(Sensor, data.get("sensor"), "sensor")
    grasp = data.get("grasp") or {}
    geometry = geometry_from(data.get("object") or {}, float(grasp.get("held_length_m", 0.03)))
    timing = data.get("timing") or {}
    try:
        rate = float(timing.get("rate_hz", DEFAULT_RATE_HZ[sensor]))
        trial_s = float(timing.get("trial_s", 0.3))
        trials, seed = int(data.get("trials", 100)), int(data.get("seed", 0))
        batch = int(data.get("batch_size", 50))
    except (TypeError, ValueError) as err:
        raise SceneError(f"Scene '{name}': timing, trials, seed and batch_size: {err}") from err
    if not (1000.0 <= rate <= 1e6 and 0 < trial_s <= 600 and trials >= 1 and batch >= 1):
        raise SceneError(
            f"Scene '{name}': need rate_hz in [1e3, 1e6], trial_s in (0, 600], trials >= 1 and "
            f"batch_size >= 1. Got {rate}, {trial_s}, {trials}, {batch}."
        )
    return Scene(
        name=name,
        task=task,
        sensor=sensor,
        geometry=geometry,
        effects=_effects(data.get("effects")),
        rate_hz=rate,
        trial_s=trial_s,
        trials=trials,
        seed=seed,
        batch_size=batch,
        description=str(data.get("description", "")),
        path=path,
    )


def shipped_scenes() -> dict[str, Path]:
    """Names and paths of the scenes shipped in the package, sorted by name."""
    folder = resources.files("ext_sense_sim") / "scenes"
    return {
        p.stem: Path(str(p))
        for p in sorted(folder.iterdir(), key=lambda p: p.name)
        if p.name.endswith(".yaml")
    }


def load_scene(name_or_path: str | Path) -> Scene:
    """Load a shipped scene by name, or any scene file by path."""
    shipped = shipped_scenes()
    key = str(name_or_path)
    path = shipped.get(key, Path(key))
    if not path.is_file():
        raise SceneError(
            f"Scene {key!r} is neither a shipped scene ({', '.join(shipped)}) nor a file."
        )
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise SceneError(f"Scene file {path} cannot be read: {err}") from err
    return scene_from_dict(
        data, data.get("name", path.stem) if isinstance(data, dict) else path.stem, path
    )
