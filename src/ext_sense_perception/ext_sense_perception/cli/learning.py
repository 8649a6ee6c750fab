# ruff: noqa: N806  (X / F for sample matrices, as in scikit-learn)
"""``ext-sense features|train|evaluate|report``: learning from sessions of recordings.

Heavy imports (scikit-learn, ONNX Runtime, matplotlib) live inside the handlers so
``ext-sense --help`` stays fast.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from ext_sense_perception.cli.options import (
    add_cluster_options,
    add_data_options,
    cache_dir,
    fail,
    load_pooled,
    write_json,
)
from ext_sense_perception.errors import PerceptionError
from ext_sense_runtime.stamps import MS

if TYPE_CHECKING:  # the handlers import these lazily: ``ext-sense --help`` stays fast
    from ext_sense_perception.data.window_set import WindowSet
    from ext_sense_perception.online.model_input import Geometry
    from ext_sense_perception.training.recipe import Recipe


def _common(p: argparse.ArgumentParser) -> None:
    add_data_options(p)
    p.add_argument(
        "--features",
        default=None,
        help="baseline, fft, est, activity, autoencoder (default: the project's best)",
    )
    p.add_argument(
        "--model",
        default=None,
        help="svm_linear, svm_rbf, svm, mlp, gru, random_forest, taxel_svr (default: best)",
    )
    p.add_argument(
        "--channels", default=None, help="all, left, right, taxel:N or ids:a,b,c (default all)"
    )
    p.add_argument(
        "--bin-ms",
        type=float,
        default=None,
        help="NUSkin feature bin, ms (default: the task profile's, 5; handover 2; food 50)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``features``, ``train``, ``evaluate`` and ``report``."""
    p = subparsers.add_parser(
        "features", help="compute a feature set from a recording or dataset into an .npy"
    )
    _common(p)
    p.add_argument(
        "--essentials",
        default=None,
        help="the paper's essentials CSV (onsets and labels) for a raw recording",
    )
    p.add_argument(
        "--out",
        required=True,
        help="output .npy (features, (n_windows, n_features)); labels go to OUT.labels.npy",
    )
    p.set_defaults(func=_cmd_features)

    p = subparsers.add_parser(
        "train", help="train a deployable model bundle (model.onnx, model.joblib, model_card.json)"
    )
    _common(p)
    p.add_argument("--out", required=True, help="bundle directory")
    p.add_argument(
        "--anytime-ms",
        default=None,
        help="comma-separated shorter post-contact windows to train anytime models for, ms "
        "(default: the task profile's, 25,50,100,150 for tap and handover, none for food; "
        "'none' for none)",
    )
    p.add_argument(
        "--arrival-jitter",
        type=float,
        default=None,
        help="fraction of NUSkin training windows re-stamped with the live reader's measured "
        "arrival jitter, 0..1 (default: the task's, 0.5 for handover, 0 otherwise; "
        "docs/perception.md 'Arrival jitter')",
    )
    p.set_defaults(func=_cmd_train)

    p = subparsers.add_parser(
        "evaluate", help="the paper's protocol (K random 90/10 splits, 4-fold grid search)"
    )
    _common(p)
    p.add_argument(
        "--k", type=int, default=None, help="splits (default: 5 for tap and RNNs, else 20)"
    )
    p.add_argument(
        "--protocol",
        choices=("paper", "cross-session"),
        default="paper",
        help="paper: K random splits over the pooled windows (default); cross-session: leave "
        "one --data session out, scored on the classes the others know, decisions restricted to "
        "its label set",
    )
    p.add_argument(
        "--calibration-trials",
        default=None,
        help="cross-session: also the calibration curve, e.g. 0,1,2,3 trials per class of the "
        "held-out session added to training (see ext-sense calibrate)",
    )
    p.add_argument(
        "--draws", type=int, default=5, help="random draws of calibration trials (default 5)"
    )
    p.add_argument(
        "--weight",
        type=int,
        default=None,
        help="repeats of each calibration trial (default: ext-sense calibrate's)",
    )
    p.add_argument("--json", default=None, help="write the result as JSON here")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_cluster_options(p, default_cache="none")
    p.set_defaults(func=_cmd_evaluate)

    p = subparsers.add_parser(
        "report", help="paper-style tables (markdown) and plots (PNG) of accuracy against time"
    )
    p.add_argument(
        "--data", action="append", required=True, help="dataset (repeatable: one per task/rod)"
    )
    p.add_argument("--out", required=True, help="output directory (report.md and PNGs)")
    p.add_argument("--k", type=int, default=None, help="splits per point (default 3; quick)")
    p.add_argument("--quick", action="store_true", help="fewer points, for a smoke run")
    p.add_argument(
        "--full",
        action="store_true",
        help="the paper's tables in full: its K per point (5 for taps and the GRU, 20 "
        "otherwise), every feature set and model, the GRU row, every section",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--bin-ms",
        type=float,
        default=None,
        help="NUSkin FFT/baseline feature bin, ms (default: each task profile's)",
    )
    p.add_argument(
        "--features",
        default=None,
        help="comma-separated feature sets of the features x models tables, e.g. fft,baseline "
        "(default fft,baseline,est,autoencoder; quick fft,baseline)",
    )
    p.add_argument(
        "--models",
        default=None,
        help="comma-separated models of those tables, e.g. svm_linear,svm_rbf "
        "(default svm_linear,svm_rbf,mlp; quick svm_rbf)",
    )
    p.add_argument(
        "--no-gru", action="store_true", help="leave out the GRU row of NUSkin tap datasets"
    )
    p.add_argument(
        "--no-latency",
        action="store_true",
        help="leave out the decision-latency / anytime-calibration sections",
    )
    p.add_argument(
        "--no-taxels",
        action="store_true",
        help="leave out the two fingers / one finger / one taxel sections",
    )
    p.add_argument(
        "--jobs", type=int, default=1, help="parallel grid-search jobs per evaluation (default 1)"
    )
    p.add_argument(
        "--plan",
        action="store_true",
        help="fit and write nothing: print how many fits the report would run per data set, "
        "how many of them are in the cache and how many are to do",
    )
    p.add_argument(
        "--sim-commit",
        default=None,
        metavar="REV",
        help="the simulator commit the simulator data sets of this run were made with, "
        "recorded in their report.json rows and sections (a dataset.npz does not carry it)",
    )
    p.add_argument(
        "--update",
        action="store_true",
        help="keep the data sets of the report in OUT that this run does not evaluate; "
        "the ones it evaluates replace theirs",
    )
    add_cluster_options(p, default_cache="OUT/fits")
    p.set_defaults(func=_cmd_report)


def _recipe(args: argparse.Namespace, anytime_post_ns: tuple[int, ...] | None = None) -> Recipe:
    """The training recipe the options ask for (everything else the task's own)."""
    from ext_sense_perception.training.recipe import Recipe

    return Recipe(
        features=args.features,
        model=args.model,
        channels=args.channels,
        feature_bin_ns=round(args.bin_ms * MS) if args.bin_ms is not None else None,
        rate_hz=args.rate_hz,
        anytime_post_ns=anytime_post_ns,
        seed=args.seed,
        arrival_jitter=getattr(args, "arrival_jitter", None),  # a train option
    )


def _cmd_features(args: argparse.Namespace) -> int:
    import numpy as np

    from ext_sense_perception.training.protocol import features_for
    from ext_sense_perception.training.recipe import resolve

    try:
        ws = load_pooled(args, need_labels=False)
        features, _, params, _ = resolve(ws, _recipe(args))
        tf = features_for(ws, features, **params)
        X = ws.X.reshape(len(ws.X), -1)
        F = tf.fit(X).transform(X)
    except PerceptionError as err:
        return fail(err)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.save(out, F.astype(np.float32))
    np.save(out.with_suffix(".labels.npy"), ws.y)
    print(
        f"{out}: {F.shape[0]} windows x {F.shape[1]} {features} features ({ws.task}, {ws.sensor})"
    )
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
    from ext_sense_perception.online.model_card import read_card
    from ext_sense_perception.training.recipe import train_bundle

    try:
        ws = load_pooled(args)
        train_bundle(ws, args.out, _recipe(args, _anytime_posts(args.anytime_ms, ws)))
        card = read_card(args.out)  # as saved: with its anytime models' times
    except PerceptionError as err:
        return fail(err)
    if card.anytime_post_ms:
        print(f"anytime models for {list(card.anytime_post_ms)} ms post-contact")
    print(
        f"{args.out}: {card.id} trained on {card.n_train} windows in {card.train_s:.1f} s; "
        f"metrics {card.metrics}"
    )
    return 0


def _anytime_posts(text: str | None, ws: WindowSet) -> tuple[int, ...] | None:
    """``--anytime-ms``: None for the task profile's times, ``()`` for none.

    Each time must cut an anytime window out of the training windows: at least one sample after the
    onset and shorter than the windows' post-onset span (:func:`anytime_range_ns`), else a
    PerceptionError.
    """
    if text is None:
        return None
    if text.strip().lower() in ("", "none"):
        return ()
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as err:
        raise PerceptionError(
            f"The '--anytime-ms' option must list numbers. Got {text!r} instead."
        ) from err
    low, high = anytime_range_ns(ws.geometry)
    bad = [v for v in values if not (math.isfinite(v) and low <= v * MS < high)]
    if bad:
        period = ws.geometry.period_ns / MS
        raise PerceptionError(
            f"The '--anytime-ms' option must list times within the training windows' "
            f"post-onset span, each in [{low / MS:g}, {high / MS:g}) ms (at least one "
            f"{period:g} ms sample after the onset, shorter than the "
            f"{ws.geometry.post_ns / MS:g} ms windows). Got {text!r} instead."
        )
    return tuple(round(v * MS) for v in values)


def anytime_range_ns(geometry: Geometry) -> tuple[int, int]:
    """The anytime post-onset times windows of ``geometry`` can be cut at, ``[low, high)`` ns.

    A cut keeps whole samples: it must end at least one sample after the onset and before the
    window's own end (the full window is the final model).
    """
    first = max(1, geometry.pre_ns // geometry.period_ns + 1)  # samples up to the first end
    return first * geometry.period_ns - geometry.pre_ns, geometry.post_ns


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from ext_sense_perception.training.evaluation import evaluation_record
    from ext_sense_perception.training.fit_jobs import fit_runner
    from ext_sense_perception.training.recipe import resolve

    if args.protocol == "cross-session":
        from ext_sense_perception.cli.sessions import cross_session_command

        return cross_session_command(args, _recipe(args))
    try:
        ws = load_pooled(args)
        recipe = _recipe(args)
        features, model, params, grid = resolve(ws, recipe)
        cache = cache_dir(args.cache, None)
        distributed = args.workers or args.scheduler or cache is not None
        with fit_runner(
            args.scheduler, args.workers, cache, progress=not args.no_progress
        ) as executor:
            rec = evaluation_record(
                ws,
                features,
                model,
                params,
                grid,
                args.k,
                args.seed,
                not args.no_progress,
                args.rate_hz,
                executor=executor if distributed else None,
            )
    except PerceptionError as err:
        return fail(err)
    unit = "m" if rec["metric"] == "mae_m" else ""
    print(
        f"{rec['task']} {rec['sensor']} {features}+{model}: {rec['metric']} {rec['mean']:.4f} +- "
        f"{rec['std']:.4f} {unit}"
        f" (k={rec['k']}, {rec['n_windows']} windows"
        + (f", excluded {', '.join(rec['excluded'])}" if rec["excluded"] else "")
        + ")"
    )
    if rec["confusion"] is not None:
        print("confusion (rows true, columns predicted):", ", ".join(rec["class_names"]))
        for name, row in zip(rec["class_names"], rec["confusion"], strict=True):
            print(f"  {name:>12s} {row}")
    print(
        f"train {rec['train_s']:.2f} s/split; inference p50/p99 sklearn "
        f"{rec['infer_p50_ms_sklearn']:.3f}/"
        f"{rec['infer_p99_ms_sklearn']:.3f} ms, onnx "
        f"{rec['infer_p50_ms_onnx']:.3f}/{rec['infer_p99_ms_onnx']:.3f} ms;"
        f" decision latency {rec['decision_latency_ms']:.1f} ms"
    )
    write_json(args.json, rec)
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from ext_sense_perception.reporting.report import build_report
    from ext_sense_perception.training.fit_jobs import fit_runner

    def names(value: str | None) -> list[str] | None:
        return None if value is None else [v.strip() for v in value.split(",") if v.strip()]

    plan: list[dict] | None = [] if args.plan else None
    try:
        if args.jobs < 1:
            raise PerceptionError(f"The '--jobs' option must be >= 1. Got {args.jobs} instead.")
        params = {"bin_ns": round(args.bin_ms * MS)} if args.bin_ms else None
        cache = cache_dir(args.cache, Path(args.out) / "fits")
        where = (None, None) if args.plan else (args.scheduler, args.workers)
        with fit_runner(*where, cache, progress=not args.plan) as executor:
            path = build_report(
                [Path(d) for d in args.data],
                Path(args.out),
                k=args.k,
                quick=args.quick,
                seed=args.seed,
                base_params=params,
                gru=False if args.no_gru else None,
                features=names(args.features),
                models=names(args.models),
                n_jobs=args.jobs,
                latency=not args.no_latency,
                taxels=not args.no_taxels,
                executor=executor,
                full=args.full,
                plan=plan,
                sim_commit=args.sim_commit,
                update=args.update,
            )
    except PerceptionError as err:
        return fail(err)
    if plan is not None:
        _print_plan(plan, cache)
    else:
        print(f"report written to {path}")
    return 0


def _print_plan(plan: list[dict], cache: Path | None) -> None:
    """``report --plan``: one line per data set and the total."""
    from collections import Counter

    def to_do(n: int, by_model: dict[str, int]) -> str:
        models = ", ".join(f"{m} {k}" for m, k in by_model.items())
        return f"{n} to do: {models}" if n else "nothing to do"

    total: Counter = Counter()
    by_model: Counter = Counter()
    for row in plan:
        print(
            f"{row['data']}: {row['points']} points, {row['fits']} fits ({row['cached']} "
            f"cached, {to_do(row['to_do'], row['to_do_by_model'])}); "
            f"{row['final_fits']} deployed-model fits for latency (after these, cached too)"
        )
        total.update({k: row[k] for k in ("points", "fits", "cached", "to_do", "final_fits")})
        by_model.update(row["to_do_by_model"])
    print(
        f"total: {total['points']} points, {total['fits']} fits ({total['cached']} cached in "
        f"{cache or 'no cache'}, {to_do(total['to_do'], dict(sorted(by_model.items())))}); "
        f"{total['final_fits']} deployed-model fits for latency (after these, cached too)"
    )
