"""``ext-sense report``: paper-style tables (markdown) and plots (PNG) of accuracy against time.

Per dataset (task): a features x models table (score, training time, ONNX inference time;
NUSkin taps add the GRU (16) + MLP on binned counts when torch is installed),
the score against the post-contact window (decision latency 25 to 250 ms), against inference
latency, against sampling rate, one finger / one taxel against two fingers, and the anytime
estimator's calibration (95% prediction-interval coverage for position; expected calibration
error and Brier score of the class probabilities). Across tap datasets: rod length.

Everything is measured with :func:`ext_sense_perception.protocol.evaluate` (K splits, default 3
for speed; the paper's K is given in the table's header when used).
"""

from __future__ import annotations

import itertools
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from ext_sense_perception.dataset import WindowSet, from_sim_dataset, load_window_set
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.models import default_choice, default_feature_grid
from ext_sense_perception.protocol import EvalResult, evaluate, features_for

MS = 1_000_000
POSTS_MS = (25, 50, 100, 150, 250)
NUSKIN_RATES_HZ = (50, 100, 250, 500, 1000, 2000, 4000)
BIOTAC_RATES_HZ = (100, 250, 500, 1000, 2200)


def _fmt(res: EvalResult) -> str:
    if res.metric == "mae_m":
        return f"{res.mean * 100:.2f} +- {res.std * 100:.2f} cm"
    return f"{res.mean:.3f} +- {res.std:.3f}"


def _score(res: EvalResult) -> float:
    return res.mean * 100 if res.metric == "mae_m" else res.mean


def _metric_label(res: EvalResult) -> str:
    return "MAE (cm, lower is better)" if res.metric == "mae_m" else "accuracy"


def _infer_ms(
    ws: WindowSet,
    features: str,
    model: str,
    params: dict[str, Any],
    grid: dict,
    model_params: dict[str, Any] | None = None,
) -> tuple[float, float]:
    """ONNX single-window p50 and p99 latency of a model trained on everything, ms."""
    from ext_sense_perception import bundle
    from ext_sense_perception.cli import measure_inference

    trained = bundle.train(ws, features, model, params, grid, model_params=model_params)
    t = measure_inference(trained, ws, n=100)
    return t["infer_p50_ms_onnx"], t["infer_p99_ms_onnx"]


def _coverage(res: EvalResult) -> float:
    """Fraction of test positions inside the 95% prediction interval (+-1.96 sigma)."""
    return float(np.mean(np.abs(res.y_true - res.y_pred) <= 1.959964 * res.y_std))


def _ece(res: EvalResult, bins: int = 5) -> tuple[float, float]:
    """Expected calibration error of the top-class probability, and the Brier score."""
    if res.proba is None:
        return float("nan"), float("nan")
    conf = res.proba.max(axis=1)
    pred = np.asarray(res.class_names)[res.proba.argmax(axis=1)]
    correct = pred == res.y_true
    edges = np.linspace(0, 1, bins + 1)
    ece = 0.0
    for lo, hi in itertools.pairwise(edges):
        m = (conf > lo) & (conf <= hi)
        if m.any():
            ece += m.mean() * abs(correct[m].mean() - conf[m].mean())
    onehot = (np.asarray(res.class_names)[None, :] == res.y_true[:, None]).astype(float)
    brier = float(np.mean(np.sum((res.proba - onehot) ** 2, axis=1)))
    return float(ece), brier


def _plot(
    path: Path,
    xs: list[float],
    ys: list[float],
    xlabel: str,
    ylabel: str,
    title: str,
    logx: bool = False,
    labels: list[str] | None = None,
    pareto_lower: bool | None = None,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.4), dpi=110)
    order = np.argsort(xs)
    ax.plot(
        np.asarray(xs)[order], np.asarray(ys)[order], "o-" if labels is None else "o", color="C0"
    )
    if labels is not None:
        for x, y, s in zip(xs, ys, labels, strict=True):
            ax.annotate(s, (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    if pareto_lower is not None:
        front, best = [], None
        for i in order:
            y = ys[i]
            if best is None or (y < best if pareto_lower else y > best):
                best = y
                front.append(i)
        ax.plot(
            np.asarray(xs)[front],
            np.asarray(ys)[front],
            "-",
            color="C3",
            lw=1,
            label="Pareto front",
        )
        ax.legend(fontsize=7)
    if logx:
        from matplotlib.ticker import NullFormatter, ScalarFormatter

        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def gru_row(ws: WindowSet, gru: bool | None = None) -> bool:
    """Whether the features x models table gets the GRU (baseline features) row.

    NUSkin tap localisation (the paper's best NUSkin tap model is the RNN on binned counts),
    unless ``gru`` is False; the row says "skipped" when torch is not installed. BioTac is left
    out: its raw PAC gives 660-step sequences, about 10x the training time.
    """
    return gru is not False and ws.task == "tap_localization" and ws.sensor == "nuskin"


def report_dataset(
    ws: WindowSet,
    path: Path,
    out: Path,
    k: int,
    quick: bool,
    seed: int,
    records: list[dict[str, Any]],
    base_params: dict[str, Any] | None = None,
    gru: bool | None = None,
    gru_params: dict[str, Any] | None = None,
) -> list[str]:
    """Markdown lines (and PNGs in ``out``) for one window set.

    ``base_params`` (e.g. ``{"bin_ns": 2_000_000}``) apply to every NUSkin evaluation;
    ``gru=False`` leaves out the GRU row (see :func:`gru_row`); ``gru_params`` are fixed
    :class:`~ext_sense_perception.gru.GRUEstimator` parameters (e.g. fewer epochs for a smoke run).
    """
    src = Path(str(path))
    name = f"{ws.task}_{ws.sensor}_{src.parent.name if src.is_file() else src.name}"
    lower = ws.is_regression
    feat0, model0 = default_choice(ws.task, ws.sensor)
    default_feature_grid(ws.task, ws.sensor, feat0)
    lines = [f"## {ws.task}, {ws.sensor} ({len(ws.y)} windows; `{path}`)", ""]
    if ws.excluded:
        lines += [f"Excluded: {', '.join(ws.excluded)} (single trial of its class).", ""]

    def run(
        wset: WindowSet,
        features: str,
        model: str,
        model_params: dict[str, Any] | None = None,
        **params: Any,
    ) -> EvalResult:
        if wset.sensor == "nuskin" and features in ("baseline", "fft", "autoencoder"):
            params = {**(base_params or {}), **params}
        grid = default_feature_grid(wset.task, wset.sensor, features)
        t0 = time.perf_counter()
        res = evaluate(
            wset,
            features_for(wset, features, **params),
            model,
            k=k,
            seed=seed,
            progress=False,
            feature_grid=grid,
            model_params=model_params,
        )
        records.append(
            {
                "dataset": name,
                "features": features,
                "model": model,
                "params": params,
                "post_ms": res.post_ns / MS,
                "metric": res.metric,
                "mean": res.mean,
                "std": res.std,
                "k": res.k,
                "eval_s": time.perf_counter() - t0,
            }
        )
        return res

    # features x models
    feats = ["fft", "baseline"] if quick else ["fft", "baseline", "est", "autoencoder"]
    if ws.sensor == "nuskin" and ws.task == "food_identification":
        feats = ["activity", *feats]
    models = ["svm_rbf"] if quick else ["svm_linear", "svm_rbf", "mlp"]
    lines += [
        f"### Features and models (K = {k} random 90/10 splits, 4-fold grid search)",
        "",
        "| features | model | score | train s/split | ONNX p50 / p99 ms |",
        "|---|---|---|---|---|",
    ]
    inf_x, inf_y, inf_lab = [], [], []
    for f in feats:
        for m in models:
            try:
                res = run(ws, f, m)
                p50, p99 = _infer_ms(ws, f, m, {}, default_feature_grid(ws.task, ws.sensor, f))
            except PerceptionError as err:
                lines.append(f"| {f} | {m} | failed: {err} | | |")
                continue
            lines.append(
                f"| {f} | {m} | {_fmt(res)} | {np.mean(res.train_s):.2f} | {p50:.3f} / {p99:.3f} |"
            )
            inf_x.append(p50)
            inf_y.append(_score(res))
            inf_lab.append(f"{f}+{m}")
    if gru_row(ws, gru):
        # the paper's best NUSkin tap model: GRU (16) + MLP on the binned counts
        from ext_sense_perception.gru import torch_available

        if not torch_available():
            lines.append(
                "| baseline | gru | skipped: torch (optional extra, requirements/train.txt) is "
                "not installed | | |"
            )
        else:
            try:
                res = run(ws, "baseline", "gru", model_params=gru_params)
                p50, p99 = _infer_ms(ws, "baseline", "gru", {}, {}, gru_params)
            except PerceptionError as err:
                lines.append(f"| baseline | gru | failed: {err} | | |")
            else:
                lines.append(
                    f"| baseline | gru | {_fmt(res)} | {np.mean(res.train_s):.2f} "
                    f"| {p50:.3f} / {p99:.3f} |"
                )
                inf_x.append(p50)
                inf_y.append(_score(res))
                inf_lab.append("baseline+gru")
    if inf_x:
        png = out / f"{name}_vs_inference.png"
        _plot(
            png,
            inf_x,
            inf_y,
            "ONNX inference p50 (ms)",
            "MAE (cm)" if lower else "accuracy",
            f"{ws.task} {ws.sensor}: score vs inference latency",
            logx=False,
            labels=inf_lab,
            pareto_lower=lower,
        )
        lines += ["", f"![score vs inference latency]({png.name})", ""]

    # decision latency and anytime calibration
    g = ws.geometry
    full_post = g.n_samples * g.period_ns - g.pre_ns
    posts = (
        [p * MS for p in POSTS_MS]
        if ws.task != "food_identification"
        else [1000 * MS, 2000 * MS, full_post]
    )
    posts = [p for p in posts if p <= full_post]
    lines += [
        f"### Decision latency ({feat0} + {model0}); anytime calibration",
        "",
        "| post-contact window ms | score | "
        + ("95% PI coverage | PI half-width cm |" if lower else "ECE | Brier |"),
        "|---|---|---|---|",
    ]
    dx, dy = [], []
    for p in posts:
        res = run(ws.crop(p), feat0, model0)
        if lower:
            cal = f"{_coverage(res):.2f} | {1.959964 * float(np.mean(res.y_std)) * 100:.2f}"
        else:
            ece, brier = _ece(res)
            cal = f"{ece:.3f} | {brier:.3f}"
        lines.append(f"| {p / MS:g} | {_fmt(res)} | {cal} |")
        dx.append(p / MS)
        dy.append(_score(res))
    png = out / f"{name}_vs_decision_latency.png"
    _plot(
        png,
        dx,
        dy,
        "post-contact window = decision latency floor (ms)",
        "MAE (cm)" if lower else "accuracy",
        f"{ws.task} {ws.sensor}: score vs decision latency",
        pareto_lower=lower,
    )
    lines += ["", f"![score vs decision latency]({png.name})", ""]

    # sampling rate
    rx, ry = [], []
    rows = []
    if ws.sensor == "nuskin" and Path(str(path)).suffix == ".npz":
        for r in NUSKIN_RATES_HZ[::2] if quick else NUSKIN_RATES_HZ:
            res = run(from_sim_dataset(path, rate_hz=r), feat0, model0)
            rows.append(f"| {r} | {_fmt(res)} |")
            rx.append(r)
            ry.append(_score(res))
    elif ws.sensor == "biotac":
        for r in BIOTAC_RATES_HZ:
            res = run(ws, feat0, model0, rate_hz=float(r))
            rows.append(f"| {r} | {_fmt(res)} |")
            rx.append(r)
            ry.append(_score(res))
    if rows:
        png = out / f"{name}_vs_rate.png"
        _plot(
            png,
            rx,
            ry,
            "sampling rate (Hz)",
            "MAE (cm)" if lower else "accuracy",
            f"{ws.task} {ws.sensor}: score vs sampling rate",
            logx=True,
        )
        lines += [
            "### Sampling rate (NUSkin: per-taxel refractory drop; BioTac: decimation)",
            "",
            "| rate Hz | score |",
            "|---|---|",
            *rows,
            "",
            f"![score vs sampling rate]({png.name})",
            "",
        ]

    # fingers and taxels
    if ws.sensor == "nuskin" and g.n_channels == 80:
        activity = np.abs(ws.X).sum(axis=(0, 2))
        top = np.argsort(activity)[::-1][: (2 if quick else 4)] + 1
        lines += ["### Two fingers, one finger, one taxel", "", "| taxels | score |", "|---|---|"]
        for sel, label in [
            (None, "both fingers (80)"),
            ("left", "one finger (1-40)"),
            ("right", "one finger (41-80)"),
        ]:
            res = run(ws, feat0, model0, channels=sel)
            lines.append(f"| {label} | {_fmt(res)} |")
        best = None
        for t in top:
            res = run(ws, feat0, model0, channels=f"taxel:{t}")
            if best is None or (res.mean < best[1].mean if lower else res.mean > best[1].mean):
                best = (t, res)
        if best is not None:
            lines.append(
                f"| best single taxel of the {len(top)} most active (taxel {best[0]}) "
                f"| {_fmt(best[1])} |"
            )
        lines.append("")
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
) -> Path:
    """Evaluate every dataset and write ``out/report.md``, PNGs and ``out/report.json``.

    Args:
        datasets: Simulator datasets or a food-poking capture directory.
        out: Output directory.
        k: Random splits per point (default 3, or 2 with ``quick``).
        quick: Fewer features, models, rates and taxels.
        seed: Seed.
        base_params: Feature parameters for every NUSkin evaluation (e.g. ``bin_ns``).
        gru: False leaves out the GRU row of NUSkin tap datasets (default: included, or
            marked skipped when torch is missing).
        gru_params: Fixed GRU parameters (e.g. ``{"max_epochs": 5}`` for a smoke run).

    Returns:
        The markdown file.
    """
    from threadpoolctl import threadpool_limits

    k = k or (2 if quick else 3)
    out.mkdir(parents=True, exist_ok=True)
    lines = [
        "# ext_sense perception report",
        "",
        "Generated by `ext-sense report`. Scores are mean +- std over the K random 90/10 splits of "
        "the paper's protocol (MAE in cm for tap localisation, accuracy otherwise).",
        "",
    ]
    records: list[dict[str, Any]] = []
    rods: list[tuple[float, EvalResult]] = []
    with threadpool_limits(limits=1):
        for path in datasets:
            ws = load_window_set(path)
            lines += report_dataset(
                ws, path, out, k, quick, seed, records, base_params, gru, gru_params
            )
            if ws.task == "tap_localization" and np.isfinite(ws.rod_length_m).any():
                feat0, model0 = default_choice(ws.task, ws.sensor)
                params = base_params if ws.sensor == "nuskin" else None
                res = evaluate(
                    ws,
                    features_for(ws, feat0, **(params or {})),
                    model0,
                    k=k,
                    seed=seed,
                    progress=False,
                )
                rods.append((float(np.nanmedian(ws.rod_length_m)), res))
    if len(rods) > 1:
        lines += [
            "## Rod length (tap localisation, default model)",
            "",
            "| rod m | MAE | MAE / length |",
            "|---|---|---|",
        ]
        for length, res in sorted(rods, key=lambda r: r[0]):
            lines.append(f"| {length:.2f} | {_fmt(res)} | {res.mean / length:.3f} |")
        lines.append("")
    md = out / "report.md"
    md.write_text("\n".join(lines) + "\n")
    (out / "report.json").write_text(json.dumps(records, indent=2, default=str) + "\n")
    return md
