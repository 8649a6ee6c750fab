"""Window shift: how far the default tap model's estimate moves when a window's onset moves.

A serial link's arrival clock moves a tap window's onset by up to about 2 ms. The default NUSkin
tap model (trained here, or ``--model DIR``) is scored on fresh taps of another seed, cut from
ideal reads (``fresh``) and from reads late by ``bench_arrival.py``'s delays (``late reads``);
each fresh window is cut again with its onset moved +-0.5, +-1 and +-2 ms: the estimate's move,
median and p90 (issue 30: at most 0.3 cm and 1 cm up to 2 ms), beside the CV and fresh-tap MAE.
Without ``--quick`` or ``--model`` models without the FFT taper, and on the paper's box bins
without it, are trained beside it on the same windows.

    python bench/bench_window_shift.py            # the default model's 600 training taps, 200 fresh
    python bench/bench_window_shift.py --quick    # 100 / 60
    python bench/bench_window_shift.py --model DIR  # a tap bundle, e.g. the demo's
    python bench/bench_window_shift.py --model DIR --seeds 9,10,11,12,13  # five fresh sets

One set of 200 fresh taps is a sample (standard error about 0.07 cm): with ``--seeds`` each
further set's MAE is printed too, and the pooled MAE the CV is held against.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ext_sense_perception.data.device_stream import READ_PERIOD_NS, cut_stream, match_truths
from ext_sense_perception.online.window import WindowConfig
from ext_sense_perception.training.arrival_jitter import MEASURED_READ_DELAY, rechunk_writes
from ext_sense_perception.training.recipe import fit_recipe
from ext_sense_perception.training.window_shift import estimate_moves
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import MS

FRESH_SEED = 9
"""Seed of the fresh taps (issue 30 scored the default model on ``sim run --seed 9``)."""
SHIFTS_MS = (0.5, 1.0, 2.0)
"""Onset moves measured, ms (each both ways)."""
MATCH_NS = 300 * MS
"""A window is a tap's when its onset lies this near the tap's true onset (as the monitor)."""

Predict = Callable[[np.ndarray], np.ndarray]


class FreshTaps(NamedTuple):
    """Fresh taps cut as the live graph cuts them, and the events they were cut from."""

    X: np.ndarray  # (n, 80, n_samples) float32
    y: np.ndarray  # (n,) tap positions, m
    onsets_ns: np.ndarray  # (n,) detected onsets
    events: EventBlock  # every event as the driver stamped it


def fresh_taps(
    reads: list[tuple[int, bytes]], truths: list, config: WindowConfig, read_period_ns: int
) -> FreshTaps:
    """The labelled final windows of a stream, with the events they were cut from.

    ``reads``: ``(t_ns, bytes)`` writes read every ``read_period_ns``, or (``read_period_ns``
    1) ``(read_ns, bytes)`` reads of a late reader.
    """
    cut = cut_stream(reads, config, read_period_ns=read_period_ns, keep_events=True)
    picked, _, _ = match_truths(cut.windows, truths, MATCH_NS)
    return FreshTaps(
        np.stack([w.data for w, _ in picked]),
        np.array([g.tap_position_m for _, g in picked]),
        np.array([w.onset_ns for w, _ in picked], dtype=np.int64),
        cut.events,
    )


def errors_cm(predict: Predict, taps: FreshTaps) -> np.ndarray:
    """Absolute error of each tap's estimate, cm."""
    return np.abs(predict(taps.X.reshape(len(taps.y), -1)) - taps.y) * 100


def mean_se(err: np.ndarray) -> tuple[float, float]:
    """Mean of ``err`` and its standard error."""
    return float(np.mean(err)), float(np.std(err, ddof=1) / np.sqrt(err.size))


def mae_cm(predict: Predict, taps: FreshTaps) -> tuple[float, float]:
    """Mean absolute error on the taps and its standard error, cm."""
    return mean_se(errors_cm(predict, taps))


def row(
    name: str,
    cv_cm: float,
    predict: Predict,
    fresh: FreshTaps,
    late: FreshTaps,
    config: WindowConfig,
) -> str:
    """One model's line: CV, fresh and late-read MAE, and the estimate moves per onset shift."""
    steps = [round(s * MS) for s in SHIFTS_MS]
    moves = estimate_moves(
        predict,
        fresh.events,
        fresh.onsets_ns,
        config,
        [d * sign for d in steps for sign in (-1, 1)],
    )
    (fresh_mae, fresh_se), (late_mae, late_se) = mae_cm(predict, fresh), mae_cm(predict, late)
    cells = []
    for d in steps:
        both = 100 * np.concatenate([moves[d], moves[-d]])
        cells.append(f"{np.median(both):5.2f} / {np.percentile(both, 90):4.2f}")
    return (
        f"  {name:26s} {cv_cm:6.2f} {fresh_mae:5.2f}+-{fresh_se:4.2f}"
        f" {late_mae:5.2f}+-{late_se:4.2f} {cv_cm / fresh_mae:6.2f} {late_mae / fresh_mae:6.2f}   "
        + "   ".join(cells)
    )


def by_seed(
    name: str, cv_cm: float, predict: Predict, seeds: list[int], sets: list[FreshTaps]
) -> str:
    """One model's fresh-tap MAE on each set and pooled, and the CV against the pooled."""
    errors = [errors_cm(predict, taps) for taps in sets]
    each = ", ".join(f"{seed} {e.mean():.2f}" for seed, e in zip(seeds, errors, strict=True))
    pooled = np.concatenate(errors)
    mae, se = mean_se(pooled)
    return (
        f"  {name:26s} fresh MAE by seed: {each}; pooled ({pooled.size} taps) "
        f"{mae:.2f}+-{se:.2f}, cv/pooled {cv_cm / mae:.2f}"
    )


def _bins(feature_params: dict) -> str:
    """How a card's features bin and taper, e.g. ``gauss, taper 0.2``."""
    kernel = feature_params.get("bin_kernel", "box")
    taper = feature_params.get("taper", 0.0)
    return f"{kernel}, taper {taper:g}" if taper else kernel


def main() -> int:
    from ext_sense_sim.default_models import TRAIN_SEED, TRIAL_PERIOD_S, TRIALS, training_set
    from ext_sense_sim.errors import SceneError
    from ext_sense_sim.scene import DEFAULT_SCENES, load_scene
    from ext_sense_sim.trial_plan import lay_out_stream

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 training and 60 fresh taps")
    parser.add_argument("--model", type=Path, help="score this tap bundle instead of training")
    parser.add_argument("--scene", default=DEFAULT_SCENES[("tap_localization", "nuskin")])
    parser.add_argument(
        "--train", type=int, help="training taps (default: the default model's, quick 100)"
    )
    parser.add_argument("--fresh", type=int, help="fresh taps (default 200, quick 60)")
    parser.add_argument(
        "--seeds",
        default=str(FRESH_SEED),
        help=f"comma-separated seeds of fresh tap sets (default {FRESH_SEED}); the moves and "
        "late reads are measured on the first, the MAE on each and pooled",
    )
    args = parser.parse_args()
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        print(f"bench_window_shift: error: --seeds {args.seeds!r}: not integers", file=sys.stderr)
        return 2
    n_train = args.train or (100 if args.quick else TRIALS[("tap_localization", "nuskin")])
    n_fresh = args.fresh or (60 if args.quick else 200)
    config = WindowConfig.for_task(Task.TAP_LOCALIZATION, Sensor.NUSKIN)
    if min(n_train, n_fresh) < 8:
        print("bench_window_shift: error: --train and --fresh must be at least 8", file=sys.stderr)
        return 2
    try:
        scene = load_scene(args.scene)
    except SceneError as err:
        print(f"bench_window_shift: error: {err}", file=sys.stderr)
        return 2

    bundle = None
    if args.model:
        from ext_sense_perception.errors import PerceptionError
        from ext_sense_perception.online.predictor import load_model

        try:
            bundle = load_model(args.model, "sklearn", "tap_localization", "nuskin")
        except PerceptionError as err:
            print(f"bench_window_shift: error: {err}", file=sys.stderr)
            return 2

    t0 = time.perf_counter()
    laid = lay_out_stream(scene, seeds[0], n_fresh, TRIAL_PERIOD_S)
    fresh = fresh_taps(laid.writes, laid.truths, config, READ_PERIOD_NS)
    late_reads = rechunk_writes(laid.writes, MEASURED_READ_DELAY, np.random.default_rng(5))
    late = fresh_taps(late_reads, laid.truths, config, 1)
    print(
        f"[window shift] {args.scene}: {len(fresh.y)} fresh taps (seed {seeds[0]}) cut as the "
        f"live graph cuts them, {len(late.y)} again by a late reader; "
        f"{time.perf_counter() - t0:.0f} s",
        flush=True,
    )

    models: list[tuple[str, float, Predict]] = []
    if bundle is not None:
        card = bundle.card
        label = _bins(card.feature_params)
        models.append((label, 100 * card.metrics["cv_mae_m"], lambda x: bundle.raw_predict(x)[0]))
        print(f"  model {args.model} ({card.n_train} training windows)")
    else:
        t0 = time.perf_counter()
        ws, recipe = training_set("tap_localization", "nuskin", args.scene, n_train)
        recipe = dataclasses.replace(recipe, anytime_post_ns=())  # the anytime models aside
        variants = [("default", recipe)]
        if not args.quick:
            variants.append(("no taper", dataclasses.replace(recipe, taper=0.0)))
            variants.append(
                ("box, no taper", dataclasses.replace(recipe, bin_kernel="box", taper=0.0))
            )
            variants.append(("arrival jitter 0.5", dataclasses.replace(recipe, arrival_jitter=0.5)))
        for name, r in variants:
            trained, _ = fit_recipe(ws, r)
            label = f"{name} ({_bins(trained.card.feature_params)})" if name == "default" else name
            models.append((label, 100 * trained.card.metrics["cv_mae_m"], trained.pipeline.predict))
        print(
            f"  trained on {len(ws.y)} taps (seed {TRAIN_SEED}) in "
            f"{time.perf_counter() - t0:.0f} s",
            flush=True,
        )
    header = "   ".join(f"+-{s:g} ms".center(12) for s in SHIFTS_MS)
    print(
        f"  {'model':26s} {'cv':>6s} {'fresh':>11s} {'late':>11s} {'cv/fr':>6s} {'lt/fr':>6s}"
        f"   estimate moves, cm, median / p90, onset moved by:\n"
        f"  {'':26s} {'MAE cm':>6s} {'MAE+-se cm':>11s} {'MAE+-se cm':>11s} {'':6s} {'':6s}"
        f"   {header}"
    )
    for name, cv_cm, predict in models:
        print(row(name, cv_cm, predict, fresh, late, config), flush=True)
    if len(seeds) > 1:
        sets = [fresh]
        for seed in seeds[1:]:
            more = lay_out_stream(scene, seed, n_fresh, TRIAL_PERIOD_S)
            sets.append(fresh_taps(more.writes, more.truths, config, READ_PERIOD_NS))
        for name, cv_cm, predict in models:
            print(by_seed(name, cv_cm, predict, seeds, sets), flush=True)
    print("  target (issue 30): moves up to 2 ms <= 0.30 / 1.00 cm; cv, fresh and live within 15 %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
