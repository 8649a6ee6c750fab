"""Sweep benchmark: the same small grid of protocol fits in one process and on local Dask clusters.

Wall time of one grid (feature sets x models x K splits on synthetic taps) here and with
``--workers 2`` (cluster start and stop included), the speed-up, that the scores are identical,
and point by point with 2 workers (what submitting together gains). No cache; the load average
is printed.

    python bench/bench_sweep.py          # 300 taps, fft, baseline, est x svm_linear, svm_rbf, K 4
    python bench/bench_sweep.py --quick  # 120 taps, fft x svm_rbf + svm_linear, K 2
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from common import synthetic_taps

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.training.fit_jobs import fit_runner
from ext_sense_perception.training.protocol import (
    assemble,
    evaluate,
    features_for,
    plan_evaluation,
)


def run_grid(
    ws: WindowSet,
    features: list[str],
    models: list[str],
    k: int,
    workers: int | None,
    together: bool = True,
) -> tuple[np.ndarray, float]:
    """Scores of every (features, model) point and the wall time, s.

    ``together``: every point's fits in one submission (``Runner.flush``, as the report does);
    else one point after the other (``evaluate``).
    """
    t0 = time.perf_counter()
    points = [(f, m) for f in features for m in models]
    with fit_runner(workers=workers) as ex:
        if together:
            plans = [plan_evaluation(ws, features_for(ws, f), m, k=k) for f, m in points]
            outcomes = ex.run_jobs([p.job() for p in plans])
            scores = [assemble(p, r).scores for p, r in zip(plans, outcomes, strict=True)]
        else:
            scores = [
                evaluate(ws, features_for(ws, f), m, k=k, executor=ex, progress=False).scores
                for f, m in points
            ]
    return np.concatenate(scores), time.perf_counter() - t0


def load() -> str:
    """The 1-minute load average and the core count."""
    return f"load {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    n, feats, models, k = (
        (120, ["fft"], ["svm_rbf", "svm_linear"], 2)
        if args.quick
        else (300, ["fft", "baseline", "est"], ["svm_linear", "svm_rbf"], 4)
    )
    ws = synthetic_taps(n)
    n_fits = len(feats) * len(models) * k
    print(f"before: {load()}")
    alone, t_alone = run_grid(ws, feats, models, k, None)
    two, t_two = run_grid(ws, feats, models, k, 2)
    by_point, t_by_point = run_grid(ws, feats, models, k, 2, together=False)
    same = all(np.array_equal(alone, s) for s in (two, by_point))
    print(f"grid: {n} taps, {'+'.join(feats)} x {'+'.join(models)}, K {k}: {n_fits} fits")
    print(f"  one process                     {t_alone:7.1f} s")
    print(
        f"  --workers 2                     {t_two:7.1f} s (cluster start and stop included, "
        "every point's fits submitted together)"
    )
    print(f"  --workers 2, point by point     {t_by_point:7.1f} s (the former submission)")
    print(
        f"  speed-up of 2 workers: {t_alone / t_two:.2f}x over one process, "
        f"{t_by_point / t_two:.2f}x over point by point; identical scores: {same}"
    )
    # one point with more splits: how long each fit takes alone and two at a time
    k8 = 4 if args.quick else 8
    for workers in (None, 2):
        t0 = time.perf_counter()
        with fit_runner(workers=workers) as ex:
            res = evaluate(
                ws, features_for(ws, "fft"), "svm_rbf", k=k8, executor=ex, progress=False
            )
        where = "one process" if workers is None else f"--workers {workers}"
        print(
            f"  one point (fft + svm_rbf, K {k8}), {where}: {time.perf_counter() - t0:.1f} s; "
            f"per fit {res.train_s.min():.2f}-{res.train_s.max():.2f} s"
        )
    print(f"after: {load()}")


if __name__ == "__main__":
    main()
