"""Sweep benchmark: the same small grid of protocol fits in one process and on local Dask clusters.

Prints, side by side in one run, the wall time of one grid (feature sets x models x K splits on
synthetic NUSkin taps, every fit a task) run in this process, with ``--workers 1`` and with
``--workers 2`` (each cluster started and stopped inside the timing, as ``ext-sense report
--workers N`` does), the speed-up of 2 workers over 1 and over the single process, and that the
three runs give identical scores. No cache: every fit is computed each time.

    python bench/bench_sweep.py            # 300 taps, fft + baseline x svm_linear + svm_rbf, K 4
    python bench/bench_sweep.py --quick    # 120 taps, fft x svm_rbf + svm_linear, K 2
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from bench_perception import synthetic_taps

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.training.fit_executor import fit_executor
from ext_sense_perception.training.protocol import evaluate, features_for


def run_grid(
    ws: WindowSet, features: list[str], models: list[str], k: int, workers: int | None
) -> tuple[np.ndarray, float]:
    """Scores of every (features, model) point and the wall time, s."""
    t0 = time.perf_counter()
    with fit_executor(workers=workers) as ex:
        scores = [
            evaluate(ws, features_for(ws, f), m, k=k, executor=ex, progress=False).scores
            for f in features
            for m in models
        ]
    return np.concatenate(scores), time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    n, feats, models, k = (
        (120, ["fft"], ["svm_rbf", "svm_linear"], 2)
        if args.quick
        else (300, ["fft", "baseline"], ["svm_linear", "svm_rbf"], 4)
    )
    ws = synthetic_taps(n)
    n_fits = len(feats) * len(models) * k
    alone, t_alone = run_grid(ws, feats, models, k, None)
    one, t_one = run_grid(ws, feats, models, k, 1)
    two, t_two = run_grid(ws, feats, models, k, 2)
    same = np.array_equal(alone, one) and np.array_equal(alone, two)
    print(f"grid: {n} taps, {'+'.join(feats)} x {'+'.join(models)}, K {k}: {n_fits} fits")
    print(f"  one process        {t_alone:7.1f} s")
    print(f"  --workers 1        {t_one:7.1f} s (cluster start and stop included)")
    print(f"  --workers 2        {t_two:7.1f} s")
    print(
        f"  speed-up 2 workers: {t_one / t_two:.2f}x over 1 worker, {t_alone / t_two:.2f}x over "
        f"one process; identical scores: {same}"
    )
    # one point with more splits: how long each fit takes alone and two at a time
    k8 = 4 if args.quick else 8
    for workers in (None, 2):
        t0 = time.perf_counter()
        with fit_executor(workers=workers) as ex:
            res = evaluate(
                ws, features_for(ws, "fft"), "svm_rbf", k=k8, executor=ex, progress=False
            )
        where = "one process" if workers is None else f"--workers {workers}"
        print(
            f"  one point (fft + svm_rbf, K {k8}), {where}: {time.perf_counter() - t0:.1f} s; "
            f"per fit {res.train_s.min():.2f}-{res.train_s.max():.2f} s"
        )


if __name__ == "__main__":
    main()
