"""Do simulated rod taps reproduce the paper's qualitative findings?

Simulates taps per rod with the scene simulator, turns each trial's NUSkin events into the
paper's features (signed spike counts in 5 ms bins from 50 ms before to 250 ms after the true
onset, |FFT| per taxel with the public code's scaling) and prints the 4-fold cross-validated
MAE of standardised features into an RBF SVR (C from 1, 10, 100 by an inner 3-fold grid
search, as the perception package's pipeline) and of ridge regression on ``log1p`` features
(a model that weighs each feature) for 80 taxels (two fingers), 40 (one finger) and the best
single taxel chosen on each training fold; for the selections also stacked per-taxel RBF SVRs
(a nonlinear model that weighs taxels: the fair one for comparing selections, since the single
RBF SVR's kernel is diluted by off-strip taxels); and the MAE for the paper's sampling-rate
reduction (per taxel, drop any spike closer than ``1/rate`` to
the last kept one). Figures and what they mean: docs/simulator.md, "Tap calibration".

    python bench/sim_findings.py                 # 1000 taps per rod (the paper's), 3 rods (~10 min)
    python bench/sim_findings.py --quick         # 150 taps, 30 cm rod only
    python bench/sim_findings.py --set grasp_transfer.grip_force_n=20   # what-if

The learning here is deliberately plain (the perception package owns the real protocol): it
measures the simulator, not the models.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
import yaml
from sklearn.linear_model import RidgeCV
from sklearn.model_selection import GridSearchCV, KFold, cross_val_predict
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVR

from ext_sense_sim.engine import Simulator
from ext_sense_sim.scene import load_scene

MS = 1_000_000
PRE_NS, POST_NS, BIN_NS = 50 * MS, 250 * MS, 5 * MS
N_BINS = (PRE_NS + POST_NS) // BIN_NS
C_GRID = (1.0, 10.0, 100.0)
RATES = (5.0, 20.0, 50.0, 200.0, 500.0, 1000.0, 2000.0, 3000.0, 4000.0)
SELECTIONS = {
    "80 taxels": np.arange(80),
    "40 (left)": np.arange(40),
    "40 (right)": np.arange(40, 80),
}


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


def simulate(scene_name: str, taps: int, seed: int, sets: list[str]):
    """Events ``(trial, t_ns rel. onset, taxel 0-based, polarity)`` and labels (cm)."""
    scene = override(load_scene(scene_name), sets)
    sim = Simulator(scene)
    parts, ys = [], []
    for tb, sig in sim.batches(taps, seed):
        ev, lab = sig["events"], sig["labels"]
        trial = ev.trial.astype(np.int64) + tb.first_trial
        rel = ev.t_ns - lab.onset_ns[ev.trial]
        keep = (rel >= -PRE_NS) & (rel < POST_NS)
        parts.append(
            (trial[keep], rel[keep], ev.taxel[keep].astype(np.int64) - 1, ev.polarity[keep])
        )
        ys.append(lab.y_m * 100.0)
    cat = [np.concatenate([p[i] for p in parts]) for i in range(4)]
    return cat, np.concatenate(ys)


def refractory_keep(trial, t_ns, taxel, rate_hz: float) -> np.ndarray:
    """The paper's per-taxel refractory drop (vectorised over channels, loop over events)."""
    tau = round(1e9 / rate_hz)
    chan = trial * 80 + taxel
    order = np.lexsort((t_ns, chan))
    c, t = chan[order], t_ns[order]
    keep_sorted = np.zeros(len(t), dtype=bool)
    start = np.r_[0, np.flatnonzero(np.diff(c)) + 1]
    # per channel: walk its events; channels are short, so iterate event index in lock-step
    last = np.full(len(start), np.iinfo(np.int64).min // 2)
    ends = np.r_[start[1:], len(t)]
    pos = start.copy()
    active = pos < ends
    while active.any():
        idx = pos[active]
        ok = t[idx] - last[active] >= tau
        keep_sorted[idx[ok]] = True
        la = last[active]
        la[ok] = t[idx[ok]]
        last[active] = la
        pos[active] += 1
        active = pos < ends
    keep = np.zeros(len(t), dtype=bool)
    keep[order] = keep_sorted
    return keep


def features(ev, n_trials: int, rate_hz: float | None) -> np.ndarray:
    """|FFT| of signed 5 ms counts per taxel, ``(n_trials, 80, N_BINS // 2 + 1)``."""
    trial, rel, taxel, pol = ev
    if rate_hz is not None:
        k = refractory_keep(trial, rel, taxel, rate_hz)
        trial, rel, taxel, pol = trial[k], rel[k], taxel[k], pol[k]
    counts = np.zeros((n_trials, 80, N_BINS))
    b = (rel + PRE_NS) // BIN_NS
    np.add.at(counts, (trial, taxel, b), pol.astype(np.float64))
    return np.abs(np.fft.rfft(counts / 1000.0, axis=-1)) / 10.0


def mae(x: np.ndarray, y: np.ndarray, seed: int = 0) -> float:
    """4-fold cross-validated MAE of an RBF SVR, same units as ``y``."""
    pipe = make_pipeline(StandardScaler(), SVR(kernel="rbf", gamma="scale", epsilon=0.1))
    model = GridSearchCV(pipe, {"svr__C": C_GRID}, cv=3, scoring="neg_mean_absolute_error")
    pred = cross_val_predict(model, x, y, cv=KFold(4, shuffle=True, random_state=seed))
    return float(np.mean(np.abs(pred - y)))


def ridge_errors(x: np.ndarray, y: np.ndarray, seed: int = 0) -> np.ndarray:
    """Per-tap absolute errors of 4-fold cross-validated ridge on log1p features.

    A linear model weighs each feature; the RBF kernel on standardised features weighs all
    equally, so uninformative taxels dilute its distances. Both are printed side by side.
    Per-tap errors (not only their mean) let two selections be compared tap by tap.
    """
    model = make_pipeline(StandardScaler(), RidgeCV(alphas=np.logspace(-1, 4, 11)))
    x = np.log1p(x * 1000.0)
    pred = cross_val_predict(model, x, y, cv=KFold(4, shuffle=True, random_state=seed))
    return np.abs(pred - y)


def ridge_mae(x: np.ndarray, y: np.ndarray, seed: int = 0) -> float:
    """4-fold cross-validated MAE of ridge regression on log1p features (alpha by inner CV)."""
    return float(np.mean(ridge_errors(x, y, seed)))


def paired(worse: np.ndarray, better: np.ndarray) -> str:
    """Mean per-tap error difference and its standard error, e.g. ``+0.10 +- 0.02``.

    The same taps are scored by both selections, so the paired difference removes the
    tap-to-tap spread that dominates either MAE's own uncertainty.
    """
    d = worse - better
    return f"{d.mean():+.2f} +- {d.std(ddof=1) / np.sqrt(len(d)):.2f}"


def _fold_mae(make, x: np.ndarray, y: np.ndarray, train: np.ndarray, test: np.ndarray) -> float:
    model = make().fit(x[train], y[train])
    return float(np.mean(np.abs(model.predict(x[test]) - y[test])))


def _ridge() -> object:
    return make_pipeline(StandardScaler(), RidgeCV(alphas=np.logspace(-1, 4, 11)))


def _svr() -> object:
    pipe = make_pipeline(StandardScaler(), SVR(kernel="rbf", gamma="scale", epsilon=0.1))
    return GridSearchCV(pipe, {"svr__C": C_GRID}, cv=3, scoring="neg_mean_absolute_error")


def single_taxel(
    f: np.ndarray, y: np.ndarray, seed: int = 0
) -> tuple[float, np.ndarray, list[int]]:
    """SVR and ridge MAE of the best single taxel, chosen on each training fold.

    In each outer fold every taxel's ridge model (log1p features) is scored by an inner 3-fold
    CV on the training part only; the best one is refitted and scored on the test part, so the
    choice never sees the test taps.

    Returns:
        ``(mae_svr, per-tap ridge errors, chosen taxel ids per fold)``.
    """
    n = len(y)
    logf = np.log1p(f * 1000.0)
    errs_s, errs_r, chosen = np.zeros(n), np.zeros(n), []
    for train, test in KFold(4, shuffle=True, random_state=seed).split(f):
        inner = KFold(3, shuffle=True, random_state=seed + 1)
        scores = []
        for tx in range(f.shape[1]):
            xt = logf[train, tx]
            scores.append(
                np.mean([_fold_mae(_ridge, xt, y[train], a, b) for a, b in inner.split(xt)])
            )
        best = int(np.argmin(scores))
        chosen.append(best + 1)
        ridge = _ridge().fit(logf[train, best], y[train])
        errs_r[test] = np.abs(ridge.predict(logf[test, best]) - y[test])
        svr = _svr().fit(f[train, best], y[train])
        errs_s[test] = np.abs(svr.predict(f[test, best]) - y[test])
    return float(errs_s.mean()), errs_r, chosen


def taxel_stack_errors(
    f: np.ndarray, y: np.ndarray, selections: dict[str, np.ndarray], seed: int = 0
) -> dict[str, np.ndarray]:
    """Per-tap errors of a nonlinear model that weighs taxels: stacked per-taxel RBF SVRs.

    One RBF SVR per taxel (its |FFT| row, standardised, C 100) predicts the position; a ridge
    regression combines the selected taxels' predictions, trained on their out-of-fold
    predictions (inner 3-fold on the training part) and scored on the outer test fold. "1
    taxel" is the taxel whose out-of-fold error on the training part is lowest. The single
    RBF SVR over all features weighs every feature alike; this one lets the data weigh each
    taxel, so comparing 80, 40 and 1 taxels is not skewed by dilution.

    Returns:
        Per-tap absolute errors for each selection, plus ``"1 taxel"``.
    """

    def svr() -> object:
        return make_pipeline(StandardScaler(), SVR(kernel="rbf", gamma="scale", C=100.0))

    n, n_taxels = f.shape[0], f.shape[1]
    errs = {label: np.zeros(n) for label in [*selections, "1 taxel"]}
    for train, test in KFold(4, shuffle=True, random_state=seed).split(f):
        oof = np.zeros((len(train), n_taxels))
        held = np.zeros((len(test), n_taxels))
        for tx in range(n_taxels):
            x = f[:, tx]
            for a, b in KFold(3, shuffle=True, random_state=seed + 1).split(train):
                oof[b, tx] = svr().fit(x[train[a]], y[train[a]]).predict(x[train[b]])
            held[:, tx] = svr().fit(x[train], y[train]).predict(x[test])
        for label, sel in selections.items():
            stack = RidgeCV(alphas=np.logspace(-3, 3, 13)).fit(oof[:, sel], y[train])
            errs[label][test] = np.abs(stack.predict(held[:, sel]) - y[test])
        best = int(np.argmin(np.abs(oof - y[train][:, None]).mean(axis=0)))
        errs["1 taxel"][test] = np.abs(held[:, best] - y[test])
    return errs


def run_rod(scene: str, taps: int, seed: int, rates, sets) -> None:
    start = time.perf_counter()
    ev, y = simulate(scene, taps, seed, sets)
    sim_s = time.perf_counter() - start
    n = len(y)
    f = features(ev, n, None)
    spread = float(np.mean(np.abs(y - y.mean())))
    line = [f"{scene}: {taps} taps, {len(ev[0]) / n:.0f} events/tap in window, sim {sim_s:.1f} s"]
    line.append(f"  spread of y (mean abs dev) {spread:.2f} cm")
    line.append(f"  {'':>10}  MAE SVR (RBF)  MAE ridge  ridge, paired per tap (cm, +- SE)")
    errs = {}
    for label, sel in SELECTIONS.items():
        x = f[:, sel].reshape(n, -1)
        errs[label] = ridge_errors(x, y)
        vs = (
            ""
            if label == "80 taxels"
            else f"  minus 80 taxels {paired(errs[label], errs['80 taxels'])}"
        )
        line.append(f"  {label:>10}: {mae(x, y):9.2f} cm {errs[label].mean():8.2f} cm{vs}")
    st, sr, tax = single_taxel(f, y)
    better = min(("40 (left)", "40 (right)"), key=lambda k: errs[k].mean())
    line.append(
        f"  {'1 taxel':>10}: {st:9.2f} cm {sr.mean():8.2f} cm  minus better finger "
        f"{paired(sr, errs[better])} (best on each training fold: taxels {tax})"
    )
    stack = taxel_stack_errors(f, y, SELECTIONS)
    line.append("  stacked per-taxel RBF SVRs (MAE, then paired per tap, cm +- SE):")
    line.append(f"  {'80 taxels':>10}: {stack['80 taxels'].mean():.2f} cm")
    for label in ("40 (left)", "40 (right)"):
        line.append(
            f"  {label:>10}: {stack[label].mean():.2f} cm  minus 80 taxels "
            f"{paired(stack[label], stack['80 taxels'])}"
        )
    better = min(("40 (left)", "40 (right)"), key=lambda k: stack[k].mean())
    line.append(
        f"  {'1 taxel':>10}: {stack['1 taxel'].mean():.2f} cm  minus better finger "
        f"{paired(stack['1 taxel'], stack[better])}"
    )
    print("\n".join(line), flush=True)
    if rates:
        print("  rate (80 taxels), MAE SVR / ridge, cm:", flush=True)
        for rate in rates:
            fr = features(ev, n, rate).reshape(n, -1)
            print(f"  {rate:>8g} Hz {mae(fr, y):6.2f} {ridge_mae(fr, y):6.2f}", flush=True)


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
    for rod in args.rods.split(","):
        rod_rates = rates if rod in with_rates else []
        run_rod(f"tap_rod{rod}_nuskin", args.taps, args.seed, rod_rates, args.set)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
