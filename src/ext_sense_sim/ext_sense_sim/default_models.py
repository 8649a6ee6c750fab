"""The default model of each task, trained on the scene simulator (``ext-sense models create``).

Each is trained by perception's one recipe (``train_bundle``) on the windows the live graph
would cut from the task's default scene, kept while the fingerprint of its inputs is current,
and staged beside its place and renamed into it under a lock (``training.bundle_io``).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

import ext_sense_perception
from ext_sense_perception.data.device_stream import window_set_from_stream
from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.online.model_card import CARD_FILE
from ext_sense_perception.online.model_store import default_name
from ext_sense_perception.online.window import WindowConfig
from ext_sense_perception.training.arrival_jitter import late_read_window_set
from ext_sense_perception.training.bundle_io import check_place, place_lock, staged_bundle
from ext_sense_perception.training.recipe import Recipe, train_bundle
from ext_sense_sim.run import run_scene
from ext_sense_sim.scene import DEFAULT_SCENES, load_scene
from ext_sense_sim.trial_plan import lay_out_stream

Log = Callable[[str], None]

TASKS = ("tap_localization", "handover_stability", "food_identification")
TRIALS: dict[tuple[str, str], int] = {
    ("tap_localization", "nuskin"): 600,
    ("tap_localization", "biotac"): 300,
    ("handover_stability", "nuskin"): 400,
    ("handover_stability", "biotac"): 80,
    ("food_identification", "nuskin"): 140,
    ("food_identification", "biotac"): 70,
}
"""Simulated training trials per task and sensor: small sets where a minute's training does;
the NUSkin handover's release streak needs more (docs/benchmarks.md), and so does the NUSkin
tap model's card: on 300 taps its CV MAE said how hard its own taps were more than how it does
on fresh ones (docs/perception.md, "The default tap model's figures")."""

JOBS = os.cpu_count() or 1
"""Grid-search jobs and processes cutting the NUSkin handover's stream: every core."""

HANDOVER_LATE_READS = 2
"""Extra cuts of the NUSkin handover's training stream by a late reader (live stamps move
events by a bin; docs/benchmarks.md, "Late-read training")."""

TRAIN_SEED = 1000
"""Seed of the training trials (the demo's own taps use another)."""

TRIAL_PERIOD_S = 1.0
"""Trial spacing of a training stream: ``sim_device``'s default ``trial_period_s``."""

FINGERPRINT_FILE = "demo_fingerprint.txt"

BYTES_PER_TRIAL = {
    "tap_localization": 128_000,
    "handover_stability": 1_600_000,
    "food_identification": 32_000,
}
"""Free space asked of a place per training trial before training: about 1.5x what the NUSkin
bundles take (docs/benchmarks.md), an upper bound for the BioTac ones."""


def space_needed(jobs: Iterable[tuple[str, int]]) -> int:
    """Bytes asked of a place before training ``(task, trials)`` jobs."""
    return sum(BYTES_PER_TRIAL[task] * trials for task, trials in jobs)


def _quiet(_line: str) -> None:
    """The default log: say nothing."""


def training_fingerprint(sensor: str, scene: str, trials: int, how: str = "") -> str:
    """A hash of what a model is trained from: sim and perception sources (not nodes) and set."""
    digest = hashlib.sha256(f"{sensor}|{scene}|{how}|{trials}|{TRAIN_SEED}".encode())
    for root in (Path(__file__).parent, Path(ext_sense_perception.__file__).parent):
        for path in sorted(root.rglob("*")):
            if path.suffix in (".py", ".yaml") and "nodes" not in path.parts:
                digest.update(str(path.relative_to(root)).encode())
                digest.update(path.read_bytes())
    return digest.hexdigest()


def as_delivered(dataset: Path, out: Path) -> Path:
    """``dataset.npz`` as the NUSkin driver delivers it live: every polarity 0 (words have none)."""
    with np.load(dataset) as npz:
        arrays = {k: npz[k] for k in npz.files}
    arrays["ev_polarity"] = np.zeros_like(arrays["ev_polarity"])
    np.savez(out, **arrays)
    return out


def _how(task: str, sensor: str) -> str:
    if sensor != "nuskin" or task == "food_identification":
        return "dataset"
    if task == "tap_localization":
        return "stream"
    return f"stream, {HANDOVER_LATE_READS} late reads"


def training_set(
    task: str, sensor: str, scene: str, trials: int, log: Log = _quiet
) -> tuple[WindowSet, Recipe]:
    """The windows a default model is trained on, and the recipe that trains it.

    NUSkin taps and handovers: the device stream cut as the live graph cuts it (handovers also
    by late readers); the rest: a simulated dataset.
    """
    how = _how(task, sensor)
    if how == "dataset":
        with tempfile.TemporaryDirectory(prefix="ext_sense_models_") as tmp:
            run_scene(load_scene(scene), Path(tmp) / "sim", trials, TRAIN_SEED, formats=("npz",))
            npz = Path(tmp) / "sim" / "dataset.npz"
            if sensor == "nuskin":
                npz = as_delivered(npz, Path(tmp) / "delivered.npz")
            return from_sim_dataset(npz), Recipe(n_jobs=JOBS)
    t0 = time.monotonic()
    laid = lay_out_stream(load_scene(scene), TRAIN_SEED, trials, TRIAL_PERIOD_S)
    source = f"stream:{scene}"
    if how != "stream":
        config = WindowConfig.for_task(task, "nuskin")
        ws, _ = late_read_window_set(
            laid.writes, laid.truths, config, HANDOVER_LATE_READS, source=source, n_jobs=JOBS
        )
        return ws, Recipe(arrival_jitter=0.0, n_jobs=JOBS)
    ws, counts = window_set_from_stream(laid.writes, laid.truths, source=source)
    log(
        f"{counts.labelled} labelled windows from {counts.words} words "
        f"({counts.unmatched_windows} unmatched windows, {counts.missed_trials} trials without "
        f"a window) in {time.monotonic() - t0:.1f} s"
    )
    return ws, Recipe()


def is_current(model_dir: Path, task: str, sensor: str, trials: int, scene: str) -> bool:
    """Whether ``model_dir`` holds a model trained from the inputs this checkout has."""
    stamp = model_dir / FINGERPRINT_FILE
    return (
        (model_dir / CARD_FILE).is_file()
        and stamp.is_file()
        and stamp.read_text().strip()
        == training_fingerprint(sensor, scene, trials, _how(task, sensor))
    )


def _train(
    model_dir: Path, task: str, sensor: str, trials: int, scene: str, force: bool, log: Log
) -> bool:
    """Train one model unless current, with the place checked and locked by the caller."""
    if not force and is_current(model_dir, task, sensor, trials, scene):
        log(f"using model {model_dir} (trained from the same inputs)")
        return False
    if (model_dir / CARD_FILE).is_file() and not force:
        log(f"{model_dir} was trained from other simulator, perception or scene inputs; retraining")
    how = _how(task, sensor)
    t0 = time.monotonic()
    log(f"{task}/{sensor}: {trials} simulated trials of {scene} ({how}) -> {model_dir}")
    ws, recipe = training_set(task, sensor, scene, trials, log)
    t1 = time.monotonic()
    log(f"simulated {len(ws.y)} windows in {t1 - t0:.1f} s")
    with staged_bundle(model_dir) as staged:
        card = train_bundle(ws, staged, recipe)
        fingerprint = training_fingerprint(sensor, scene, trials, how)
        (staged / FINGERPRINT_FILE).write_text(fingerprint + "\n")
    log(f"trained {card.id} in {time.monotonic() - t1:.1f} s; metrics {card.metrics}")
    return True


def _ensure_all(
    place: Path, jobs: list[tuple[str, Path, int, str]], sensor: str, force: bool, log: Log
) -> bool:
    """Train each ``(task, model_dir, trials, scene)`` job unless its model is current.

    ``place`` is first checked for room and locked while models are made (a second run waits).
    """
    todo = []
    for task, model_dir, trials, scene in jobs:
        if not force and is_current(model_dir, task, sensor, trials, scene):
            log(f"using model {model_dir} (trained from the same inputs)")
        else:
            todo.append((task, model_dir, trials, scene))
    if not todo:
        return False
    check_place(place, space_needed((task, trials) for task, _, trials, _ in todo))
    with place_lock(place, log):
        trained = [_train(d, task, sensor, n, scene, force, log) for task, d, n, scene in todo]
    return any(trained)


def ensure_model(
    model_dir: Path,
    task: str,
    sensor: str,
    trials: int | None = None,
    scene: str = "",
    force: bool = False,
    log: Log = _quiet,
) -> bool:
    """Train the task's default model into ``model_dir`` unless a current one is there.

    ``trials`` and ``scene`` default to the task's (:data:`TRIALS`, ``DEFAULT_SCENES``); a
    current model is used wherever it lies, else the parent of ``model_dir`` is checked and
    locked as by :func:`create_models`. Returns whether a model was trained.

    Raises:
        PerceptionError: The place is not writable or too full, or training failed.
        SceneError: The scene cannot be loaded.
    """
    trials = trials or TRIALS[(task, sensor)]
    scene = scene or DEFAULT_SCENES[(task, sensor)]
    return _ensure_all(model_dir.parent, [(task, model_dir, trials, scene)], sensor, force, log)


def create_models(
    out: Path, sensor: str, tasks: Sequence[str] = TASKS, force: bool = False, log: Log = _quiet
) -> None:
    """Train the default model of each task into ``out/<task>_<sensor>`` unless current."""
    jobs = [
        (t, out / default_name(t, sensor), TRIALS[(t, sensor)], DEFAULT_SCENES[(t, sensor)])
        for t in tasks
    ]
    _ensure_all(out, jobs, sensor, force, log)
