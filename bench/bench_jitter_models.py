"""Arrival-jitter augmentation, decided by measurement: models with and without it, side by side.

The training recipe trains each model twice on the same windows, without augmentation and with
``arrival_jitter=F`` (that fraction re-stamped as a late reader stamps them, with the read
delays ``bench_arrival.py`` measured). Both are scored on the same test trials cut ``clean``
(ideal reads), ``jittered`` (the measured delays, decoded and cut as live) and ``jittered x2``.
Scenes: ``tap_rod30_nuskin`` (MAE, cm) and ``handover_rod_nuskin`` (accuracy); ``--captures``:
the real food captures, leave-one-day-out with the held-out day re-stamped at bin level.

    python bench/bench_jitter_models.py            # 300 train / 100 test taps, 120/60 handovers
    python bench/bench_jitter_models.py --quick    # 100/40 taps, no handover (about 1 min)
    python bench/bench_jitter_models.py --captures /work/shared/data
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from ext_sense_perception.data.device_stream import window_set_from_stream
from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.online.window import WindowConfig
from ext_sense_perception.training.arrival_jitter import (
    MEASURED_READ_DELAY,
    ReadDelay,
    jitter_window,
    rechunk_writes,
)
from ext_sense_perception.training.recipe import Recipe, fit_recipe
from ext_sense_runtime.enums import Sensor, Task

SEED_TRAIN, SEED_TEST = 1000, 77
"""Seeds of the training and test trials (``--seed-offset`` adds to both)."""


def scaled(delay: ReadDelay, factor: float) -> ReadDelay:
    """The same distribution with every delay times ``factor``."""
    return delay._replace(delay_ns=tuple(int(d * factor) for d in delay.delay_ns))


def scene_sets(
    scene_name: str, task: Task, n_train: int, n_test: int, seed_offset: int = 0
) -> tuple[WindowSet, dict[str, WindowSet]]:
    """Training windows (clean) and the test windows cut clean and jittered."""
    from ext_sense_sim.scene import load_scene
    from ext_sense_sim.trial_plan import lay_out_stream

    scene = load_scene(scene_name)
    config = WindowConfig.for_task(task, Sensor.NUSKIN)
    train = lay_out_stream(scene, SEED_TRAIN + seed_offset, n_train)
    ws_train, _ = window_set_from_stream(train.writes, train.truths, config, source=scene_name)
    test = lay_out_stream(scene, SEED_TEST + seed_offset, n_test)
    tests = {"clean": window_set_from_stream(test.writes, test.truths, config)[0]}
    for name, factor in (("jittered", 1.0), ("jittered x2", 2.0)):
        rng = np.random.default_rng(5 + seed_offset)
        reads = rechunk_writes(test.writes, scaled(MEASURED_READ_DELAY, factor), rng)
        tests[name] = window_set_from_stream(reads, test.truths, config, read_period_ns=1)[0]
    return ws_train, tests


def score(model: object, ws: WindowSet) -> float:
    """MAE in cm (regression) or accuracy."""
    pred = model.predict(ws.X.reshape(len(ws.y), -1))
    if ws.is_regression:
        return float(np.mean(np.abs(pred - ws.y)) * 100)
    return float(np.mean(pred == ws.y))


def compare(ws_train: WindowSet, tests: dict[str, WindowSet], fraction: float) -> dict:
    """Fit without and with augmentation; scores on each test set."""
    out = {}
    for label, jitter in (("plain", 0.0), (f"aug {fraction:g}", fraction)):
        t0 = time.perf_counter()
        trained, _ = fit_recipe(ws_train, Recipe(anytime_post_ns=(), arrival_jitter=jitter))
        fit_s = time.perf_counter() - t0
        out[label] = {name: score(trained.pipeline, ws) for name, ws in tests.items()}
        out[label]["fit_s"] = fit_s
    return out


def print_table(title: str, unit: str, res: dict, tests: dict[str, WindowSet]) -> None:
    names = list(tests)
    print(f"[{title}] {unit}; test windows: " + ", ".join(f"{n} {len(tests[n].y)}" for n in names))
    print(f"  {'model':10s} " + " ".join(f"{n:>12s}" for n in names) + "   fit s")
    for label, r in res.items():
        print(
            f"  {label:10s} " + " ".join(f"{r[n]:12.3f}" for n in names) + f"   {r['fit_s']:5.1f}",
            flush=True,
        )


def captures(root: Path, fraction: float) -> None:
    """Leave one day out on the real food captures; the held-out day clean and re-stamped."""
    from ext_sense_perception.data.sessions import load_session, pooled

    days = sorted(p for p in root.glob("nuskin_food_poking*") if p.is_dir())
    sessions = [load_session(d, anchor="capture_start") for d in days]
    for k, held in enumerate(sessions):
        train = pooled([s for j, s in enumerate(sessions) if j != k])
        test = held.windows
        known = np.isin(test.y, train.class_names)
        if not known.any():
            print(f"[food, held out {held.info.name}] no window of a class the others know")
            continue
        test = test.subset(known)
        g = test.geometry
        rng = np.random.default_rng(5)
        tests = {"clean": test}
        for name, factor in (("jittered", 1.0), ("jittered x2", 2.0)):
            delay = scaled(MEASURED_READ_DELAY, factor)
            X = np.stack([jitter_window(x, g.period_ns, None, delay, rng) for x in test.X])  # noqa: N806
            tests[name] = test._replace(X=X)
        res = compare(train, tests, fraction)
        print_table(f"food, held out {held.info.name}", "accuracy", res, tests)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer trials, taps only")
    parser.add_argument("--fraction", type=float, default=0.5, help="arrival_jitter to compare")
    parser.add_argument("--captures", type=Path, help="folder holding nuskin_food_poking*")
    parser.add_argument("--seed-offset", type=int, default=0, help="added to the trial seeds")
    args = parser.parse_args()
    print(
        f"[jitter models] read delays: {MEASURED_READ_DELAY.source}; median "
        f"{np.interp(0.5, MEASURED_READ_DELAY.probs, MEASURED_READ_DELAY.delay_ns) / 1e3:.0f} us,"
        f" p99 {np.interp(0.99, MEASURED_READ_DELAY.probs, MEASURED_READ_DELAY.delay_ns) / 1e3:.0f}"
        " us",
        flush=True,
    )
    runs = [("tap_rod30_nuskin", Task.TAP_LOCALIZATION, "MAE cm", 300, 100)]
    if not args.quick:
        runs.append(("handover_rod_nuskin", Task.HANDOVER_STABILITY, "accuracy", 120, 60))
    else:
        runs = [("tap_rod30_nuskin", Task.TAP_LOCALIZATION, "MAE cm", 100, 40)]
    for scene, task, unit, n_train, n_test in runs:
        ws_train, tests = scene_sets(scene, task, n_train, n_test, args.seed_offset)
        print_table(
            f"{scene}, {len(ws_train.y)} train",
            unit,
            compare(ws_train, tests, args.fraction),
            tests,
        )
    if args.captures:
        captures(args.captures, args.fraction)
    return 0


if __name__ == "__main__":
    sys.exit(main())
