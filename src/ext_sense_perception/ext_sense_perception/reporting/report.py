"""``ext-sense report``: paper-style tables (markdown) and plots (PNG) of accuracy against time.

Per data set: models, decision latency, inference latency, sampling rate, fingers and taxels,
anytime calibration; across tap data sets, rod length. ``report.md`` is rewritten after every
data set.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from ext_sense_perception.data.sources import from_sim_dataset, load_window_set
from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.reporting.document import (
    SIM_COMMIT,
    ReportParts,
    provenance,
    read_report,
    source_lines,
    write_report,
)
from ext_sense_perception.reporting.plots import plot
from ext_sense_perception.reporting.runner import Runner, Study, check_choices
from ext_sense_perception.reporting.scores import fmt, pareto_front, score, spread
from ext_sense_perception.reporting.sections import (
    dataset_name,
    gru_row,
    latency_section,
    taxel_section,
)
from ext_sense_perception.training.fit_jobs import FitRunner
from ext_sense_perception.training.gru import torch_available
from ext_sense_perception.training.models import default_choice
from ext_sense_runtime.stamps import MS

NUSKIN_RATES_HZ = (50, 100, 250, 500, 1000, 2000, 3000, 4000)
NUSKIN_QUICK_RATES_HZ = (50, 250, 1000, 4000)
BIOTAC_RATES_HZ = (100, 250, 500, 1000, 2200)
REPORT_FEATURES = ("fft", "baseline", "est", "autoencoder")
REPORT_MODELS = ("svm_linear", "svm_rbf", "mlp")
QUICK_FEATURES = ("fft", "baseline")
QUICK_MODELS = ("svm_rbf",)


def report_dataset(
    ws: WindowSet,
    path: Path,
    out: Path,
    run: Runner,
    quick: bool,
    gru: bool | None = None,
    gru_params: dict[str, Any] | None = None,
    features: tuple[str, ...] | None = None,
    models: tuple[str, ...] | None = None,
    latency: bool = True,
    taxels: bool = True,
) -> list[str]:
    """Markdown lines (and PNGs in ``out``) for one window set.

    ``gru=False`` leaves out the GRU row, ``gru_params`` fixes its parameters; ``features`` /
    ``models`` replace the table's defaults (NUSkin food always starts with ``activity``);
    ``latency`` / ``taxels`` False leave those sections out.
    """
    name = dataset_name(ws, path)
    lower = ws.is_regression
    feat0, model0 = default_choice(ws.task, ws.sensor)
    lines = [f"## {ws.task}, {ws.sensor} ({len(ws.y)} windows; `{path}`)", ""]
    if ws.excluded:
        lines += [f"Excluded: {', '.join(ws.excluded)} (single trial of its class).", ""]

    # features x models
    feats = list(features or (QUICK_FEATURES if quick else REPORT_FEATURES))
    if ws.sensor == "nuskin" and ws.task == "food_identification" and "activity" not in feats:
        feats = ["activity", *feats]
    mods = list(models or (QUICK_MODELS if quick else REPORT_MODELS))
    lines += [
        f"### Features and models (K = {run.k_text} random 90/10 splits, 4-fold grid search)",
        "",
        "| features | model | score | train s/split | ONNX p50 / p99 ms | decision latency ms |",
        "|---|---|---|---|---|---|",
    ]
    inf_x, inf_y, inf_lab, inf_err, dec_x = [], [], [], [], []
    post_ms = ws.geometry.post_ns / MS

    def model_row(f: str, m: str, model_params: dict[str, Any] | None = None) -> None:
        try:
            res = run(ws, name, f, m, model_params=model_params)
            p50, p99 = run.infer_ms(ws, f, m, res, model_params)
        except PerceptionError as err:
            lines.append(f"| {f} | {m} | failed: {err} | | | |")
            return
        lines.append(
            f"| {f} | {m} | {fmt(res)} | {np.mean(res.train_s):.2f} | {p50:.3f} / {p99:.3f} "
            f"| {post_ms + p99:.1f} |"
        )
        run.row(res, Study.MODELS)
        inf_x.append(p50)
        inf_y.append(score(res))
        inf_err.append(spread(res))
        inf_lab.append(f"{f}+{m}")
        dec_x.append(post_ms + p99)

    for f in feats:
        for m in mods:
            model_row(f, m)
    if gru_row(ws, gru):
        # the paper's best NUSkin tap model: GRU (16) + MLP on the binned counts
        if not torch_available():
            lines.append(
                "| baseline | gru | skipped: torch (optional extra, requirements/train.txt) is "
                "not installed | | | |"
            )
        else:
            model_row("baseline", "gru", gru_params)
    if inf_x:
        png = out / f"{name}_vs_inference.png"
        plot(
            png,
            inf_x,
            inf_y,
            "ONNX inference p50 (ms)",
            "MAE (cm)" if lower else "accuracy",
            f"{ws.task} {ws.sensor}: score vs inference latency",
            logx=False,
            labels=inf_lab,
            pareto_lower=lower,
            yerr=inf_err,
        )
        lines += ["", f"![score vs inference latency]({png.name})", ""]
        for axis, xs in (("inference latency", inf_x), ("decision latency", dec_x)):
            front = [inf_lab[i] for i in pareto_front(xs, inf_y, lower)]
            lines += [f"Pareto front against {axis} (fastest first): {', '.join(front)}.", ""]

    g = ws.geometry
    if latency:
        lines += latency_section(ws, run, name, out, feat0, model0)

    # sampling rate
    rx, ry, rerr = [], [], []
    rows = []
    rates: Iterable[tuple[int, WindowSet, dict[str, float]]] = ()
    if ws.sensor == "nuskin" and Path(str(path)).suffix == ".npz":
        rates = (  # each rate's windows thinned from the events, loaded in turn
            (r, from_sim_dataset(path, rate_hz=r), {})
            for r in (NUSKIN_QUICK_RATES_HZ if quick else NUSKIN_RATES_HZ)
        )
    elif ws.sensor == "biotac":
        rates = ((r, ws, {"rate_hz": float(r)}) for r in BIOTAC_RATES_HZ)
    for r, rate_ws, rate_params in rates:
        res = run(rate_ws, name, feat0, model0, **rate_params)
        run.row(res, Study.SAMPLING_RATE, rate_hz=float(r))
        rows.append(f"| {r} | {fmt(res)} |")
        rx.append(r)
        ry.append(score(res))
        rerr.append(spread(res))
    if rows:
        png = out / f"{name}_vs_rate.png"
        plot(
            png,
            rx,
            ry,
            "sampling rate (Hz)",
            "MAE (cm)" if lower else "accuracy",
            f"{ws.task} {ws.sensor}: score vs sampling rate",
            logx=True,
            yerr=rerr,
        )
        lines += [
            f"### Sampling rate ({feat0} + {model0}; NUSkin: per-taxel refractory drop; "
            "BioTac: decimation)",
            "",
            "| rate Hz | score |",
            "|---|---|",
            *rows,
            "",
            f"![score vs sampling rate]({png.name})",
            "",
        ]

    # fingers and taxels
    if taxels and ws.sensor == "nuskin" and g.n_channels == 80:
        lines += taxel_section(ws, run, name, feat0, model0, 2 if quick else 4)
    return lines


def build_report(
    datasets: list[Path],
    out: Path,
    k: int | None = None,
    quick: bool = False,
    seed: int = 0,
    base_params: dict[str, Any] | None = None,
    gru: bool | None = None,
    gru_params: dict[str, Any] | None = None,
    features: list[str] | tuple[str, ...] | None = None,
    models: list[str] | tuple[str, ...] | None = None,
    n_jobs: int = 1,
    latency: bool = True,
    taxels: bool = True,
    executor: FitRunner | None = None,
    full: bool = False,
    plan: list[dict[str, Any]] | None = None,
    sim_commit: str | None = None,
    update: bool = False,
) -> Path:
    """Evaluate every dataset and write ``out/report.md``, PNGs and ``out/report.json``.

    ``k`` defaults to 3 (2 with ``quick``, which also takes fewer features, models, rates and
    taxels); ``full`` gives the paper's tables in full (its K per point unless ``k`` is given, every
    section). ``base_params`` go to every NUSkin evaluation, ``gru_params`` fix the GRU row's
    estimator, ``features`` / ``models`` the tables' columns. With ``plan`` (a list) nothing is
    fitted or written: each data set's :meth:`Runner.listed` counts are appended to it.
    ``sim_commit`` is recorded in the simulator data sets' rows; ``update`` keeps the former
    report's data sets this run does not evaluate. PerceptionError: an unknown feature set or model
    (before anything runs), unreadable data, or (``update``) an unreadable former report.
    """
    features, models = check_choices(features, models)
    if full:
        if quick or not (latency and taxels) or gru is False:
            raise PerceptionError(
                "The '--full' report has every section: leave out --quick, --no-latency, "
                "--no-taxels and --no-gru."
            )
    else:
        k = k or (2 if quick else 3)
    if sim_commit is not None and not SIM_COMMIT.fullmatch(sim_commit):
        raise PerceptionError(
            "The 'sim_commit' parameter must be a commit name (letters, digits, '.', '_', '+', "
            f"'-'; 4 to 64 characters). Got {sim_commit!r} instead."
        )
    former = read_report(out) if update else ReportParts({}, [])
    if plan is None:
        out.mkdir(parents=True, exist_ok=True)
    records: list[dict[str, Any]] = []
    run = Runner(k, seed, records, base_params, n_jobs, executor)
    parts = ReportParts(dict(former.sections), list(former.records))

    def sections(ws: WindowSet, path: Path, where: Path) -> list[str]:
        """The data set's lines; its default point for the rod-length table is asked for too."""
        found = report_dataset(
            ws, path, where, run, quick, gru, gru_params, features, models, latency, taxels
        )
        if ws.task == "tap_localization" and np.isfinite(ws.rod_length_m).any():
            feat0, model0 = default_choice(ws.task, ws.sensor)
            res = run(ws, dataset_name(ws, path), feat0, model0)  # memoised above
            run.row(res, Study.ROD_LENGTH)
        return found

    names: dict[str, Path] = {}
    with threadpool_limits(limits=1):
        for done, path in enumerate(datasets, start=1):
            ws = load_window_set(path)
            name = dataset_name(ws, path)
            if name in names:
                raise PerceptionError(
                    f"The data sets {str(names[name])!r} and {str(path)!r} share the report name "
                    f"{name!r} (task, sensor, folder): their sections and plots would overwrite "
                    "each other. Give each its own folder."
                )
            names[name] = path
            rod = ws.rod_length_m[np.isfinite(ws.rod_length_m)]
            run.provenance = {
                "task": ws.task,
                "sensor": ws.sensor,
                **provenance(path, sim_commit),
                "rod_m": round(float(np.median(rod)), 4) if rod.size else None,
            }
            with tempfile.TemporaryDirectory(prefix="ext_sense_plan_") as scratch, run.plan():
                sections(ws, path, Path(scratch))  # lists every point of the data set
            if plan is not None:
                plan.append({"data": str(path), **run.listed()})
                run.discard()
                continue
            run.flush()  # every split fit of the data set, submitted together
            with tempfile.TemporaryDirectory(prefix="ext_sense_plan_") as scratch:
                with run.plan_deployed():
                    sections(ws, path, Path(scratch))  # lists the deployed models
                run.flush_deployed()  # their fits, submitted together, then their timing
            first = len(records)
            lines = sections(ws, path, out)
            parts.sections[name] = [*lines[:2], *source_lines(run.provenance), *lines[2:]]
            parts.records[:] = [r for r in parts.records if r.get("dataset") != name]
            parts.records.extend(records[first:])
            if done < len(datasets):  # a long run keeps what it has so far
                write_report(out, parts, f"(In progress: {done} of {len(datasets)} data sets.)")
    if plan is not None:
        return out / "report.md"
    return write_report(out, parts)
