"""``ext-sense report``: paper-style tables (markdown) and plots (PNG) of accuracy against time.

Per dataset (task): a features x models table (score, training time, ONNX inference time;
NUSkin taps add the GRU (16) + MLP on binned counts when torch is installed),
the score against the post-contact window (decision latency 25 to 250 ms), against inference
latency, against sampling rate, one finger / one taxel against two fingers (default model and
the linear SVM side by side; the single taxel chosen on each split's training part), and the
anytime estimator's calibration (95% prediction-interval coverage for position; expected
calibration error and Brier score of the class probabilities). Across tap datasets: rod length.

Everything is measured with :func:`ext_sense_perception.protocol.evaluate` (K splits, default 3
for speed; the paper's K is given in the table's header when used). A point shared by several
sections is evaluated once; ``report.md`` is rewritten after every data set, so a long run
keeps what it has.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from ext_sense_perception.dataset import WindowSet, from_sim_dataset, load_window_set
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.models import default_choice
from ext_sense_perception.protocol import EvalResult, evaluate, features_for

MS = 1_000_000
POSTS_MS = (25, 50, 100, 150, 250)
NUSKIN_RATES_HZ = (50, 100, 250, 500, 1000, 2000, 3000, 4000)
NUSKIN_QUICK_RATES_HZ = (50, 250, 1000, 4000)
BIOTAC_RATES_HZ = (100, 250, 500, 1000, 2200)
REPORT_FEATURES = ("fft", "baseline", "est", "autoencoder")
REPORT_MODELS = ("svm_linear", "svm_rbf", "mlp")
QUICK_FEATURES = ("fft", "baseline")
QUICK_MODELS = ("svm_rbf",)
LINEAR_MODEL = "svm_linear"  # the paper's linear SVM/SVR: weighs each feature on its own
# The linear SVR's C grid (metre labels): the paper's 0.01..1 extended three decades down. On
# the 1000-tap 30 cm rod (FFT, 80 taxels) the paper's grid chose its lowest C in every split
# (2.13 cm); the extended grid chooses 3e-5 inside it (1.49 cm); one finger chooses 1e-4.
LINEAR_REGRESSION_C = (1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 0.01, 0.03, 0.1, 0.3, 1.0)
# feature sets whose NUSkin bin the report's ``base_params`` (``--bin-ms``) sets
BINNED_FEATURES = ("baseline", "fft", "autoencoder")


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


def check_choices(
    features: list[str] | tuple[str, ...] | None, models: list[str] | tuple[str, ...] | None
) -> tuple[tuple[str, ...] | None, tuple[str, ...] | None]:
    """Validated feature-set and model names for the features x models tables.

    Args:
        features: Feature set names (aliases such as ``raw`` allowed), or None for the default.
        models: Model names, or None for the default. ``gru`` is not one of them: the GRU has
            its own row (``gru=False`` leaves it out).

    Returns:
        ``(features, models)``: canonical names, duplicates dropped, order kept (None stays None).

    Raises:
        PerceptionError: on an empty list or an unknown name.
    """
    from ext_sense_perception.features import FeatureKind
    from ext_sense_perception.models import MODEL_NAMES

    out_f = None
    if features is not None:
        names = [FeatureKind.parse(f).name.lower() for f in features if str(f).strip()]
        if not names:
            raise PerceptionError(
                "The 'features' parameter must name at least one feature set. Got "
                f"{list(features)!r} instead."
            )
        out_f = tuple(dict.fromkeys(names))
    out_m = None
    if models is not None:
        allowed = tuple(m for m in MODEL_NAMES if m != "gru")
        names = [str(m).strip().lower() for m in models if str(m).strip()]
        if not names:
            raise PerceptionError(
                "The 'models' parameter must name at least one model. Got "
                f"{list(models)!r} instead."
            )
        for m in names:
            if m not in allowed:
                raise PerceptionError(
                    f"The 'models' parameter must be among {', '.join(allowed)} (the GRU has its "
                    f"own row: leave it out with --no-gru). Got {m!r} instead."
                )
        out_m = tuple(dict.fromkeys(names))
    return out_f, out_m


def _fingerprint(ws: WindowSet) -> bytes:
    """Digest of a window set's windows, labels and geometry (memo key)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(np.ascontiguousarray(ws.X).view(np.uint8).ravel())
    h.update(np.asarray(ws.y).astype(str).tobytes())
    h.update(repr((ws.task, ws.sensor, tuple(ws.geometry))).encode())
    return h.digest()


def _modal_params(res: EvalResult) -> dict[str, Any]:
    """The hyper-parameters chosen in most splits (ties: the first split's)."""
    keys = [repr(sorted(p.items())) for p in res.best_params]
    best = Counter(keys).most_common(1)[0][0]
    return dict(res.best_params[keys.index(best)])


class _Runner:
    """Runs the protocol once per distinct (windows, features, model, parameters).

    Points shared by several sections (the default model on the full window, the nominal
    rate, both fingers, the rod-length table) are evaluated once and reused; every computed
    point is appended to ``records`` (report.json).
    """

    def __init__(
        self,
        k: int,
        seed: int,
        records: list[dict[str, Any]],
        base_params: dict[str, Any] | None,
        n_jobs: int,
    ) -> None:
        self.k, self.seed, self.records = k, seed, records
        self.base_params = dict(base_params or {})
        self.n_jobs = n_jobs
        self._memo: dict[tuple, EvalResult] = {}
        self._prints: dict[int, tuple[np.ndarray, bytes]] = {}

    def feature_params(self, ws: WindowSet, features: str, params: dict[str, Any]) -> dict:
        """Feature parameters: project defaults (2 ms handover bins), base_params, params."""
        from ext_sense_perception.models import default_feature_params

        out = dict(default_feature_params(ws.task, ws.sensor))
        if ws.sensor == "nuskin" and features in BINNED_FEATURES:
            out.update(self.base_params)
        out.update({k: v for k, v in params.items() if v is not None})  # None: the default
        return out

    def _print(self, ws: WindowSet) -> bytes:
        hit = self._prints.get(id(ws.X))
        if hit is None or hit[0] is not ws.X:
            hit = (ws.X, _fingerprint(ws))
            self._prints[id(ws.X)] = hit
        return hit[1]

    def __call__(
        self,
        ws: WindowSet,
        name: str,
        features: str,
        model: str,
        model_params: dict[str, Any] | None = None,
        extra_grid: dict[str, list[Any]] | None = None,
        **params: Any,
    ) -> EvalResult:
        """Score ``features`` + ``model`` on ``ws`` (K splits), or return the memoised result."""
        from ext_sense_perception.models import default_feature_grid

        params = self.feature_params(ws, features, params)
        grid = dict(default_feature_grid(ws.task, ws.sensor, features))
        if model == LINEAR_MODEL and ws.is_regression:
            grid["model__C"] = list(LINEAR_REGRESSION_C)
        grid.update(extra_grid or {})
        key = (
            self._print(ws),
            features,
            model,
            repr(sorted(params.items())),
            repr(sorted((model_params or {}).items())),
            repr(sorted(grid.items())),
        )
        if key in self._memo:
            return self._memo[key]
        t0 = time.perf_counter()
        res = evaluate(
            ws,
            features_for(ws, features, **params),
            model,
            k=self.k,
            seed=self.seed,
            progress=False,
            n_jobs=self.n_jobs,
            feature_grid=grid,
            model_params=model_params,
        )
        self.records.append(
            {
                "dataset": name,
                "data": key[0].hex(),  # digest of the windows and labels evaluated
                "features": features,
                "model": model,
                "params": params,
                "grid": grid,
                "post_ms": res.post_ns / MS,
                "metric": res.metric,
                "mean": res.mean,
                "std": res.std,
                "scores": res.scores.tolist(),
                "best_params": res.best_params,
                "k": res.k,
                "eval_s": time.perf_counter() - t0,
            }
        )
        self._memo[key] = res
        return res

    def infer_ms(
        self,
        ws: WindowSet,
        features: str,
        model: str,
        res: EvalResult,
        model_params: dict[str, Any] | None = None,
    ) -> tuple[float, float]:
        """ONNX single-window p50 and p99 latency, ms, of the model the protocol would deploy.

        It is trained on every window with the hyper-parameters chosen in most splits (a
        one-candidate grid, so it costs about a quarter of a split, not a second search).
        """
        from ext_sense_perception import bundle
        from ext_sense_perception.cli import measure_inference

        fixed = {k: [v] for k, v in _modal_params(res).items()}
        trained = bundle.train(
            ws,
            features,
            model,
            self.feature_params(ws, features, {}),
            fixed,
            seed=self.seed,
            n_jobs=self.n_jobs,
            model_params=model_params,
        )
        t = measure_inference(trained, ws, n=100)
        return t["infer_p50_ms_onnx"], t["infer_p99_ms_onnx"]


def gru_row(ws: WindowSet, gru: bool | None = None) -> bool:
    """Whether the features x models table gets the GRU (baseline features) row.

    NUSkin tap localisation (the paper's best NUSkin tap model is the RNN on binned counts),
    unless ``gru`` is False; the row says "skipped" when torch is not installed. BioTac is left
    out: its raw PAC gives 660-step sequences, about 10x the training time.
    """
    return gru is not False and ws.task == "tap_localization" and ws.sensor == "nuskin"


def dataset_name(ws: WindowSet, path: Path | str) -> str:
    """File-name stem of a data set's plots: task, sensor and the data's folder name."""
    src = Path(str(path))
    return f"{ws.task}_{ws.sensor}_{src.parent.name if src.is_file() else src.name}"


def _taxel_section(
    ws: WindowSet,
    run: _Runner,
    name: str,
    feat0: str,
    model0: str,
    n_top: int,
    k: int,
) -> list[str]:
    """Both fingers against one finger against one taxel, default and linear model side by side.

    The single taxel is a hyper-parameter: among the ``n_top`` most active taxels (activity
    summed over every window, which uses no label), each split's 4-fold grid search on its
    training part picks it, so the test part never chooses it.
    """
    g = ws.geometry
    cols = [model0] + ([LINEAR_MODEL] if model0 != LINEAR_MODEL else [])
    activity = np.abs(ws.X).sum(axis=(0, 2))
    top = np.sort(np.argsort(activity, kind="stable")[::-1][:n_top])  # 0-based channel rows
    sub = ws._replace(
        X=np.ascontiguousarray(ws.X[:, top, :]), geometry=g._replace(n_channels=len(top))
    )
    taxel_grid = {"features__channels": [f"taxel:{i + 1}" for i in range(len(top))]}
    ids = ", ".join(str(int(t) + 1) for t in top)
    header = " | ".join(f"{feat0} + {m}" + (" (default)" if m == model0 else "") for m in cols)
    lines = [
        "### Two fingers, one finger, one taxel",
        "",
        f"K = {k} splits; the linear model weighs each standardised feature on its own, the RBF "
        "kernel weighs all alike (off-strip taxels dilute it).",
        "",
        f"| taxels | {header} |",
        "|---|" + "---|" * len(cols),
    ]
    for sel, label in [
        (None, f"both fingers ({g.n_channels})"),
        ("left", f"one finger (1-{g.n_channels // 2})"),
        ("right", f"one finger ({g.n_channels // 2 + 1}-{g.n_channels})"),
    ]:
        cells = []
        for m in cols:
            try:
                cells.append(_fmt(run(ws, name, feat0, m, channels=sel)))
            except PerceptionError as err:
                cells.append(f"failed: {err}")
        lines.append(f"| {label} | {' | '.join(cells)} |")
    cells, picks = [], []
    for m in cols:
        try:
            res = run(sub, name, feat0, m, extra_grid=taxel_grid)
        except PerceptionError as err:
            cells.append(f"failed: {err}")
            continue
        cells.append(_fmt(res))
        chosen = [
            int(top[int(p["features__channels"].split(":")[1]) - 1]) + 1 for p in res.best_params
        ]
        picks.append(f"{m}: {', '.join(str(c) for c in chosen)}")
    lines += [
        f"| one taxel, chosen per split on the training part among the {len(top)} most active "
        f"({ids}) | {' | '.join(cells)} |",
        "",
        f"Taxel chosen in each split: {'; '.join(picks)}.",
        "",
    ]
    return lines


def _latency_section(
    ws: WindowSet, run: _Runner, name: str, out: Path, feat0: str, model0: str
) -> list[str]:
    """Score against the post-contact window (decision latency), with anytime calibration."""
    lower = ws.is_regression
    g = ws.geometry
    full_post = g.n_samples * g.period_ns - g.pre_ns
    posts = (
        [p * MS for p in POSTS_MS]
        if ws.task != "food_identification"
        else [1000 * MS, 2000 * MS, full_post]
    )
    posts = [p for p in posts if p <= full_post]
    lines = [
        f"### Decision latency ({feat0} + {model0}); anytime calibration",
        "",
        "| post-contact window ms | score | "
        + ("95% PI coverage | PI half-width cm |" if lower else "ECE | Brier |"),
        "|---|---|---|---|",
    ]
    dx, dy = [], []
    for p in posts:
        res = run(ws.crop(p), name, feat0, model0)
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
    return lines


def report_dataset(
    ws: WindowSet,
    path: Path,
    out: Path,
    run: _Runner,
    quick: bool,
    gru: bool | None = None,
    gru_params: dict[str, Any] | None = None,
    features: tuple[str, ...] | None = None,
    models: tuple[str, ...] | None = None,
    latency: bool = True,
    taxels: bool = True,
) -> list[str]:
    """Markdown lines (and PNGs in ``out``) for one window set.

    ``run`` evaluates and memoises points (K, seed, ``base_params``, jobs); ``gru=False`` leaves
    out the GRU row (see :func:`gru_row`); ``gru_params`` are fixed
    :class:`~ext_sense_perception.gru.GRUEstimator` parameters (e.g. fewer epochs for a smoke
    run); ``features`` / ``models`` replace the features x models table's defaults (the NUSkin
    food table always starts with its default ``activity`` features); ``latency=False`` /
    ``taxels=False`` leave out the decision-latency / finger and taxel sections.
    """
    k = run.k
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
        f"### Features and models (K = {k} random 90/10 splits, 4-fold grid search)",
        "",
        "| features | model | score | train s/split | ONNX p50 / p99 ms |",
        "|---|---|---|---|---|",
    ]
    inf_x, inf_y, inf_lab = [], [], []
    for f in feats:
        for m in mods:
            try:
                res = run(ws, name, f, m)
                p50, p99 = run.infer_ms(ws, f, m, res)
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
                res = run(ws, name, "baseline", "gru", model_params=gru_params)
                p50, p99 = run.infer_ms(ws, "baseline", "gru", res, gru_params)
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

    g = ws.geometry
    if latency:
        lines += _latency_section(ws, run, name, out, feat0, model0)

    # sampling rate
    rx, ry = [], []
    rows = []
    if ws.sensor == "nuskin" and Path(str(path)).suffix == ".npz":
        for r in NUSKIN_QUICK_RATES_HZ if quick else NUSKIN_RATES_HZ:
            res = run(from_sim_dataset(path, rate_hz=r), name, feat0, model0)
            rows.append(f"| {r} | {_fmt(res)} |")
            rx.append(r)
            ry.append(_score(res))
    elif ws.sensor == "biotac":
        for r in BIOTAC_RATES_HZ:
            res = run(ws, name, feat0, model0, rate_hz=float(r))
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
        lines += _taxel_section(ws, run, name, feat0, model0, 2 if quick else 4, k)
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
) -> Path:
    """Evaluate every dataset and write ``out/report.md``, PNGs and ``out/report.json``.

    Args:
        datasets: Simulator datasets or a food-poking capture directory.
        out: Output directory.
        k: Random splits per point (default 3, or 2 with ``quick``).
        quick: Fewer features, models, rates and candidate taxels.
        seed: Seed.
        base_params: Feature parameters for every NUSkin evaluation (e.g. ``bin_ns``).
        gru: False leaves out the GRU row of NUSkin tap datasets (default: included, or
            marked skipped when torch is missing).
        gru_params: Fixed GRU parameters (e.g. ``{"max_epochs": 5}`` for a smoke run).
        features: Feature sets of the features x models tables (default: fft, baseline, est,
            autoencoder; quick: fft, baseline).
        models: Models of those tables (default: svm_linear, svm_rbf, mlp; quick: svm_rbf).
        n_jobs: Parallel grid-search jobs per evaluation.
        latency: False leaves out the decision-latency / anytime-calibration sections.
        taxels: False leaves out the two fingers / one finger / one taxel sections.

    Returns:
        The markdown file.

    Raises:
        PerceptionError: on an unknown feature set or model name (before anything runs), or
            unreadable data.
    """
    from threadpoolctl import threadpool_limits

    features, models = check_choices(features, models)
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
    run = _Runner(k, seed, records, base_params, n_jobs)
    rods: list[tuple[float, str, EvalResult]] = []
    with threadpool_limits(limits=1):
        for done, path in enumerate(datasets, start=1):
            ws = load_window_set(path)
            lines += report_dataset(
                ws, path, out, run, quick, gru, gru_params, features, models, latency, taxels
            )
            if done < len(datasets):  # a long run keeps what it has so far
                _write(
                    out, [*lines, f"(In progress: {done} of {len(datasets)} data sets.)"], records
                )
            if ws.task == "tap_localization" and np.isfinite(ws.rod_length_m).any():
                feat0, model0 = default_choice(ws.task, ws.sensor)
                res = run(ws, dataset_name(ws, path), feat0, model0)  # memoised above
                rods.append((float(np.nanmedian(ws.rod_length_m)), ws.sensor, res))
    if len(rods) > 1:
        lines += [
            "## Rod length (tap localisation, default model)",
            "",
            "| rod m | sensor | MAE | MAE / length |",
            "|---|---|---|---|",
        ]
        for length, sensor, res in sorted(rods, key=lambda r: (r[1], r[0])):
            lines.append(f"| {length:.2f} | {sensor} | {_fmt(res)} | {res.mean / length:.3f} |")
        lines.append("")
    return _write(out, lines, records)


def _write(out: Path, lines: list[str], records: list[dict[str, Any]]) -> Path:
    """Write ``report.md`` and ``report.json``; returns the markdown file."""
    md = out / "report.md"
    md.write_text("\n".join(lines) + "\n")
    (out / "report.json").write_text(json.dumps(records, indent=2, default=str) + "\n")
    return md
