"""Handover models on fresh trials cut ideally and by late readers they were not trained on.

    python bench/handover_late_reads.py MODEL_DIR [MODEL_DIR ...] [--trials 160] [--seed 11]

The scene's trials of ``--seed`` are laid out as the device streams them
(``ext_sense_sim.trial_plan.lay_out_stream``), then cut as the window node cuts them: with ideal
reads, and once per ``--late-seeds`` by a late reader with the measured read delays
(``training.arrival_jitter.rechunk_writes``). Per model and cut: accuracy, the share of stable
trials with P(stable) >= 0.8, and the release rule (``bench_live_offline.reaches_release``)
on the stable trials grouped by four, as one grasp. A model that keeps its releases here but
loses them live meets something live the late-reader model does not cover
(docs/benchmarks.md, "The emulator's look-ahead").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from bench_live_offline import GRASP_TRIALS, load, reaches_release

from ext_sense_perception.data.device_stream import match_truths, stream_windows
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.training.arrival_jitter import MEASURED_READ_DELAY, rechunk_writes
from ext_sense_sim.scene import load_scene
from ext_sense_sim.trial_plan import lay_out_stream

MATCH_NS = 300_000_000
"""Largest distance from a window's onset to its trial's (as the estimate monitor matches)."""


def score(model_dir: Path, cut: str, writes: list, truths: list, read_period_ns: int) -> str:
    """One model on one cut, as a printed line."""
    model, config = load(model_dir)
    kwargs = {"read_period_ns": read_period_ns} if read_period_ns else {}
    windows, _, _ = stream_windows(writes, config, **kwargs)
    pairs, _, missed = match_truths(windows, truths, MATCH_NS)
    ests, labels = [], []
    for window, truth in pairs:
        try:
            ests.append(model.predict(window))
        except PerceptionError:
            continue
        labels.append(truth.class_label)
    correct = np.mean([e.class_label == y for e, y in zip(ests, labels, strict=True)])
    stable = [e for e, y in zip(ests, labels, strict=True) if y == "stable"]
    p = np.array([e.stability_probability for e in stable])
    grasps = [
        stable[i : i + GRASP_TRIALS] for i in range(0, len(stable) - GRASP_TRIALS + 1, GRASP_TRIALS)
    ]
    released = sum(reaches_release(g) for g in grasps)
    return (
        f"{model_dir.name:>28} {cut:>9}: accuracy {correct:.3f} ({len(ests)} trials, {missed} "
        f"without a window), stable P>=0.8 {np.mean(p >= 0.8):.3f}, release {released} of "
        f"{len(grasps)}"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", type=Path, nargs="+")
    parser.add_argument("--scene", default="handover_rod_nuskin")
    parser.add_argument("--trials", type=int, default=160)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--late-seeds", default="101,102")
    args = parser.parse_args()
    laid = lay_out_stream(load_scene(args.scene), args.seed, args.trials, 1.0)
    cuts = {"ideal": (laid.writes, 0)}
    for s in (int(x) for x in args.late_seeds.split(",") if x):
        late = rechunk_writes(laid.writes, MEASURED_READ_DELAY, np.random.default_rng(s))
        cuts[f"late {s}"] = (late, 1)
    for model_dir in args.models:
        for name, (writes, period) in cuts.items():
            print(score(model_dir, name, writes, laid.truths, period), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
