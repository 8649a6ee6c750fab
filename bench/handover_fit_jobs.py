"""How long the NUSkin handover model of ``ext-sense models create`` takes to fit, by part and
by grid-search jobs, in one run (docs/runtime.md, the ``models create`` table)::

    python bench/handover_fit_jobs.py --trials 400 --jobs 1,2

Cuts the training stream as ``models create`` does (``commands.models.late_read_set``) once
per job count (its ideal and late-read cuts in that many processes, the same windows), then
fits the recipe's choice with ``fit_model`` and ``fit_anytime`` once per job count, printing
each part's wall time beside the CV accuracy and the chosen parameters (equal for every job
count: the grid search's folds do not depend on it).
"""

from __future__ import annotations

import argparse
import time


def main() -> None:
    from ext_sense.commands.models import TRIALS, late_read_set
    from ext_sense.graphs import DEFAULT_SCENES
    from ext_sense_perception.training.fit import fit_anytime, fit_model
    from ext_sense_perception.training.recipe import Recipe, resolve

    key = ("handover_stability", "nuskin")
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=TRIALS[key])
    parser.add_argument("--jobs", default="1,2", help="job counts, comma separated")
    args = parser.parse_args()

    job_counts = [int(j) for j in args.jobs.split(",")]
    for jobs in job_counts:
        t0 = time.perf_counter()
        ws = late_read_set(DEFAULT_SCENES[key], key[0], args.trials, n_jobs=jobs)
        print(
            f"{jobs} job(s): cut {time.perf_counter() - t0:.1f} s, {len(ws.y)} windows", flush=True
        )
    choice = resolve(ws, Recipe(arrival_jitter=0.0))
    posts = ws.task_profile.anytime_post_ns
    for jobs in job_counts:
        kwargs = {
            "feature_params": choice.feature_params,
            "feature_grid": choice.feature_grid,
            "seed": 0,
            "n_jobs": jobs,
        }
        t0 = time.perf_counter()
        model = fit_model(ws, choice.features, choice.model, **kwargs)
        t1 = time.perf_counter()
        anytime = fit_anytime(ws, choice.features, choice.model, posts, **kwargs)
        t2 = time.perf_counter()
        print(
            f"{jobs} job(s): model {t1 - t0:.1f} s, {len(anytime)} anytime models {t2 - t1:.1f} s;"
            f" {model.card.metrics} {model.card.best_params}",
            flush=True,
        )


if __name__ == "__main__":
    main()
