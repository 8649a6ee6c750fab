"""``sim run``: simulate a scene's trials and write every output into one folder.

The layout of the folder is in docs/simulator.md ("Outputs of ``sim run``").
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from ext_sense_sim.dataset import DatasetCollector
from ext_sense_sim.engine import Simulator
from ext_sense_sim.errors import SceneError
from ext_sense_sim.scene import Scene

KEPT_SIGNALS = ("labels", "events", "biotac", "wire")
"""What the writers need of each batch (the big intermediate arrays are dropped)."""


def run_scene(
    scene: Scene,
    out: Path,
    trials: int | None = None,
    seed: int | None = None,
    formats: tuple[str, ...] = ("npz", "paper", "raw", "bag"),
) -> dict[str, Any]:
    """Simulate and write the outputs into a new or empty ``out``; returns ``run.json``'s summary.

    ``trials`` and ``seed`` default to the scene's.
    """
    from ext_sense_sim.output import write_outputs

    trials = scene.trials if trials is None else int(trials)
    seed = scene.seed if seed is None else int(seed)
    out = Path(out)
    if out.exists() and any(out.iterdir()):
        raise SceneError(
            f"The output folder {out} must be new or empty (it holds a previous run, whose "
            f"files would mix with this one). Choose another --out or remove it."
        )
    out.mkdir(parents=True, exist_ok=True)
    sim = Simulator(scene)
    collector = DatasetCollector(scene, seed)
    start = time.perf_counter()
    batches = []
    for tb, signals in sim.batches(trials, seed):
        collector.add(tb, signals)
        batches.append((tb, {k: v for k, v in signals.items() if k in KEPT_SIGNALS}))
    sim_s = time.perf_counter() - start
    written = write_outputs(scene, out, collector, batches, formats)
    summary = {
        "scene": scene.name,
        "trials": trials,
        "seed": seed,
        "simulate_s": round(sim_s, 3),
        "effects": {k: asdict(v) for k, v in sim.stats.items()},
        "files": sorted(str(p.relative_to(out)) for p in written),
    }
    (out / "run.json").write_text(json.dumps(summary, indent=2))
    return summary
