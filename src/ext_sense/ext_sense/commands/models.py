"""``ext-sense models create|list``: the default models of the three tasks, and where models are.

``create`` trains the default model of every task for one sensor on the scene simulator, with
the training paths the rest of the project uses: tap localization as ``ext-sense demo`` does
(NUSkin: windows cut from the emulated device's own byte stream, ``demo.ensure_model``; the same
model the demo uses), handover and food on simulated sets through the one training
recipe (``ext_sense_perception.training.recipe.train_bundle``); the NUSkin handover set is cut
from the device stream too, and again as a late reader reads it (``HANDOVER_LATE_READS``). It writes
``<task>_<sensor>/`` bundles into the user's data directory (``$EXT_SENSE_MODELS`` when set; see
``ext_sense_perception.online.model_store``) or ``--out DIR``. A model whose training inputs
(simulator and perception sources, scene, trial count) are unchanged is kept; ``--force``
retrains it. ``list`` prints the search path and every bundle found along it.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, TextIO

TASKS = ("tap_localization", "handover_stability", "food_identification")
TRIALS: dict[tuple[str, str], int] = {
    ("tap_localization", "nuskin"): 300,
    ("tap_localization", "biotac"): 300,
    ("handover_stability", "nuskin"): 400,
    ("handover_stability", "biotac"): 80,
    ("food_identification", "nuskin"): 70,
    ("food_identification", "biotac"): 70,
}
"""Simulated training trials per task and sensor. Taps: the demo's own default (so ``ext-sense
demo`` and ``ros2 launch`` share one model). Food and the BioTac handover: small sets that keep
the command at about a minute on the 2-core machine (docs/runtime.md has the measured times and
scores). The NUSkin handover: 400, because its release rule (3 confident estimates in a row)
needs probabilities that hold on live reads; on two live 40-grasp bags its model released 81 of
120 stable grasps (three fit seeds) with 80 trials, 96 with 160, 104 with 240 and 117 with 400,
against 103-120 on the same trials read ideally (docs/benchmarks.md, "Where the release streak
is lost")."""

JOBS = os.cpu_count() or 1
"""Grid-search jobs of the recipe-trained models, and processes cutting the NUSkin handover's
stream (its ideal and late-read cuts side by side): every core, the same model as one job. The
NUSkin handover's 400-trial fit on a slow 2-core machine: 129.2 + 244.8 s (model + anytime
models) with 1 job, 71.7 + 144.1 s with 2, the same CV accuracy and parameters
(``bench/handover_fit_jobs.py``, docs/runtime.md). Its three stream cuts: 95.7 s in one process,
85.3 s in two, the same windows (27 November 2026, same machine kind; each cut's windows, about
77 MB, travel back from its process)."""

HANDOVER_LATE_READS = 2
"""Extra cuts of the NUSkin handover training stream by a late reader
(``training.arrival_jitter.late_read_window_set``). Its FFT + SVM reads 2 ms bins, and live
stamps move events by a bin. On one live 40-grasp bag (docs/benchmarks.md, "Late-read
training") the model trained this way brought 7 of its 20 stable grasps to the release rule
where the former one (bin-level augmentation only) brought 5, at 0.868 against 0.843
accuracy; offline, on the plan's ideal stamps, 16 and 17."""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``models`` subcommand with ``create`` and ``list``."""
    parser = subparsers.add_parser(
        "models",
        help="create the default models of the three tasks; list where models are found",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="models_command", metavar="{create,list}")
    sub.required = True
    create = sub.add_parser(
        "create",
        help="train the default models on the simulator",
        description="Train the default model of each task on the scene simulator into "
        "OUT/<task>_<sensor>.",
    )
    create.add_argument(
        "--out",
        type=Path,
        help="directory of the bundles (default: $EXT_SENSE_MODELS when set, else "
        "$XDG_DATA_HOME/ext_sense/models, i.e. ~/.local/share/ext_sense/models)",
    )
    create.add_argument("--sensor", choices=("nuskin", "biotac"), default="nuskin")
    create.add_argument(
        "--task",
        action="append",
        choices=TASKS,
        help="only this task (repeatable; default: all three)",
    )
    create.add_argument(
        "--force", action="store_true", help="retrain even when a current model is there"
    )
    create.set_defaults(func=_create)
    listing = sub.add_parser("list", help="the search path and every model found along it")
    listing.set_defaults(func=_list)


def create_models(
    out: Path,
    sensor: str,
    tasks: tuple[str, ...] = TASKS,
    force: bool = False,
    log: TextIO = sys.stderr,
) -> int:
    """Train the default model of each task into ``out/<task>_<sensor>``.

    Returns:
        0 on success, else the failing step's exit code (the others are still attempted).
    """
    from ext_sense.commands.demo import ensure_model
    from ext_sense_perception.online.model_store import default_name

    rc = 0
    for task in tasks:
        model_dir = out / default_name(task, sensor)
        t0 = time.monotonic()
        trials = TRIALS[(task, sensor)]
        print(f"[models] {task}/{sensor}: {trials} simulated trials -> {model_dir}", file=log)
        if task == "tap_localization":
            step = ensure_model(model_dir, sensor, trials, retrain=force, log=log)
        else:
            step = train_simulated(model_dir, task, sensor, trials, force, log)
        print(
            f"[models] {task}/{sensor}: {'done' if step == 0 else 'FAILED'} in "
            f"{time.monotonic() - t0:.1f} s",
            file=log,
        )
        rc = rc or step
    return rc


def train_simulated(
    model_dir: Path, task: str, sensor: str, trials: int, force: bool, log: TextIO
) -> int:
    """Simulate ``trials`` of the task's default scene and train the one recipe on them.

    NUSkin events are taken as the driver delivers them (polarity 0, ``demo.as_delivered``). A
    model whose fingerprint (``demo.training_fingerprint``) is current is kept unless ``force``.
    """
    from ext_sense.commands.demo import (
        FINGERPRINT_FILE,
        TRAIN_SEED,
        as_delivered,
        training_fingerprint,
    )
    from ext_sense.graphs import DEFAULT_SCENES
    from ext_sense_perception.data.sources import from_sim_dataset
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.training.recipe import Recipe, train_bundle
    from ext_sense_sim.errors import SceneError
    from ext_sense_sim.run import run_scene
    from ext_sense_sim.scene import load_scene

    scene = DEFAULT_SCENES[(task, sensor)]
    from_stream = task == "handover_stability" and sensor == "nuskin"
    how = f"stream, {HANDOVER_LATE_READS} late reads" if from_stream else "dataset"
    fingerprint = training_fingerprint(sensor, f"{scene} ({how})", trials)
    stamp = model_dir / FINGERPRINT_FILE
    current = stamp.is_file() and stamp.read_text().strip() == fingerprint
    if (model_dir / "model_card.json").is_file() and current and not force:
        print(f"[models] keeping {model_dir} (trained from the same inputs)", file=log)
        return 0
    try:
        t0 = time.monotonic()
        if from_stream:
            ws, recipe = late_read_set(scene, task, trials), Recipe(arrival_jitter=0.0, n_jobs=JOBS)
        else:
            with tempfile.TemporaryDirectory(prefix="ext_sense_models_") as tmp:
                run_scene(
                    load_scene(scene), Path(tmp) / "sim", trials, TRAIN_SEED, formats=("npz",)
                )
                npz = Path(tmp) / "sim" / "dataset.npz"
                if sensor == "nuskin":
                    npz = as_delivered(npz, Path(tmp) / "delivered.npz")
                ws, recipe = from_sim_dataset(npz), Recipe(n_jobs=JOBS)
        t1 = time.monotonic()
        print(
            f"[models] simulated {scene} ({how}: {len(ws.y)} windows) in {t1 - t0:.1f} s", file=log
        )
        card = train_bundle(ws, model_dir, recipe)
    except (SceneError, PerceptionError, OSError) as err:
        print(f"ext-sense models: error: {err}", file=sys.stderr)
        return 2
    stamp.write_text(fingerprint + "\n")
    print(
        f"[models] trained {card.id} in {time.monotonic() - t1:.1f} s; metrics {card.metrics}",
        file=log,
    )
    return 0


def late_read_set(
    scene: str,
    task: str,
    trials: int,
    late_reads: int = HANDOVER_LATE_READS,
    n_jobs: int = JOBS,
) -> Any:
    """The scene's trials as the emulated device streams them, cut ideally and by late reads.

    The ``contact_window`` node's own configuration cuts them (``WindowConfig.for_task``), so
    the windows are the ones the live graph makes; trials are one second apart, as the demo's.
    """
    from ext_sense.commands.demo import TRAIN_SEED, TRIAL_PERIOD_S
    from ext_sense_perception.online.window import WindowConfig
    from ext_sense_perception.training.arrival_jitter import late_read_window_set
    from ext_sense_sim.scene import load_scene
    from ext_sense_sim.trial_plan import lay_out_stream

    laid = lay_out_stream(load_scene(scene), TRAIN_SEED, trials, TRIAL_PERIOD_S)
    config = WindowConfig.for_task(task, "nuskin")
    ws, _ = late_read_window_set(
        laid.writes, laid.truths, config, late_reads, source=f"stream:{scene}", n_jobs=n_jobs
    )
    return ws


def _create(args: argparse.Namespace) -> int:
    from ext_sense_perception.online.model_store import default_store

    out = (args.out or default_store()).expanduser().absolute()
    tasks = tuple(args.task) if args.task else TASKS
    rc = create_models(out, args.sensor, tasks, args.force)
    if rc == 0:
        print(f"models of {', '.join(tasks)} ({args.sensor}) in {out}")
    return rc


def _list(args: argparse.Namespace) -> int:
    from ext_sense_perception.errors import PerceptionError
    from ext_sense_perception.online.model_card import read_card
    from ext_sense_perception.online.model_store import (
        describe,
        find_model,
        search_places,
        stored_models,
    )

    print("search path (a name is looked up in this order; never in the working directory):")
    for i, place in enumerate(search_places(), 1):
        absent = place.root is not None and not place.root.is_dir()
        print(f"  {i}. {describe(place)}{' (absent)' if absent else ''}")
    print("models:")
    found = stored_models()
    for m in found:
        try:
            card = read_card(m.path)
            what = f"{card.task}/{card.sensor} {card.id} {_metrics(card.metrics)}"
        except PerceptionError as err:
            what = f"unusable: {err}"
        shadow = " (shadowed by an earlier place)" if m.shadowed else ""
        print(f"  {m.name:<28} {m.place.label:<17} {m.path}{shadow}\n      {what}")
    if not found:
        print("  none")
    print("task defaults (what a graph loads without model:=):")
    for sensor in ("nuskin", "biotac"):
        for task in TASKS:
            try:
                where = str(find_model("", task, sensor))
            except PerceptionError:
                where = "not found"
            print(f"  {task + '/' + sensor:<28} -> {where}")
    return 0


def _metrics(metrics: dict[str, float]) -> str:
    shown = {k: v for k, v in metrics.items() if k in ("cv_mae_m", "cv_accuracy")}
    return " ".join(f"{k}={v:.4g}" for k, v in shown.items())
