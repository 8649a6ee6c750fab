"""NUSkin handover models trained on more or fewer simulated trials, scored on kept live bags.

    python bench/handover_bag_scores.py BAG:SEED [BAG:SEED ...] [--trials 80,400] [--late-reads 2]

BAG is a handover bag of ``bench_live_offline.py --keep`` (``handover_quiet_bag`` in its
directory), SEED the ``--seed`` of that run. Per training-set size and fit seed, the NUSkin
handover model is trained as ``ext-sense models create`` trains it (``models.late_read_set``:
the trials as the device streams them, cut with ideal reads and by two late readers; the one
recipe with ``arrival_jitter=0``), without its anytime models (the release rule reads final
estimates only). Each bag is then scored by ``bench_live_offline.score_run``, the bench's own
scoring: the bag's bytes replayed through the graph's core ("bag", equal to live in every run
so far) and the same trials with ideal reads ("plan"), stable grasps released by the handover
behaviour's rule and accuracy. Training trials never overlap the bags' trials (another seed).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from bench_live_offline import HANDOVER, score_run

from ext_sense.commands.models import HANDOVER_LATE_READS, late_read_set
from ext_sense.graphs import DEFAULT_SCENES
from ext_sense_perception.training.recipe import Recipe, train_bundle

TASK = "handover_stability"


def parse_bag(text: str) -> tuple[Path, int]:
    """``BAG:SEED`` -> (path, seed)."""
    path, _, seed = text.rpartition(":")
    if not path or not seed.isdigit():
        raise argparse.ArgumentTypeError(f"expected BAG:SEED, got {text!r}")
    return Path(path), int(seed)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bags", type=parse_bag, nargs="+", metavar="BAG:SEED")
    parser.add_argument("--trials", default="80,400", help="training-set sizes, comma separated")
    parser.add_argument("--fit-seeds", default="0,1,2", help="recipe seeds (folds, calibration)")
    parser.add_argument(
        "--late-reads", type=int, default=HANDOVER_LATE_READS, help="late-read cuts per trial"
    )
    args = parser.parse_args()
    scene = DEFAULT_SCENES[(TASK, "nuskin")]
    for n in (int(x) for x in args.trials.split(",")):
        t0 = time.monotonic()
        ws = late_read_set(scene, TASK, n, args.late_reads)
        print(
            f"{n} trials, {args.late_reads} late-read cuts: {len(ws.y)} windows cut in "
            f"{time.monotonic() - t0:.1f} s",
            flush=True,
        )
        total = {"bag": [0, 0, 0.0], "plan": [0, 0, 0.0]}  # released, stable, accuracy sum
        runs = 0
        for fit_seed in (int(x) for x in args.fit_seeds.split(",")):
            with tempfile.TemporaryDirectory(prefix="handover_bag_scores_") as tmp:
                model_dir = Path(tmp) / "model"
                t0 = time.monotonic()
                card = train_bundle(
                    ws, model_dir, Recipe(arrival_jitter=0.0, seed=fit_seed, anytime_post_ns=())
                )
                fit_s = time.monotonic() - t0
                for bag, seed in args.bags:
                    r = score_run(HANDOVER, "kept", seed, 0, bag, model_dir, {})
                    runs += 1
                    for name, s in (("bag", r.bag), ("plan", r.plan)):
                        total[name][0] += s.released_grasps
                        total[name][1] += s.stable_grasps
                        total[name][2] += s.accuracy
                    print(
                        f"  {n} trials, fit seed {fit_seed} (cv {card.metrics['cv_accuracy']:.3f}, "
                        f"{fit_s:.0f} s), bag seed {seed}: released bag {r.bag.released_grasps} / "
                        f"plan {r.plan.released_grasps} of {r.plan.stable_grasps}, accuracy bag "
                        f"{r.bag.accuracy:.3f} / plan {r.plan.accuracy:.3f}",
                        flush=True,
                    )
        (rb, sb, ab), (rp, sp, ap) = total["bag"], total["plan"]
        print(
            f"{n} trials: released bag {rb} of {sb}, plan {rp} of {sp} (bag / plan "
            f"{rb / max(rp, 1):.3f}); mean accuracy bag {ab / runs:.3f}, plan {ap / runs:.3f}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
