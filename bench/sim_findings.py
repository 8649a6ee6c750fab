"""Do simulated rod taps reproduce the paper's qualitative findings?

Simulates taps per rod with the scene simulator and runs them through the perception package's
own offline path, the one ``ext-sense train`` uses: the simulator's ``dataset.npz`` is read by
``data.sources.from_sim_dataset`` (windows cut by ``online.window.window_from_recording`` with
the tap profile: 50 ms before to 250 ms after the true onset; for the rate study the events are
first thinned by ``data.refractory.refractory_mask``, the paper's per-taxel refractory drop:
drop any spike closer than ``1/rate`` to the taxel's last kept one), features are
``features_for(ws, "fft", channels=...)`` (|FFT| of the profile's 5 ms feature bins per taxel,
the public code's scaling; ``all``, ``left``, ``right``, ``taxel:N``), and the models come from
``training.models.make_pipeline`` (scaler and model of the pipeline, on the features computed
once, as the training protocol does). It prints the 4-fold cross-validated MAE of:

- ``svm_rbf``: standardised features into an RBF SVR, C from the package's grid by its inner
  4-fold search (``training.protocol.inner_cv``), as the tap default;
- ridge regression on ``log1p`` of the same features (alpha by generalised CV): a linear model
  that weighs each feature. The package has no ridge model, so this one is scikit-learn's
  ``RidgeCV`` on the package's features;
- ``taxel_svr`` (``TaxelStackSVR``): one RBF SVR per selected taxel, combined by ridge trained on
  out-of-fold predictions (a nonlinear model that weighs taxels: the fair one for comparing
  selections, since the single RBF SVR's kernel is diluted by off-strip taxels);

for 80 taxels (two fingers), 40 (one finger) and the best single taxel chosen on each training
fold, with finger comparisons paired per tap; and the MAE against the sampling rate. Figures and
what they mean: docs/simulator.md, "Tap calibration".

    python bench/sim_findings.py                 # 1000 taps per rod (the paper's), 3 rods
    python bench/sim_findings.py --quick         # 150 taps, 30 cm rod only
    python bench/sim_findings.py --set grasp_transfer.grip_force_n=20   # what-if

It measures the simulator through the package's pipeline; it adds no feature code of its own.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from sklearn.base import BaseEstimator
from sklearn.linear_model import RidgeCV
from sklearn.model_selection import GridSearchCV, KFold, cross_val_predict
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import FunctionTransformer, StandardScaler
from threadpoolctl import threadpool_limits

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.features.transformer import WindowFeatures
from ext_sense_perception.profiles import profile_for
from ext_sense_perception.training.models import head_of, make_estimator, make_pipeline
from ext_sense_perception.training.protocol import features_for, inner_cv
from ext_sense_sim.dataset import DatasetCollector
from ext_sense_sim.engine import Simulator
from ext_sense_sim.scene import load_scene

RATES = (5.0, 20.0, 50.0, 200.0, 500.0, 1000.0, 2000.0, 3000.0, 4000.0)
SELECTIONS = {"80 taxels": "all", "40 (left)": "left", "40 (right)": "right"}
FINGERS = ("40 (left)", "40 (right)")
RIDGE_ALPHAS = np.logspace(-1, 4, 11)
LOG_SCALE = 1000.0  # ridge sees log1p(1000 |FFT|): the FFT scaling's 1/1000 undone
CM = 100.0  # labels are metres; figures are printed in cm
CV_SEED = 0  # outer 4-fold split and models (the simulator has its own --seed)


def override(scene, sets: list[str]):
    """Scene with ``effect.param=value`` overrides (value parsed as YAML)."""
    effects = [(name, dict(params)) for name, params in scene.effects]
    for item in sets:
        key, value = item.split("=", 1)
        effect, param = key.split(".", 1)
        for name, params in effects:
            if name == effect:
                params[param] = yaml.safe_load(value)
                break
        else:
            raise SystemExit(f"--set: the scene lists no effect {effect!r}")
    return dataclasses.replace(scene, effects=tuple(effects))


def simulate(scene_name: str, taps: int, seed: int, sets: list[str], out: Path) -> float:
    """Write the scene's ``dataset.npz`` to ``out``; returns the events per tap in the window."""
    scene = override(load_scene(scene_name), sets)
    sim = Simulator(scene)
    collector = DatasetCollector(scene, seed)
    for tb, sig in sim.batches(taps, seed):
        collector.add(tb, sig)
    arrays = collector.arrays()
    np.savez(out, **arrays)  # uncompressed: read back at once for every rate
    profile = profile_for(str(arrays["task"]))  # the window from_sim_dataset cuts
    rel = arrays["ev_t_ns"] - arrays["onset_ns"][arrays["ev_trial"]]
    inside = (rel >= -profile.pre_ns) & (rel < profile.post_ns)
    return float(inside.sum()) / taps


def fft_features(ws: WindowSet, channels: str) -> tuple[WindowFeatures, np.ndarray]:
    """The package's FFT transformer for a channel selection, and its features of ``ws``."""
    feats = features_for(ws, "fft", channels=channels)
    x = ws.X.reshape(len(ws.y), -1)
    return feats, feats.fit(x[:1]).transform(x)


def svm_rbf(feats: WindowFeatures, ws: WindowSet) -> GridSearchCV:
    """The package's ``svm_rbf`` (scaler + SVR) with its grid searched by its inner CV."""
    pipe, grid = make_pipeline(feats, "svm_rbf", True, CV_SEED)
    return GridSearchCV(
        head_of(pipe), grid, cv=inner_cv(ws, ws.y, CV_SEED), scoring="neg_mean_absolute_error"
    )


def taxel_svr(feats: WindowFeatures) -> Pipeline:
    """The package's ``taxel_svr`` (scaler + TaxelStackSVR over the selected taxels)."""
    return head_of(make_pipeline(feats, "taxel_svr", True, CV_SEED)[0])


def _log_features(f: np.ndarray) -> np.ndarray:
    return np.log1p(f * LOG_SCALE)


def ridge() -> Pipeline:
    """Ridge regression on ``log1p`` features, alpha by generalised CV (no package model)."""
    return Pipeline(
        [
            ("log", FunctionTransformer(_log_features)),
            ("scale", StandardScaler()),
            ("model", RidgeCV(alphas=RIDGE_ALPHAS)),
        ]
    )


def outer_folds(n: int):
    return KFold(4, shuffle=True, random_state=CV_SEED).split(np.arange(n))


def cv_errors(model: BaseEstimator, f: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per-tap absolute errors (cm) of 4-fold cross-validated predictions."""
    pred = cross_val_predict(model, f, y, cv=KFold(4, shuffle=True, random_state=CV_SEED))
    return np.abs(pred - y) * CM


def inner_mae(model: BaseEstimator, f: np.ndarray, y: np.ndarray) -> float:
    """MAE of an inner 3-fold CV on a training part only (choosing a taxel)."""
    inner = KFold(3, shuffle=True, random_state=CV_SEED + 1)
    return float(np.mean(np.abs(cross_val_predict(model, f, y, cv=inner) - y)))


def paired(worse: np.ndarray, better: np.ndarray) -> str:
    """Mean per-tap error difference and its standard error, e.g. ``+0.10 +- 0.02``.

    The same taps are scored by both selections, so the paired difference removes the
    tap-to-tap spread that dominates either MAE's own uncertainty.
    """
    d = worse - better
    return f"{d.mean():+.2f} +- {d.std(ddof=1) / np.sqrt(len(d)):.2f}"


def single_taxel(
    ws: WindowSet, taxels: list[tuple[WindowFeatures, np.ndarray]]
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """``svm_rbf`` and ridge per-tap errors of the best single taxel, chosen on each fold.

    In each outer fold every taxel's ridge model is scored by an inner 3-fold CV on the training
    part only; the best one is refitted and scored on the test part, so the choice never sees
    the test taps.

    Returns:
        ``(svm_rbf errors, ridge errors, chosen taxel ids per fold)``, errors in cm.
    """
    y = ws.y
    errs_s, errs_r, chosen = np.zeros(len(y)), np.zeros(len(y)), []
    for train, test in outer_folds(len(y)):
        scores = [inner_mae(ridge(), f[train], y[train]) for _, f in taxels]
        best = int(np.argmin(scores))
        chosen.append(best + 1)
        feats, f = taxels[best]
        pred = ridge().fit(f[train], y[train]).predict(f[test])
        errs_r[test] = np.abs(pred - y[test]) * CM
        pred = svm_rbf(feats, ws).fit(f[train], y[train]).predict(f[test])
        errs_s[test] = np.abs(pred - y[test]) * CM
    return errs_s, errs_r, chosen


def taxel_stack_errors(
    ws: WindowSet,
    selections: dict[str, tuple[WindowFeatures, np.ndarray]],
    taxels: list[tuple[WindowFeatures, np.ndarray]],
) -> tuple[dict[str, np.ndarray], list[int]]:
    """Per-tap errors (cm) of ``taxel_svr`` for each selection and for the best single taxel.

    The single taxel is the one whose SVR (the stack's per-taxel SVR: the package's ``svm_rbf``
    at the stack's C) has the lowest out-of-fold error in an inner 3-fold CV on the training
    part; the stack is then fitted on that taxel alone.

    Returns:
        Per-tap errors per selection plus ``"1 taxel"``, and the chosen taxel ids per fold.
    """
    y = ws.y
    stack_c = make_estimator("taxel_svr", True, CV_SEED)[0].C
    errs = {label: np.zeros(len(y)) for label in [*selections, "1 taxel"]}
    chosen = []
    for train, test in outer_folds(len(y)):
        for label, (feats, f) in selections.items():
            pred = taxel_svr(feats).fit(f[train], y[train]).predict(f[test])
            errs[label][test] = np.abs(pred - y[test]) * CM
        scores = []
        for feats, f in taxels:
            svr = head_of(make_pipeline(feats, "svm_rbf", True, CV_SEED)[0])
            scores.append(inner_mae(svr.set_params(model__C=stack_c), f[train], y[train]))
        best = int(np.argmin(scores))
        chosen.append(best + 1)
        feats, f = taxels[best]
        pred = taxel_svr(feats).fit(f[train], y[train]).predict(f[test])
        errs["1 taxel"][test] = np.abs(pred - y[test]) * CM
    return errs, chosen


def run_rod(scene: str, taps: int, seed: int, rates, sets) -> None:
    with tempfile.TemporaryDirectory(prefix="sim_findings_") as tmp:
        data = Path(tmp) / "dataset.npz"
        start = time.perf_counter()
        per_tap = simulate(scene, taps, seed, sets, data)
        sim_s = time.perf_counter() - start
        ws = from_sim_dataset(data)
        _run_windows(ws, scene, taps, per_tap, sim_s)
        if rates:
            print("  rate (80 taxels), MAE SVR / ridge, cm:", flush=True)
            for rate in rates:
                wr = from_sim_dataset(data, rate_hz=rate)
                feats, f = fft_features(wr, "all")
                svr = cv_errors(svm_rbf(feats, wr), f, wr.y).mean()
                print(f"  {rate:>8g} Hz {svr:6.2f} {cv_errors(ridge(), f, wr.y).mean():6.2f}")


def _run_windows(ws: WindowSet, scene: str, taps: int, per_tap: float, sim_s: float) -> None:
    y = ws.y
    selections = {label: fft_features(ws, sel) for label, sel in SELECTIONS.items()}
    taxels = [fft_features(ws, f"taxel:{t}") for t in range(1, ws.geometry.n_channels + 1)]
    spread = float(np.mean(np.abs(y - y.mean()))) * CM
    line = [f"{scene}: {taps} taps, {per_tap:.0f} events/tap in window, sim {sim_s:.1f} s"]
    line.append(f"  spread of y (mean abs dev) {spread:.2f} cm")
    line.append(f"  {'':>10}  MAE SVR (RBF)  MAE ridge  ridge, paired per tap (cm, +- SE)")
    errs = {}
    for label, (feats, f) in selections.items():
        errs[label] = cv_errors(ridge(), f, y)
        svr = cv_errors(svm_rbf(feats, ws), f, y).mean()
        vs = (
            ""
            if label == "80 taxels"
            else f"  minus 80 taxels {paired(errs[label], errs['80 taxels'])}"
        )
        line.append(f"  {label:>10}: {svr:9.2f} cm {errs[label].mean():8.2f} cm{vs}")
    st, sr, tax = single_taxel(ws, taxels)
    better = min(FINGERS, key=lambda k: errs[k].mean())
    line.append(
        f"  {'1 taxel':>10}: {st.mean():9.2f} cm {sr.mean():8.2f} cm  minus better finger "
        f"{paired(sr, errs[better])} (best on each training fold: taxels {tax})"
    )
    stack, stack_tax = taxel_stack_errors(ws, selections, taxels)
    line.append("  stacked per-taxel RBF SVRs (MAE, then paired per tap, cm +- SE):")
    line.append(f"  {'80 taxels':>10}: {stack['80 taxels'].mean():.2f} cm")
    for label in FINGERS:
        line.append(
            f"  {label:>10}: {stack[label].mean():.2f} cm  minus 80 taxels "
            f"{paired(stack[label], stack['80 taxels'])}"
        )
    better = min(FINGERS, key=lambda k: stack[k].mean())
    line.append(
        f"  {'1 taxel':>10}: {stack['1 taxel'].mean():.2f} cm  minus better finger "
        f"{paired(stack['1 taxel'], stack[better])} (taxels {stack_tax})"
    )
    print("\n".join(line), flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--taps", type=int, default=1000, help="taps per rod (paper: 1000)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--rods", default="20,30,50")
    parser.add_argument("--rates", default=",".join(f"{r:g}" for r in RATES))
    parser.add_argument("--no-rates-except", default="20,30,50", help="rods whose rate study runs")
    parser.add_argument("--set", action="append", default=[], help="effect.param=value")
    parser.add_argument("--quick", action="store_true", help="150 taps, 30 cm rod only")
    args = parser.parse_args()
    if args.quick:
        args.taps, args.rods = 150, "30"
    rates = [float(r) for r in args.rates.split(",") if r]
    with_rates = set(args.no_rates_except.split(","))
    # BLAS pinned to one thread, as the package's fitting does (small matrices, shared cores)
    with threadpool_limits(limits=1):
        for rod in args.rods.split(","):
            rod_rates = rates if rod in with_rates else []
            run_rod(f"tap_rod{rod}_nuskin", args.taps, args.seed, rod_rates, args.set)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
